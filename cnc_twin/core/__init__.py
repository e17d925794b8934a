"""core: (docstring to come)"""
