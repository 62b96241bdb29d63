"""robocal: identify a robot's geometric and compliance parameters from measurements.

Conventions (frames, units, parameter order) are in docs/conventions.md.
"""

from ._errors import (ConvergenceWarning, DegenerateDataError, IdentifiabilityWarning, InputError,
                      MisfitWarning, RobocalError, RobocalWarning)
from ._kinematics import (evaluate, forward_kinematics, jacobian, model_from_vector, parameter_names,
                          parameter_vector)
from ._model import Frame, Marker, Payload, RobotModel, parallel_beta_frames, serial_model
from ._measurements import Measurements
from ._identifiability import Absorption, IdentifiabilityResult
from ._calibration import (CalibrationResult, Comparison, ParameterEstimate, calibrate, compare, error_stats, identifiability,
                        random_configurations, register_base)
from ._parameters import candidate_parameters
from ._simulation import measure, perturb_model, simulate
from ._pose_selection import PoseSelection, select_poses
from ._files.urdf import from_standard_dh, mdh_table, read_urdf, write_mdh_csv, write_urdf
from ._files.model import model_from_dict, model_to_dict, read_model, write_model
from ._files.measurements import read_measurements, split_sets, write_measurements
from ._files.result import read_result, write_result
from ._presentation.html import render_report, write_report
from ._compensation import Compensation, compensate, joint_jacobian
from ._accuracy_limit import (AccuracyLimit, PoseRepeatability, PrecisionResult, PredictedPrecision, RepeatabilityData,
                     RepeatabilityResult, accuracy_limit, controller_precision, iso9283_repeatability,
                     predicted_controller_precision, read_repeatability_csv)

__version__ = "0.1.0"

__all__ = [
    "ConvergenceWarning", "DegenerateDataError", "IdentifiabilityWarning", "InputError", "MisfitWarning",
    "RobocalError", "RobocalWarning", "evaluate", "forward_kinematics", "jacobian", "model_from_vector",
    "parameter_names", "parameter_vector", "Frame", "Marker", "Payload", "RobotModel",
    "parallel_beta_frames", "serial_model", "Measurements", "Absorption", "IdentifiabilityResult",
    "CalibrationResult", "Comparison", "compare", "ParameterEstimate", "calibrate", "error_stats", "identifiability",
    "random_configurations", "register_base", "candidate_parameters", "measure", "perturb_model", "simulate",
    "PoseSelection", "select_poses", "from_standard_dh", "mdh_table", "read_urdf", "write_mdh_csv", "write_urdf",
    "model_from_dict", "model_to_dict", "read_model", "write_model", "read_measurements", "split_sets",
    "write_measurements", "read_result", "write_result", "AccuracyLimit", "PoseRepeatability", "PrecisionResult",
    "PredictedPrecision", "RepeatabilityData", "RepeatabilityResult", "accuracy_limit", "controller_precision",
    "iso9283_repeatability", "predicted_controller_precision", "read_repeatability_csv",
    "render_report", "write_report", "Compensation", "compensate", "joint_jacobian",
]
