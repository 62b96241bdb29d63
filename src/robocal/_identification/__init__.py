"""The core's identification: the problem (a stack of observation blocks), the solve, the
identifiability analysis, held-out errors and the accuracy in use, the checks and verdict, and
``calibrate``: one sequence of steps for every kind of observation, and its result record.

May import: ``_base``, ``_model``.
"""
