"""trace: (docstring to come)"""
