"""The diagnosis of a calibration: specific mistakes tested against the data and ranked by
evidence, for measured points and for contacts.

May import: ``_base``, ``_model``, ``_identification``, ``_accuracy``, ``_simulation``.
"""
