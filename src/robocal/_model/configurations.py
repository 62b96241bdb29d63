"""Configurations of a robot: the box within its joint limits that configurations are drawn
from, random configurations, and readings with nothing measured (what depends on the poses only)."""

from __future__ import annotations

import numpy as np

from .._base.arguments import SEED, accepts, is_a, whole
from .._base.errors import InputError
from .._base.options import MAX_POSES
from .measurements import Measurements
from .robot import RobotModel


@accepts(model=is_a(RobotModel))
def sampling_box(model: RobotModel) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper readings within which configurations are drawn, (n_joints,) each.

    An unbounded revolute reading turns within +-pi (every orientation); an unbounded prismatic
    one has no such range and is refused.

    Parameters
    ----------
    {model}

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        Lower and upper readings, (n_joints,) each.
    """
    lo, hi = model.lower_limits.copy(), model.upper_limits.copy()
    angle = np.zeros(model.n_joints, dtype=bool)
    for f in model.frames:
        for j, _ in f.coupling:
            angle[j] |= f.joint == "revolute"
    open_ = ~(np.isfinite(lo) & np.isfinite(hi))
    if np.any(open_ & ~angle):
        j = int(np.argmax(open_ & ~angle))
        raise InputError(f"joint {model.joint_names[j]!r} slides without finite limits: configurations cannot be "
                         "drawn; give its limits", where=f"joints[{j}].limits")
    lo[open_] = np.maximum(lo[open_], -np.pi)
    hi[open_] = np.minimum(hi[open_], np.pi)
    empty = ~(lo <= hi) | ~np.isfinite(hi - lo)  # e.g. limits [inf, inf]: nothing to draw from
    if np.any(empty):
        j = int(np.argmax(empty))
        raise InputError(f"joint {model.joint_names[j]!r} has no finite range of readings within its limits "
                         f"({model.lower_limits[j]:g}, {model.upper_limits[j]:g}): configurations cannot be drawn",
                         where=f"joints[{j}].limits")
    return lo, hi


@accepts(model=is_a(RobotModel), n=whole(0, MAX_POSES), rng=SEED)
def random_configurations(model: RobotModel, n: int, rng=None) -> np.ndarray:
    """``n`` joint readings (n, n_joints) drawn uniformly within ``sampling_box(model)``.

    Parameters
    ----------
    {model}
    n : int
        Number of configurations.
    {rng}

    Returns
    -------
    numpy.ndarray, shape (n, n_joints)
        Joint readings within the joint limits.
    """
    rng = np.random.default_rng(rng)
    lo, hi = sampling_box(model)
    return rng.uniform(lo, hi, size=(n, model.n_joints))

def design_measurements(model: RobotModel, q, orientation: bool = False, markers=None, approach=None) -> Measurements:
    """Configurations without measured values, for what depends on the poses only (the Jacobian).

    ``markers``: the names of the markers measured (default all the model's); ``approach``
    (n, n_joints) the direction each joint comes from (default: the row order)."""
    names = model.marker_names if markers is None else tuple(markers)
    n, m = len(q), len(names)
    return Measurements(q=q, positions=np.zeros((n, m, 3)), marker_names=names,
                        rotations=np.broadcast_to(np.eye(3), (n, m, 3, 3)) if orientation else None,
                        extra={} if approach is None else {"approach": np.asarray(approach, dtype=float)})
