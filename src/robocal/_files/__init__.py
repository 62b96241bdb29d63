"""Files in and out, the only place units are converted: model files, measurement and contact
files, seatings folders, result files, URDF and DH tables, robot programs, atomic writes.

May import: ``_base``, ``_model``, ``_identification``, ``_accuracy``, ``_simulation``, ``_diagnosis``.
"""
