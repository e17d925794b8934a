"""run: (docstring to come)"""
