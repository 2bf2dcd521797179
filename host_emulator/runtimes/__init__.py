"""(docstring follows in phase B)"""
