"""robocal: identify a robot's geometric and compliance parameters from measurements.

``import robocal as rc`` gives the everyday surface, each name served by the public module that
holds it: ``robocal.kinematics``, ``robocal.io``, ``robocal.sim``, ``robocal.limit``,
``robocal.report``, ``robocal.identification``, ``robocal.store`` and ``robocal.errors``.
Conventions (frames, units, parameter order) are in docs/conventions.md. Names load on first use,
so the command line starts without the numerical libraries.
"""

from importlib import import_module

from ._version import __version__

# name -> public module that provides it
_EVERYDAY = {
    "errors": ("RobocalError", "InputError", "DegenerateDataError", "RobocalWarning", "CheckWarning",
               "ConvergenceWarning", "MisfitWarning", "IdentifiabilityWarning"),
    "kinematics": ("Frame", "Marker", "Payload", "RobotModel", "serial_model", "parallel_beta_frames",
                   "mdh_transform", "evaluate", "forward_kinematics", "jacobian", "gravity_loads", "joint_jacobian",
                   "parameter_names", "parameter_vector", "model_from_vector", "candidate_parameters",
                   "random_configurations", "default_masses", "inverse_kinematics", "InverseKinematics", "posture",
                   "compensate", "Compensation", "compensate_poses", "PoseCompensation"),
    "io": ("Measurements", "Noise", "Contacts", "KnownDistance", "KnownPlane", "read_model", "write_model",
           "model_from_dict", "model_to_dict", "read_measurements", "write_measurements", "split_sets", "read_result",
           "write_result", "read_urdf", "write_urdf", "from_standard_dh", "mdh_table", "write_mdh_csv",
           "read_dh_table", "urdf_text", "to_standard_dh", "read_repeatability_csv"),
    "sim": ("simulate", "measure", "perturb_model", "select_poses", "PoseSelection", "predict_campaign",
            "CampaignPrediction"),
    "limit": ("AccuracyLimit", "PoseRepeatability", "PrecisionResult", "PredictedPrecision", "RepeatabilityData",
              "RepeatabilityResult", "accuracy_limit", "controller_precision", "iso9283_repeatability",
              "predicted_controller_precision", "verify", "Verification", "Accuracy", "positional_accuracy"),
    "report": ("render_report", "write_report", "change_line", "history_summary", "type_summary",
               "verification_summary", "render_history", "write_history"),
    "identification": ("calibrate", "compare", "register_base", "error_stats",
                       "CalibrationResult", "Comparison", "ParameterEstimate", "ErrorStats", "ErrorSummary",
                       "LimitJudgement", "SolverRecord", "PoseSet", "NestedTest", "Check", "diagnose", "Diagnosis",
                       "Finding", "diagnose_contacts", "identifiability", "status_table", "Absorption",
                       "IdentifiabilityResult", "contact_errors", "ContactFigures", "ContactErrors"),
    "store": ("Store", "open_store", "store_location", "default_store_path", "history", "type_comparison",
              "verify_robot", "latest_usable", "judge_changes", "judge_overall", "compare_type", "stored_calibration",
              "accuracy_at_calibration", "History", "Change", "Overall", "TypeComparison", "Latest", "Outlier",
              "StoredCalibration", "StoredVerification", "Estimate", "model_document", "sidak_threshold",
              "JUDGED_FAMILIES"),
}
_WHERE = {name: module for module, names in _EVERYDAY.items() for name in names}
_SUBMODULES = ("kinematics", "io", "sim", "limit", "report", "errors", "identification", "store", "cli")

__all__ = ["__version__"] + sorted(_WHERE)


def __getattr__(name: str):
    if name in _SUBMODULES:
        return import_module(f".{name}", __name__)
    if name in _WHERE:
        value = getattr(import_module(f".{_WHERE[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'robocal' has no attribute {name!r}")


def __dir__():
    return __all__ + list(_SUBMODULES)
