"""polishing: (docstring to come)"""
