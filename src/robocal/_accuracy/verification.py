"""A quick verification: a short campaign held against a calibrated model, judged against the
accuracy the calibration reached.

Positional accuracy is in the terms of ISO 9283 (section 7.2.1): for each commanded pose the
barycentre of the attained positions against the position the model commands, ``AP_p``; the
worst pose's is the robot's ``AP``. The verdict compares the mean squared error now with the one at
calibration: an F test at ``alpha`` (each point error three components; base re-registration takes
six of them), so an unchanged robot is told "recalibrate" in about ``alpha`` of verifications.

Without an instrument, a few ball seatings in sockets verify a robot calibrated from seatings: the
calibrated model puts the ball of every seating of one socket on one point when it still holds,
so the error of a seating is its distance from its socket's mean predicted centre (each socket's
centre takes three components), held against the same figure of the calibration's held-out
seatings (``SEATINGS``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._base.arguments import FLAG, accepts, both, in_range, is_a, measured_on, shaped, whole
from .._base.arrays import vector_norms
from .._base.errors import DegenerateDataError, InputError
from .._identification.contact_figures import contact_errors
from .._identification.registration import rigid_base as register_base
from .._identification.steps import without_copies
from .._model.contacts import Contacts
from .._model.kinematics import evaluate
from .._model.measurements import Measurements
from .._model.robot import RobotModel

WITHIN, RECALIBRATE = "within accuracy", "recalibrate"
VERDICTS = (WITHIN, RECALIBRATE)
# an unchanged robot is told to recalibrate in this share of verifications
DEFAULT_ALPHA = 0.01
# a verification campaign is short: fewer poses say too little, more are a calibration
FEW_POSES, MANY_POSES = 10, 30
# the source of an accuracy at calibration of seatings (each one's distance from its socket's mean
# predicted centre, held out), which only seatings are held against
SEATINGS = "held-out seatings, each from its socket's centre"
NO_BASE_TO_REGISTER = "seatings have no base to register: each socket's centre is taken from its own seatings"


@dataclass(frozen=True)
class Accuracy:
    """The position accuracy a calibration reached, metres: ``rms``, ``mean``, ``p95``, ``max`` of the
    point error norms (``p95``/``max`` None when not known), over ``n`` points (the degrees of freedom
    behind ``rms`` for the verdict's test), and where it comes from (``source``: "held-out poses",
    "fitted poses held out, <the cross-validation's folds>", "fitted poses" or ``SEATINGS``).
    Of seatings, ``sets`` placements of the plate make it up, whose own mean squares scatter beyond
    what their seatings' number explains by ``scatter`` (the standard deviation of their logs): a
    placement is reached in configurations of its own, which seat the ball with a scatter of their
    own, and a verification's placement is held against that too."""

    rms: float
    mean: float | None
    n: int
    source: str
    p95: float | None = None
    max: float | None = None
    sets: int = 0
    scatter: float = 0.0


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
    calibration; else None. Of seatings (``sockets`` > 0): ``errors`` (n_rows, 1) each seating's
    distance from its socket's mean predicted centre, ``poses`` the sockets and ``ap`` the RMS of
    each one's distances (``ap_max`` the worst); ``rms`` as measured, the ratio's with the sockets'
    centres' degrees of freedom taken out; ``left_out`` what the verification did not count and why
    (a socket seated once, contacts of other kinds).
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
    sockets: int = 0
    left_out: tuple[str, ...] = ()

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
    return float(np.sqrt(_f_quantile(3 * n_points - (6 if registered else 0), 3 * then_n, alpha)))


def _observed(value, name, args):
    """Measured points of the model (``measured_on``), or contacts."""
    if not isinstance(value, Contacts):
        both(is_a(Measurements, Contacts), measured_on())(value, name, args)


@accepts(model=is_a(RobotModel), data=_observed, then=is_a(Accuracy), register=FLAG,
         alpha=in_range(0.0, 0.5, low_open=True, high_open=True))
