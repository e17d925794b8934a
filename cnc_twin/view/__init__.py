"""view: (docstring to come)"""
