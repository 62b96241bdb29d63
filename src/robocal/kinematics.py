"""The robot model and its kinematics: records, the modified-DH transform, forward kinematics, the
identification Jacobian, gravity loads, and the parameters (names, units, vector <-> model).

``mdh_transform`` is the readable reference of one frame's placement; ``forward_kinematics`` and
``jacobian`` are the batched engine (poses first: ``q`` is (n_poses, n_joints)), tested against it.
"""

from ._accuracy.compensation import (
    POSTURE,
    Compensation,
    InverseKinematics,
    PoseCompensation,
    arm_chain,
    compensate,
    compensate_poses,
    inverse_kinematics,
    joint_jacobian,
    posture,
)
from ._base import arguments as _arguments
from ._model.configurations import random_configurations, sampling_box
from ._model.kinematics import Evaluation, evaluate, forward_kinematics, gravity_loads, jacobian
from ._model.parameters import (
    BASE_KINDS,
    COMPLIANCE_KINDS,
    FAMILIES,
    FRAME_KINDS,
    GEOMETRIC_KINDS,
    KIND_QUANTITY,
    MARKER_KINDS,
    SI_UNITS,
    Parameter,
    ParameterLayout,
    candidate_parameters,
    families,
    matched_by_pattern,
    model_from_vector,
    parameter_layout,
    parameter_names,
    parameter_vector,
)
from ._model.robot import (
    Frame,
    Marker,
    Payload,
    RobotModel,
    default_masses,
    mdh_transform,
    parallel_beta_frames,
    placement_parameters,
    serial_model,
)

__all__ = ["Frame", "Marker", "Payload", "RobotModel", "serial_model", "parallel_beta_frames", "mdh_transform",
           "placement_parameters", "default_masses",
           "Evaluation", "evaluate", "forward_kinematics", "jacobian", "gravity_loads", "joint_jacobian",
           "Parameter", "ParameterLayout", "parameter_layout", "parameter_names", "parameter_vector",
           "model_from_vector", "candidate_parameters", "families", "matched_by_pattern", "random_configurations",
           "sampling_box",
           "BASE_KINDS", "GEOMETRIC_KINDS", "COMPLIANCE_KINDS", "FRAME_KINDS", "MARKER_KINDS", "KIND_QUANTITY",
           "SI_UNITS", "FAMILIES"]
__all__ += ["POSTURE", "arm_chain", "posture", "inverse_kinematics", "InverseKinematics", "compensate", "Compensation",
            "compensate_poses", "PoseCompensation"]

# the functions users call check their arguments; robocal's own code calls them unchecked
_arguments.export_checked(globals())