def verify(model: RobotModel, data: Measurements | Contacts, then: Accuracy, *, register: bool = False,
           alpha: float = DEFAULT_ALPHA) -> Verification:
    """Hold a short campaign ``data`` against the calibrated ``model`` and judge it against ``then``.

    Parameters
    ----------
    model : RobotModel
        The calibrated model (as stored).
    data : Measurements or Contacts
        The verification campaign: 10 to 30 poses are enough (more are allowed); or ball seatings
        in sockets (two or more per socket, in varied configurations; a socket seated once, and plane
        and bar contacts, are left out, named in ``left_out``), for a robot calibrated from seatings.
    then : Accuracy
        The accuracy the calibration reached (``robocal.accuracy_at_calibration``).
    register : bool
        Re-register the base on these poses first (the tracker was set up again); not with seatings.
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
    if isinstance(data, Contacts) or then.source == SEATINGS:
        return _seatings(model, data, then, register, alpha)
    missing = [m for m in data.marker_names if m not in model.marker_names]
    if missing:
        raise InputError(f"marker(s) {', '.join(missing)} are not the calibrated model's "
                         f"({', '.join(model.marker_names)})", source=data.source or None)
    _refuse_copies(data)
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


def _refuse_copies(data: Measurements) -> None:
    """Refuse poses that repeat an earlier one exactly: an instrument never repeats a reading to the
    last digit, and counted, copies would be evidence the verification does not have."""
    copies = data.n_poses - without_copies(data)[0].n_poses
    if copies:
        raise DegenerateDataError(f"{data.source or 'the verification'}: {copies} of {data.n_poses} poses repeat an "
                                  "earlier one exactly (readings and measured positions): copies, not measurements; "
                                  "remove them")


def _seatings(model: RobotModel, data, then: Accuracy, register: bool, alpha: float) -> Verification:
    """``verify`` of ball seatings in sockets against the calibration's held-out seatings."""
    src = getattr(data, "source", "") or None
    if not isinstance(data, Contacts) or then.source != SEATINGS:
        now = "measured points" if isinstance(data, Measurements) else "seatings"
        then_kind = "seatings" if then.source == SEATINGS else "measured points"
        raise InputError(f"the calibration's accuracy is of {then_kind} ({then.source}) and these are {now}: verify "
                         "with what the calibration was judged on", source=src)
    if register:
        raise InputError(NO_BASE_TO_REGISTER, source=src, where="register")
    groups, left_out = _seated_again(data)
    if not groups:
        raise DegenerateDataError(f"{src or 'the verification'}: no socket seated twice or more: a seating's "
                                  "distance from its socket's centre needs the socket seated again")
    missing = sorted({data.marker[i] for g in groups for i in g.rows} - set(model.marker_names))
    if missing:
        raise InputError(f"marker(s) {', '.join(missing)} are not the calibrated model's "
                         f"({', '.join(model.marker_names)})", source=src)
    seated = contact_errors(model, data).seatings      # the calibration's held-out figure, on these seatings
    errors = np.full(data.n_rows, np.nan)
    for g in groups:
        errors[g.rows] = seated[g.label]
    spread = np.array([np.sqrt(np.mean(seated[g.label] ** 2)) for g in groups])
    v = errors[np.isfinite(errors)]
    dof = v.size - len(groups)             # each socket's centre takes three of its seatings' components
    ratio = float(np.sqrt(np.sum(v ** 2) / dof) / then.rms)
    threshold = _seatings_threshold(then, len({g.placement for g in groups}), dof, alpha)
    return Verification(errors=errors[:, None], rms=float(np.sqrt(np.mean(v ** 2))), mean=float(v.mean()),
                        p95=float(np.percentile(v, 95)), max=float(v.max()), poses=tuple(g.label for g in groups),
                        ap=spread, ap_max=float(spread.max()), then=then, ratio=ratio, threshold=threshold,
                        verdict=RECALIBRATE if ratio > threshold else WITHIN, registered_base=False,
                        n_points=int(v.size), alpha=alpha, sockets=len(groups), left_out=left_out)


def _seated_again(data: Contacts) -> tuple[list, tuple[str, ...]]:
    """The sockets seated twice or more, and each one left out with why: a socket seated once (its one
    seating is its socket's centre), and the contacts of other kinds (planes, bars), which hold no
    socket's consistency."""
    sockets = data.groups("socket")
    others = [g for g in data.groups() if g.kind != "socket"]
    return [g for g in sockets if len(g.rows) >= 2], tuple(
        f"socket {g.label}, seated once: one seating cannot show consistency (it is its socket's centre)"
        for g in sockets if len(g.rows) < 2) + tuple(
        f"{g.kind} {g.label}, {len(g.rows)} contact(s): a verification judges socket seatings only" for g in others)


def _seatings_threshold(then: Accuracy, placements: int, dof: int, alpha: float) -> float:
    """The RMS ratio an unchanged robot's seatings on ``placements`` placements (``dof`` points'
    degrees of freedom) exceed with probability ``alpha``: the log of their mean square against the
    calibration's placements' (``then.sets``), each placement's drawn with the scatter between
    placements (``then.scatter``) and its seatings' own (chi-square: variance 2 / its components of
    the log), Student's t over the calibration's placements. Without them, the F test of
    ``ratio_threshold``. (A few placements tell that scatter poorly: four of a simulated arm gave
    0.06 where sixty give 0.16, so the t's degrees of freedom are the placements', whatever part of
    the variance the scatter is. Sockets taken one by one, as if each had configurations of its own,
    made that arm recalibrate unchanged in 5 of 100 verifications at 0.01.)"""
    from scipy.special import stdtrit

    if then.sets < 2:
        return float(np.sqrt(_f_quantile(3 * dof, 3 * then.n, alpha)))
    each = 2.0 / (3.0 * max(then.n / then.sets, 1.0))       # a calibration placement's log, by chance
    var = then.scatter ** 2 / placements + 2.0 / (3.0 * dof) + (then.scatter ** 2 + each) / then.sets
    return float(np.exp(0.5 * stdtrit(then.sets - 1, 1.0 - alpha) * np.sqrt(var)))


def _f_quantile(d1: int, d2: int, alpha: float) -> float:
    from scipy.special import fdtri  # the F quantile, without importing scipy.stats (1.8 s)

    return float(fdtri(max(d1, 1), max(d2, 1), 1.0 - alpha))


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
