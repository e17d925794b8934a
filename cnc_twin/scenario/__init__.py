"""scenario: (docstring to come)"""
