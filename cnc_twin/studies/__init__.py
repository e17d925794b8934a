"""studies: (docstring to come)"""
