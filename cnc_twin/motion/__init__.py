"""motion: (docstring to come)"""
