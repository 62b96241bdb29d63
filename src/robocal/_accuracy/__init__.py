"""Accuracy beyond the fit: the limit of absolute accuracy (ISO 9283 repeatability, controller
precision), verification of a calibration on a short campaign, and compensation (inverse
kinematics, compensated joint commands).

May import: ``_base``, ``_model``, ``_identification``.
"""
