"""What a calibration of any kind of observation reports per parameter and per error, and what
its geometry does over the workspace: the records and functions that the calibration from
measured points and the one from contacts share."""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import numpy as np

from .._base.arguments import NORMS, accepts
from .._base.arrays import read_only, vector_norms
from .._model.configurations import design_measurements
from .._model.measurements import Measurements
from .._model.parameters import parameter_layout, parameter_vector
from .._model.robot import RobotModel
from .checks import WorkspaceChange, tolerances
from .points import Points
from .problem import Problem
from .solve import solve

# The fit of base and markers behind the errors before calibration stops at this tolerance, its
# last step taken: its errors are those of the fit run to 1e-12 within a few 1e-10 m (they are
# shown in micrometres), and it takes one Jacobian and one pass fewer.
REGISTRATION_TOL = 1e-6


@dataclass(frozen=True)
class ErrorStats:
    """Statistics of ``n`` error norms (m for positions, rad for rotations).

    Attributes
    ----------
    n : int
        How many norms (points measured).
    mean : float or None
        Their mean; None when n = 0 (likewise below).
    std : float or None
        Their standard deviation (n - 1 in the denominator; 0 for one norm).
    rms : float or None
        Their root mean square.
    max : float or None
        The largest.
    """

    n: int
    mean: float | None
    std: float | None
    rms: float | None
    max: float | None


@accepts(norms=NORMS)
def error_stats(norms) -> ErrorStats:
    """The statistics of error norms; NaN entries were not measured.

    Parameters
    ----------
    norms : array_like
        Error norms, m (any shape; NaN where not measured).

    Returns
    -------
    ErrorStats
        Their count, mean, standard deviation, RMS and maximum (None when there are none).
    """
    v = np.asarray(norms, dtype=float).ravel()
    finite = np.isfinite(v)
    if not finite.all():                  # no copy where every point was measured
        v = v[finite]
    if v.size == 0:
        return ErrorStats(0, None, None, None, None)
    return ErrorStats(n=int(v.size), mean=float(v.mean()), std=float(v.std(ddof=1)) if v.size > 1 else 0.0,
                      rms=float(np.sqrt(np.mean(v ** 2))), max=float(v.max()))


@dataclass(frozen=True)
class ParameterEstimate:
    """One identified parameter (``change`` is the estimate less the nominal value).

    Attributes
    ----------
    name : str
        The parameter's name ("j2.alpha", "base.x", "tool.y").
    unit : str
        Its SI unit: "m", "rad" or "rad/(N m)".
    nominal : float
        The value the solve started from (the model's, or the registered base's), SI.
    estimate : float
        The identified value, SI.
    std : float
        The standard deviation of the estimate, SI.
    family : str
        Its family ("geometric", "compliance", "backlash", "base", "markers").
    quantity : str
        What it measures: "length", "angle" or "compliance".
    """

    name: str
    unit: str
    nominal: float
    estimate: float
    std: float
    family: str = ""
    quantity: str = ""

    @property
    def change(self) -> float:
        return self.estimate - self.nominal


def effect_text(v: float, quantity: str) -> str:
    """A predicted standard deviation as text: mm for a length, degrees (of deflection) otherwise."""
    if quantity == "length":
        return f"{v * 1e3:.3g} mm"
    return f"{np.degrees(v):.3g} deg" + (" of deflection" if quantity == "compliance" else "")


def weak_words(found, lay) -> tuple[tuple[str, str], ...]:
    """Each weak parameter of ``weakly_identifiable``'s findings with its predicted standard deviation
    in words (that of the parameter it leaves beyond its bound, when another)."""
    return tuple((n, effect_text(e, lay[by].quantity) + ("" if by == n else f" of {by} with it"))
                 for n, by, e, _ in found)


def workspace_change(start: RobotModel, p: np.ndarray, q: np.ndarray, markers, free, at: Points | None = None
                     ) -> WorkspaceChange:
    """How far the geometry of the vector ``p`` (the layout of ``start``) moves the ``markers`` from
    where ``start``'s puts them at readings ``q``, once the nominal's base and the ``free`` markers'
    parameters are registered onto it: the change of what the robot does, whatever the
    parametrisation (equivalent ones move nothing). Compliance and backlash are left out: their
    own tolerances judge them. ``at``: a problem of ``start`` at ``q`` already evaluated at ``p``,
    whose predictions are taken when they are the geometry's alone."""
    lay = parameter_layout(start)
    p0 = parameter_vector(start)
    families = start.derived(workspace_change, lambda: read_only(np.array([lay[n].family for n in lay.names])))
    p_geom = np.where((families != "compliance") & (families != "backlash"), p, p0)
    if (at is not None and at.compliance == start.has_compliance and np.array_equal(p_geom, p)
            and set(markers) <= set(at.data.marker_names)):
        target = at.predicted(p)[0][:, [at.data.marker_names.index(n) for n in markers]]
    else:
        target = Points(start, design_measurements(start, q, markers=markers), (),
                        compliance=start.has_compliance).predicted(p_geom)[0]
    tol = tolerances(start)
    t_len, t_ang = tol.get(("frames", "length")), tol.get(("frames", "angle"))
    radius = float(np.max(vector_norms(target - np.asarray(start.base_position, dtype=float))))
    owners, free_set = set(markers), set(free)
    placed = tuple(n for n, f in zip(lay.names, families) if f == "base"
                   or (f == "markers" and lay[n].owner in owners and n in free_set))
    ws = Measurements(q=q, positions=target, marker_names=tuple(markers), joint_names=start.joint_names)
    nominal = Problem(start, placed, data=ws, compliance=start.has_compliance)
    p_start = p0.copy()
    p_start[lay.indices(placed)] = p[lay.indices(placed)]
    d = cast(Points, nominal.points).error_norms(solve(nominal, p_start, tol=REGISTRATION_TOL).p)
    bar = None if t_len is None or t_ang is None else float(t_len + t_ang * radius)
    return WorkspaceChange(max_m=float(np.nanmax(d)), rms_m=float(np.sqrt(np.nanmean(d ** 2))), tolerance_m=bar,
                           reach_m=radius, n_poses=len(q))
