"""A quick verification: a short campaign held against a calibrated model, judged against the
accuracy the calibration reached.

Positional accuracy is in the terms of ISO 9283 (section 7.2.1): for each commanded pose the
barycentre of the attained positions against the position the model commands, ``AP_p``; the
worst pose's is the robot's ``AP``. The verdict compares the mean squared error now with the one at
calibration: an F test at ``alpha`` (each point error three components; base re-registration takes
six of them), so an unchanged robot is told "recalibrate" in about ``alpha`` of verifications.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._base.arguments import FLAG, accepts, both, in_range, is_a, measured_on, shaped, whole
from .._base.arrays import vector_norms
from .._base.errors import DegenerateDataError, InputError
from .._identification.registration import rigid_base as register_base
from .._model.kinematics import evaluate
from .._model.measurements import Measurements
from .._model.robot import RobotModel

WITHIN, RECALIBRATE = "within accuracy", "recalibrate"
VERDICTS = (WITHIN, RECALIBRATE)
# an unchanged robot is told to recalibrate in this share of verifications
DEFAULT_ALPHA = 0.01
# a verification campaign is short: fewer poses say too little, more are a calibration
FEW_POSES, MANY_POSES = 10, 30


@dataclass(frozen=True)
class Accuracy:
    """The position accuracy a calibration reached, metres: ``rms``, ``mean``, ``p95``, ``max`` of the
    point error norms (``p95``/``max`` None when not known), over ``n`` points (the degrees of freedom
    behind ``rms`` for the verdict's test), and where it comes from (``source``: "in use
    (validation)", "in use (cross-validation)", "held-out poses" or "fitted poses")."""

    rms: float
    mean: float | None
    n: int
    source: str
    p95: float | None = None
    max: float | None = None


@dataclass(frozen=True, eq=False)
class Verification:
    """A verification campaign against a calibrated model.

    ``errors`` (n_poses, n_markers) position error norms, metres (NaN where not measured);
    ``rms``, ``mean``, ``p95``, ``max`` of them; ``ap`` (n_commanded,) ISO 9283 positional accuracy
    of each commanded pose (labels in ``poses``), ``ap_max`` the worst. ``then`` the accuracy at
    calibration; ``ratio`` = rms now / rms then, ``threshold`` the ratio beyond which the verdict
    is "recalibrate"; ``registered_base``: the base was re-registered on these poses first.
    ``if_registered``: when the verdict is "recalibrate" without re-registering, (ratio, threshold)
    with the base re-registered on these poses, the check of an instrument set up again since the
    calibration; else None.
    """

    errors: np.ndarray
    rms: float
    mean: float
    p95: float
    max: float
    poses: tuple[str, ...]
    ap: np.ndarray
    ap_max: float
    then: Accuracy
    ratio: float
    threshold: float
    verdict: str
    registered_base: bool
    n_points: int
    alpha: float
    if_registered: tuple[float, float] | None = None

    @property
    def n_poses(self) -> int:
        return int(self.errors.shape[0])


def _commanded_poses(data: Measurements) -> tuple[tuple[str, ...], np.ndarray]:
    """(labels of the commanded poses, index of each row's pose): repeated visits of one pose share a label."""
    labels = data.labels if len(data.labels) == data.n_poses else tuple(str(i + 1) for i in range(data.n_poses))
    names, first, inverse = np.unique(np.asarray(labels, dtype=object).astype(str), return_index=True,
                                      return_inverse=True)
    order = np.argsort(first)                      # poses in order of first appearance
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    return tuple(str(n) for n in names[order]), rank[inverse]


def _pose_index(value, name, args):
    """(n,) whole numbers in [0, n_commanded), one per row of ``predicted``."""
    a = shaped(len(args["predicted"]))(value, name, args)
    if np.any(a != np.round(a)) or np.any(a < 0) or np.any(a >= args["n_commanded"]):
        raise InputError(f"must be whole numbers in [0, {args['n_commanded'] - 1}], one per point", where=name)


@accepts(n_commanded=whole(1), predicted=shaped(None, 3),
         measured=lambda value, name, args: shaped(len(args["predicted"]), 3)(value, name, args),
         pose_index=_pose_index)
def positional_accuracy(predicted, measured, pose_index, n_commanded: int) -> np.ndarray:
    """ISO 9283 positional accuracy ``AP_p`` of each commanded pose: the distance between the
    barycentre of its attained positions and the commanded position, metres.

    ``predicted``/``measured`` (n, 3) points; ``pose_index`` (n,) the commanded pose of each row.

    Parameters
    ----------
    predicted : array_like, shape (n, 3)
        The commanded (predicted) position of each point, m.
    measured : array_like, shape (n, 3)
        The attained (measured) position of each point, m.
    pose_index : array_like of int, shape (n,)
        The commanded pose of each point, in [0, n_commanded).
    n_commanded : int
        The number of commanded poses.

    Returns
    -------
    numpy.ndarray, shape (n_commanded,)
        ``AP_p`` of each commanded pose, m (NaN for a pose without points).

    >>> positional_accuracy([[0, 0, 0.0]] * 2, [[0.001, 0, 0], [0.003, 0, 0]], [0, 0], 1).round(6).tolist()
    [0.002]
    """
    predicted, measured = np.asarray(predicted, dtype=float), np.asarray(measured, dtype=float)
    idx = np.asarray(pose_index, dtype=int)
    counts = np.bincount(idx, minlength=n_commanded).astype(float)
    sums = np.zeros((n_commanded, 3))
    np.add.at(sums, idx, measured - predicted)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.linalg.norm(sums / counts[:, None], axis=1)


def ratio_threshold(n_points: int, then_n: int, *, registered: bool, alpha: float = DEFAULT_ALPHA) -> float:
    """The RMS ratio (now / at calibration) an unchanged robot exceeds with probability ``alpha``:
    the square root of the F quantile, three components per point now (six fewer when the base was
    re-registered on them) against three per point at calibration.

    >>> round(ratio_threshold(20, 60, registered=False), 3)
    1.263
    """
    from scipy.special import fdtri  # the F quantile, without importing scipy.stats (1.8 s)

    d1 = max(3 * n_points - (6 if registered else 0), 1)
    d2 = max(3 * then_n, 1)
    return float(np.sqrt(fdtri(d1, d2, 1.0 - alpha)))


@accepts(model=is_a(RobotModel), data=both(is_a(Measurements), measured_on()), then=is_a(Accuracy), register=FLAG,
         alpha=in_range(0.0, 0.5, low_open=True, high_open=True))
def verify(model: RobotModel, data: Measurements, then: Accuracy, *, register: bool = False,
           alpha: float = DEFAULT_ALPHA) -> Verification:
    """Hold a short campaign ``data`` against the calibrated ``model`` and judge it against ``then``.

    Parameters
    ----------
    model : RobotModel
        The calibrated model (as stored).
    data : Measurements
        The verification campaign: 10 to 30 poses are enough (more are allowed).
    then : Accuracy
        The accuracy the calibration reached (``robocal.accuracy_at_calibration``).
    register : bool
        Re-register the base on these poses first (the tracker was set up again).
    alpha : float
        The share of verifications of an unchanged robot that say "recalibrate".

    Returns
    -------
    Verification
        Errors, ISO 9283 positional accuracy per commanded pose, the ratio to the accuracy then and
        the verdict ("within accuracy" or "recalibrate").
    """
    if not isinstance(then, Accuracy) or not (then.rms > 0 and np.isfinite(then.rms)) or then.n < 1:
        raise InputError("the accuracy at calibration must be a positive RMS over at least one point", where="then")
    if not 0 < alpha < 0.5:
        raise InputError(f"must be between 0 and 0.5, got {alpha!r}", where="alpha")
    missing = [m for m in data.marker_names if m not in model.marker_names]
    if missing:
        raise InputError(f"marker(s) {', '.join(missing)} are not the calibrated model's "
                         f"({', '.join(model.marker_names)})", source=data.source or None)
    norms, predicted = _errors(register_base(model, data) if register else model, data)
    v = norms[np.isfinite(norms)]
    if v.size < (4 if register else 1):
        raise DegenerateDataError("the verification has too few measured points")
    names, ap = _iso_accuracy(data, predicted)
    ratio, threshold = _ratio(v, then, register, alpha)
    says = RECALIBRATE if ratio > threshold else WITHIN
    if_registered = None
    if says == RECALIBRATE and not register and v.size >= 4:  # would a new set-up of the instrument explain it?
        again = _errors(register_base(model, data), data)[0]
        if_registered = _ratio(again[np.isfinite(again)], then, True, alpha)
    return Verification(errors=norms, rms=float(np.sqrt(np.mean(v ** 2))), mean=float(v.mean()),
                        p95=float(np.percentile(v, 95)), max=float(v.max()), poses=names, ap=ap,
                        ap_max=float(ap.max()), then=then, ratio=ratio, threshold=threshold, verdict=says,
                        registered_base=register, n_points=int(v.size), alpha=alpha, if_registered=if_registered)


def _errors(model: RobotModel, data: Measurements) -> tuple[np.ndarray, np.ndarray]:
    """(n_poses, n_markers) position error norms of ``data`` against ``model`` (NaN where not
    measured), and the positions the model predicts."""
    mi = np.array([model.marker_names.index(n) for n in data.marker_names])
    predicted = evaluate(model, data.q, payload_mass=data.payload_mass).positions[:, mi]
    mask = np.asarray(data.mask, dtype=bool)
    return np.where(mask, vector_norms(data.positions - predicted), np.nan), predicted


def _iso_accuracy(data: Measurements, predicted: np.ndarray) -> tuple[tuple[str, ...], np.ndarray]:
    """The ISO 9283 pose points (each marker of a commanded pose, labelled pose[/marker]) and their ``AP_p``."""
    mask = np.asarray(data.mask, dtype=bool)
    poses, index = _commanded_poses(data)
    rows, markers = np.nonzero(mask)
    key = index[rows] * len(data.marker_names) + markers
    used, inverse = np.unique(key, return_inverse=True)
    ap = positional_accuracy(predicted[rows, markers], data.positions[rows, markers], inverse, used.size)
    names = tuple(poses[k // len(data.marker_names)] + (f"/{data.marker_names[k % len(data.marker_names)]}"
                                                        if len(data.marker_names) > 1 else "") for k in used)
    return names, ap


def _ratio(v: np.ndarray, then: Accuracy, register: bool, alpha: float) -> tuple[float, float]:
    """(RMS of the error norms ``v`` over the RMS then, the ratio beyond which to recalibrate); a
    re-registered base takes six of the degrees of freedom."""
    rms = float(np.sqrt(np.mean(v ** 2)))
    dof = 3 * v.size
    rms_dof = rms * np.sqrt(dof / max(dof - 6, 1)) if register else rms
    return float(rms_dof / then.rms), ratio_threshold(v.size, then.n, registered=register, alpha=alpha)
