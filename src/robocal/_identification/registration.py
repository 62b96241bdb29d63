"""The rigid registration of a robot's base on measured points (Kabsch/Horn, via scipy)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from .._base.errors import DegenerateDataError
from .._model.kinematics import evaluate
from .._model.measurements import Measurements
from .._model.robot import RobotModel


def rigid_base(model: RobotModel, data: Measurements) -> RobotModel:
    """The model with ``X_WB`` from a closed-form rigid registration: the nominal marker positions
    in frame 0 matched to the measured ones in W (three non-collinear measured points at least)."""
    origin = model.replace(base_position=(0.0, 0.0, 0.0),
                           base_rotation=((1.0, 0, 0), (0, 1.0, 0), (0, 0, 1.0)))
    ev = evaluate(origin, data.q, payload_mass=data.payload_mass)
    mi = np.array([model.marker_names.index(n) for n in data.marker_names])
    pb = ev.positions[:, mi][data.mask]
    pw = data.positions[data.mask]
    if len(pb) < 3 or np.linalg.matrix_rank(pb - pb.mean(0), tol=1e-6) < 2:
        raise DegenerateDataError("base registration needs at least three measured points that are not collinear")
    cb, cw = pb.mean(0), pw.mean(0)
    rot, _ = Rotation.align_vectors(pw - cw, pb - cb)
    R = rot.as_matrix()
    t = cw - R @ cb
    return model.replace(base_position=tuple(float(v) for v in t),
                         base_rotation=tuple(tuple(float(v) for v in row) for row in R))


