"""machine: (docstring to come)"""
