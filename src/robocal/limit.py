"""The limit of absolute accuracy (docs/method.md section 5): ISO 9283 repeatability plus the
precision of the geometric control system; and a calibration verified on a short campaign (ISO 9283
positional accuracy against the accuracy at calibration)."""

from ._accuracy.limit import (
    AccuracyLimit,
    PoseRepeatability,
    PrecisionResult,
    PredictedPrecision,
    RepeatabilityData,
    RepeatabilityResult,
    accuracy_limit,
    controller_precision,
    iso9283_repeatability,
    predicted_controller_precision,
    rounded_parameters,
)
from ._accuracy.verification import Accuracy, Verification, positional_accuracy, verify
from ._base import arguments as _arguments

__all__ = ["AccuracyLimit", "PoseRepeatability", "PrecisionResult", "PredictedPrecision", "RepeatabilityData",
           "RepeatabilityResult", "accuracy_limit", "controller_precision", "iso9283_repeatability",
           "predicted_controller_precision", "rounded_parameters", "verify", "Verification", "Accuracy",
           "positional_accuracy"]

# the functions users call check their arguments; robocal's own code calls them unchecked
_arguments.export_checked(globals())
