"""The limit of absolute accuracy (docs/method.md section 5): ISO 9283 repeatability plus the
precision of the geometric control system."""

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

__all__ = ["AccuracyLimit", "PoseRepeatability", "PrecisionResult", "PredictedPrecision", "RepeatabilityData",
           "RepeatabilityResult", "accuracy_limit", "controller_precision", "iso9283_repeatability",
           "predicted_controller_precision", "rounded_parameters"]
