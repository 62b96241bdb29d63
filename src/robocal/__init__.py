"""robocal: identify a robot's geometric and compliance parameters from measurements.

Conventions (frames, units, parameter order) are in docs/conventions.md.
"""

from ._errors import (ConvergenceWarning, DegenerateDataError, IdentifiabilityWarning, InputError,
                      MisfitWarning, RobocalError, RobocalWarning)
from ._kinematics import (evaluate, forward_kinematics, jacobian, model_from_vector, parameter_names,
                          parameter_vector)
from ._model import Frame, Marker, Payload, RobotModel, parallel_beta_frames, serial_model

__version__ = "0.1.0"

__all__ = [
    "ConvergenceWarning", "DegenerateDataError", "IdentifiabilityWarning", "InputError", "MisfitWarning",
    "RobocalError", "RobocalWarning", "evaluate", "forward_kinematics", "jacobian", "model_from_vector",
    "parameter_names", "parameter_vector", "Frame", "Marker", "Payload", "RobotModel",
    "parallel_beta_frames", "serial_model",
]
