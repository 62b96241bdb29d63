"""The limit of absolute accuracy (docs/method.md section 5): repeatability + geometric-control precision.

Calibration cannot make a robot more accurate than the sum of

* the precision of the positioning control system, the pose repeatability RP of ISO 9283
  (``iso9283_repeatability``), and
* the precision of the geometric control system: the tool moves even with perfect parameters,
  because the controller reads its joints with a finite encoder resolution and stores its
  dimensional parameters rounded to a quantum (``controller_precision``, a Monte Carlo over the
  workspace; ``predicted_controller_precision`` is its first-order counterpart).

``accuracy_limit`` adds the two. Everything is SI inside (metres, radians); the CSV reader is the
only place where millimetres appear.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass, field

import numpy as np

from .._base.arguments import (
    CALLABLE,
    NON_NEGATIVE,
    SEED,
    SEQUENCE,
    accepts,
    is_a,
    marker_of,
    one_of,
    optional,
    per_joint,
    shaped,
    whole,
)
from .._base.errors import InputError, check_choice
from .._base.options import LIMIT_CHUNK, LIMIT_MARKER_MODES, MAX_CHUNK, MAX_LIMIT_WORK, MAX_SAMPLES
from .._base.spatial import cross, vector3
from .._base.threads import one_blas_thread
from .._model.configurations import sampling_box
from .._model.kinematics import evaluate, kinematic_pass, layout
from .._model.parameters import families, parameter_layout, parameter_vector
from .._model.robot import RobotModel

PERCENTILES = (50.0, 90.0, 95.0, 99.0)
HIST_BINS = 20_000
HIST_EDGES = np.logspace(-12, 0, HIST_BINS + 1)


def _histogram_percentile(hist: np.ndarray, pct: float, top: float) -> float:
    """Percentile from counts over ``HIST_EDGES`` (index 0 below the first edge, last above),
    interpolated geometrically inside the bin; never above the largest sample ``top``."""
    cum = np.cumsum(hist)
    target = pct / 100.0 * cum[-1]
    k = int(np.searchsorted(cum, target, side="left"))
    if k == 0:
        return float(HIST_EDGES[0])
    if k > HIST_BINS:
        return top
    lo, hi = HIST_EDGES[k - 1], HIST_EDGES[k]
    before = cum[k - 1] - hist[k]
    frac = (target - before) / hist[k] if hist[k] else 0.0
    return float(min(lo * (hi / lo) ** frac, top))
MARKER_MODES = LIMIT_MARKER_MODES
DEFAULT_CHUNK = LIMIT_CHUNK


# -- records -----------------------------------------------------------------------------------

@dataclass(frozen=True)
class RepeatabilityData:
    """Repeated measurements of attained positions: ``points`` (n, 3) in metres, in file order.

    ``pose_ids`` (n,) name the commanded pose of each row, ``cycles`` (n,) its cycle number.
    """

    pose_ids: tuple[str, ...]
    cycles: np.ndarray = field(compare=False)
    points: np.ndarray = field(compare=False)
    source: str = ""


@dataclass(frozen=True)
class PoseRepeatability:
    """ISO 9283 pose repeatability of one commanded pose (metres).

    ``barycentre`` is the mean attained position, ``l`` the distances l_j of the attained positions
    from it, ``s_l`` their sample standard deviation (n - 1) and ``rp = l_mean + 3 s_l``.
    """

    pose: Hashable
    n_cycles: int
    barycentre: tuple[float, float, float]
    l: tuple[float, ...]  # noqa: E741 - ISO 9283's symbol l_j
    l_mean: float
    s_l: float
    rp: float



@dataclass(frozen=True)
class RepeatabilityResult:
    """Per-pose ISO 9283 repeatability; ``rp`` is the worst pose's RP (metres)."""

    poses: tuple[PoseRepeatability, ...]
    rp: float
    worst_pose: Hashable



@dataclass(frozen=True)
class PrecisionResult:
    """Monte Carlo of the geometric control system's precision: tool deviations in metres.

    ``mean`` is the statistic that counts as the precision; ``standard_error`` is that of the mean
    (std / sqrt(n), the samples are independent). ``rms`` (with ``rms_standard_error``, delta
    method) is the figure to compare with ``predicted_controller_precision``. ``percentiles`` are
    ``((50, v), (90, v), (95, v), (99, v))``, read from a fixed log-spaced histogram (bins 0.14 %
    wide, so memory does not grow with the sample count).
    """

    n_samples: int
    mean: float
    std: float
    standard_error: float
    rms: float
    rms_standard_error: float
    percentiles: tuple[tuple[float, float], ...]
    max: float
    encoder_resolution: tuple[float, ...]
    length_quantum: float
    angle_quantum: float
    markers: str
    rounded_parameters: tuple[str, ...]
    method: str

    def percentile(self, pct: float) -> float:
        return dict(self.percentiles)[float(pct)]



@dataclass(frozen=True)
class PredictedPrecision:
    """First-order prediction of the geometric control precision (metres), averaged over the workspace.

    ``rms`` = sqrt(E_q trace(J Sigma J^T)) is exact to first order whatever the error
    distribution; ``mean_gaussian`` is E|dP| for dP ~ N(0, J Sigma J^T), an approximation (the
    quantisation errors are uniform, not Gaussian). Standard errors are those of the sampling
    over configurations (and Gaussian draws).
    """

    n_configurations: int
    rms: float
    rms_standard_error: float
    mean_gaussian: float
    mean_gaussian_standard_error: float
    marker: str



@dataclass(frozen=True)
class AccuracyLimit:
    """The limit of absolute accuracy (metres): ``limit = repeatability + precision``.

    ``precision`` is the Monte Carlo mean tool deviation (``precision_statistic == "mean"``: the
    paper compares mean errors); ``limit_p95`` uses the 95th percentile instead.
    """

    repeatability: float
    precision: float
    precision_p95: float
    limit: float
    limit_p95: float
    precision_statistic: str
    repeatability_detail: RepeatabilityResult | None
    precision_detail: PrecisionResult



# -- ISO 9283 repeatability --------------------------------------------------------------------

@accepts(pose_ids=SEQUENCE, points=shaped(None, 3))
def iso9283_repeatability(pose_ids: Sequence[Hashable], points) -> RepeatabilityResult:
    """ISO 9283 pose repeatability of each commanded pose and the worst pose.

    ``pose_ids`` (n,) name the commanded pose of each attained position ``points`` (n, 3), metres.
    Per pose: barycentre, ``l_j = |P_j - barycentre|``, ``l_mean``, ``S_l`` (sample standard
    deviation, n - 1) and ``RP = l_mean + 3 S_l``. Poses are reported in order of first appearance.

    Parameters
    ----------
    {pose_ids, points}

    Returns
    -------
    RepeatabilityResult
        RP per pose and the worst.

    >>> r = iso9283_repeatability(["a"] * 2, [[0.0, 0, 0], [0.002, 0, 0]])
    >>> round(r.poses[0].l_mean, 6), round(r.poses[0].s_l, 6), round(r.rp, 6)
    (0.001, 0.0, 0.001)
    """
    P = np.asarray(points, dtype=float)
    ids = list(pose_ids)
    if P.ndim != 2 or P.shape[1] != 3:
        raise InputError(f"expected an (n, 3) array, got shape {P.shape}", where="points")
    if len(ids) != P.shape[0]:
        raise InputError(f"{len(ids)} pose ids for {P.shape[0]} points", where="pose_ids")
    if not np.all(np.isfinite(P)):
        raise InputError("points must be finite", where="points")
    order: dict = {}
    for i, pid in enumerate(ids):
        order.setdefault(pid, []).append(i)
    if not order:
        raise InputError("no measurements", where="points")
    poses = []
    for pid, rows in order.items():
        if len(rows) < 2:
            raise InputError(f"pose {pid!r} has a single cycle; repeatability needs at least two",
                             where="pose_ids")
        Pj = P[rows]
        bary = Pj.mean(axis=0)
        dist = np.linalg.norm(Pj - bary, axis=1)
        l_mean = float(dist.mean())
        s_l = float(dist.std(ddof=1))
        poses.append(PoseRepeatability(pose=pid, n_cycles=len(rows), barycentre=vector3(bary),
                                       l=tuple(float(v) for v in dist), l_mean=l_mean, s_l=s_l,
                                       rp=l_mean + 3.0 * s_l))
    worst = max(poses, key=lambda r: r.rp)
    return RepeatabilityResult(poses=tuple(poses), rp=worst.rp, worst_pose=worst.pose)


# -- geometric control precision ---------------------------------------------------------------

@dataclass(frozen=True)
class _Rounded:
    """The parameters the controller stores rounded: indices in the full vector, steps, quanta."""

    names: tuple[str, ...]
    params: np.ndarray   # (K,) index in parameter_vector
    steps: np.ndarray    # (K,) step of the kinematic pass each one moves
    quanta: np.ndarray   # (K,) metres or radians


@accepts(model=is_a(RobotModel), length_quantum=NON_NEGATIVE, angle_quantum=NON_NEGATIVE)
def rounded_parameters(model: RobotModel, length_quantum: float, angle_quantum: float) -> _Rounded:
    """Which stored parameters the controller rounds, with their quanta.

    Every frame's d, r (lengths) and alpha, theta (angles); beta where the frame carries it; gamma
    and b where the frame hangs off a frame other than its predecessor (elsewhere they are
    structural zeros, not stored numbers); every marker's and the base's x, y, z. Rotation
    corrections and compliances are not stored dimensions.

    Parameters
    ----------
    {model}
    length_quantum : float
        Resolution lengths are stored with, m (0: exact).
    angle_quantum : float
        Resolution angles are stored with, rad (0: exact).

    Returns
    -------
    _Rounded
        The model's values as the controller stores them.
    """
    lay = layout(model)
    params = parameter_layout(model)
    quantum = {"length": length_quantum, "angle": angle_quantum}
    chosen = [params[n] for n in families(model)["geometric"]
              if params[n].quantity == "length" or params[n].role == "frame"]
    # parameter-vector order, so the random stream does not depend on how the families list them
    chosen.sort(key=lambda prm: prm.index)
    idx = np.array([prm.index for prm in chosen], dtype=int)
    return _Rounded(names=tuple(prm.name for prm in chosen), params=idx, steps=lay.param_step[idx],
                    quanta=np.array([quantum[prm.quantity] for prm in chosen], dtype=float))


def _nonnegative(value, name: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"expected a number, got {value!r}", where=name) from None
    if not math.isfinite(v) or v < 0:
        raise InputError(f"must be a finite number >= 0, got {value!r}", where=name)
    return v


def _count(value, name: str, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise InputError(f"must be an integer >= {minimum}, got {value!r}", where=name)
    return int(value)


def _resolution(model: RobotModel, encoder_resolution) -> np.ndarray:
    res = np.atleast_1d(np.asarray(encoder_resolution, dtype=float))
    if res.shape == (1,):
        res = np.repeat(res, model.n_joints)
    if res.shape != (model.n_joints,):
        raise InputError(f"expected one resolution per joint ({model.n_joints}), got {res.size}",
                         where="encoder_resolution")
    if not np.all(np.isfinite(res)) or np.any(res < 0):
        raise InputError(f"resolutions must be finite and >= 0, got {res.tolist()}", where="encoder_resolution")
    return res


def _generator(rng) -> np.random.Generator:
    if isinstance(rng, np.random.Generator):
        return rng
    if isinstance(rng, (int, np.integer)) and not isinstance(rng, bool):
        return np.random.default_rng(int(rng))
    raise InputError(f"expected a numpy Generator or an integer seed, got {rng!r}", where="rng")


def _error_model(model: RobotModel, encoder_resolution, length_quantum, angle_quantum):
    """Validated joint resolutions (n_joints,), the rounded parameters and the joint box."""
    res = _resolution(model, encoder_resolution)
    rp = rounded_parameters(model, _nonnegative(length_quantum, "length_quantum"),
                            _nonnegative(angle_quantum, "angle_quantum"))
    return res, rp, sampling_box(model)


def parameter_displacement(ps, rot: np.ndarray, steps: np.ndarray, on_path: np.ndarray,
                            dp: np.ndarray, P: np.ndarray) -> np.ndarray:
    """First-order tool displacement (N, 3) of the point P (N, 3) for per-pose errors dp (N, K).

    A rotation step by dp about unit axis u through Q moves P by dp u x (P - Q), a translation by
    dp u: the engine's own step geometry, so the sum is J_p(q) @ dp without forming J.
    """
    rot, steps, dp = rot[on_path], steps[on_path], dp[:, on_path]  # steps off the path do not move P
    w = ps.U[steps] * dp.T[:, :, None]                                  # (K, N, 3) scaled axes
    trans = w[~rot].sum(axis=0)
    wr = w[rot]
    # sum_k w_k x (P - Q_k) = (sum_k w_k) x P - sum_k w_k x Q_k
    turn = cross(wr.sum(axis=0), P) - cross(wr, ps.Q[steps[rot]]).sum(axis=0)
    return trans + turn


# seconds of one unit of the Monte Carlo's work (a sample on a frame, ``check_work``), for messages
SECONDS_PER_WORK = 2.5e-7


def check_work(model: RobotModel, n: int, markers: str, where: str = "n_samples") -> None:
    """Refuse, before it starts, a Monte Carlo that would run for minutes: each sample costs two
    passes down the frames and a displacement along each marker's path."""
    evaluated = len(model.markers) if markers == "all" else 1
    per = len(model.frames) * (1 + evaluated / 5)
    if n * per > MAX_LIMIT_WORK:
        raise InputError(f"{n:,} samples of a model of {len(model.frames)} frames ({evaluated} marker(s) evaluated) "
                         f"take about {n * per * SECONDS_PER_WORK:.0f} s; robocal runs up to about "
                         f"{MAX_LIMIT_WORK * SECONDS_PER_WORK:.0f} s, {int(MAX_LIMIT_WORK / per):,} samples of this "
                         "model: fewer samples", where=where)


@accepts(model=is_a(RobotModel), encoder_resolution=per_joint(), length_quantum=NON_NEGATIVE,
         angle_quantum=NON_NEGATIVE, n_samples=whole(1, MAX_SAMPLES), chunk_size=whole(1, MAX_CHUNK), rng=SEED,
         progress=optional(CALLABLE), markers=one_of(LIMIT_MARKER_MODES))
@one_blas_thread
def controller_precision(model: RobotModel, *, encoder_resolution, length_quantum: float,
                         angle_quantum: float, n_samples: int, chunk_size: int = DEFAULT_CHUNK, rng,
                         progress: Callable[[int, int], None] | None = None,
                         markers: str = "first") -> PrecisionResult:
    """Precision of the geometric control system by Monte Carlo over the workspace (metres).

    Model: the controller stores every dimensional parameter rounded to its quantum
    (``rounded_parameters``: lengths to ``length_quantum`` m, angles to ``angle_quantum`` rad), and
    reaches each joint within its ``encoder_resolution`` (one value per joint reading, rad or m,
    or one value for all). Per sample: a configuration q uniform within the joint limits, a joint
    error uniform in [-res/2, res/2] per joint and a round-off error uniform in [-quantum/2,
    quantum/2] per rounded parameter (the true value is unknown relative to the grid); the
    deviation is ``|P(p, q) - P(p + dp, q + dq)|`` for the first marker (``markers="first"``) or
    the largest over the markers (``markers="all"``).

    Exactness: the joint part is exact forward kinematics at q + dq; the parameter part is the
    first-order displacement J_p(q + dq) @ dp from the engine's step geometry. The neglected
    second-order term is ~|dp|^2 * reach, about 1e-10 m for 0.1 mm and 1e-3 deg quanta. The rigid
    model is used (no gravity deflection): deflection is common to both positions.

    Random stream: each sample consumes one row of ``rng.random((n, 2 n_joints + K))``, so the
    results do not depend on ``chunk_size``. Memory is bounded whatever ``n_samples``: the
    kinematics works on ``chunk_size`` configurations at a time, the moments are running sums and
    the percentiles come from a fixed histogram of ``HIST_BINS`` log-spaced bins over
    [1e-12 m, 1 m] (relative resolution 0.14 %). ``progress(done, total)`` is called after each chunk.

    Parameters
    ----------
    {model, encoder_resolution, length_quantum, angle_quantum, n_samples, chunk_size, rng, progress}
    markers : str
        ``first`` marker or ``all`` markers.

    Returns
    -------
    PrecisionResult
        Monte Carlo statistics of the position error the control leaves.
    """
    res, rp, (lo, hi) = _error_model(model, encoder_resolution, length_quantum, angle_quantum)
    n = _count(n_samples, "n_samples", 2)
    chunk = _count(chunk_size, "chunk_size", 1)
    check_choice(markers, MARKER_MODES, "markers")
    check_work(model, n, markers)
    gen = _generator(rng)
    lay = layout(model)
    p = parameter_vector(model)
    C = model.coupling_matrix
    rot = lay.step_is_rot[rp.steps]
    sel = range(len(model.markers)) if markers == "all" else range(1)
    nj, K = model.n_joints, len(rp.params)
    s1 = s2 = s4 = 0.0
    top = 0.0
    hist = np.zeros(HIST_BINS + 2, dtype=np.int64)   # under- and overflow at the ends
    for start in range(0, n, chunk):
        m = min(chunk, n - start)
        u = gen.random((m, 2 * nj + K))
        q = lo + (hi - lo) * u[:, :nj]
        dq = (u[:, nj:2 * nj] - 0.5) * res
        dp = (u[:, 2 * nj:] - 0.5) * rp.quanta
        ref = kinematic_pass(model, lay, p, q @ C.T).P
        ps = kinematic_pass(model, lay, p, (q + dq) @ C.T)
        P = ps.P
        assert ref is not None and P is not None  # passes with markers
        worst = np.zeros(m)
        for k in sel:
            d = P[k] + parameter_displacement(ps, rot, rp.steps, lay.marker_path[k, rp.steps], dp, P[k])
            worst = np.maximum(worst, np.linalg.norm(d - ref[k], axis=1))
        sq = worst * worst
        s1 += float(worst.sum())
        s2 += float(sq.sum())
        s4 += float((sq * sq).sum())
        top = max(top, float(worst.max()))
        hist += np.bincount(np.searchsorted(HIST_EDGES, worst, side="right"), minlength=HIST_BINS + 2)
        if progress is not None:
            progress(start + m, n)
    mean = s1 / n
    std = math.sqrt(max(s2 - n * mean * mean, 0.0) / (n - 1))
    msq = s2 / n
    rms = math.sqrt(msq)
    sq_std = math.sqrt(max(s4 - n * msq * msq, 0.0) / (n - 1))
    return PrecisionResult(
        n_samples=n, mean=mean, std=std, standard_error=std / math.sqrt(n), rms=rms,
        rms_standard_error=sq_std / math.sqrt(n) / (2 * rms) if rms > 0 else 0.0,
        percentiles=tuple((pct, _histogram_percentile(hist, pct, top)) for pct in PERCENTILES),
        max=top, encoder_resolution=tuple(float(v) for v in res), length_quantum=float(length_quantum),
        angle_quantum=float(angle_quantum), markers=markers, rounded_parameters=rp.names,
        method="exact forward kinematics for joint errors, first order (J_p dp) for parameter round-off")


@accepts(model=is_a(RobotModel), encoder_resolution=per_joint(), length_quantum=NON_NEGATIVE,
         angle_quantum=NON_NEGATIVE, n_configurations=whole(1, MAX_SAMPLES), chunk_size=whole(1, MAX_CHUNK), rng=SEED,
         marker=marker_of())
@one_blas_thread
def predicted_controller_precision(model: RobotModel, *, encoder_resolution, length_quantum: float,
                                   angle_quantum: float, n_configurations: int = 20000,
                                   chunk_size: int = 2048, rng, marker: int = 0) -> PredictedPrecision:
    """First-order prediction of ``controller_precision`` for one marker (metres).

    Per configuration q (uniform within the joint limits) the tool error is dP = J_q dq + J_p dp
    with independent uniform errors of variance res^2/12 per joint and quantum^2/12 per rounded
    parameter, so Cov(dP) = J Sigma J^T (J from ``evaluate(..., jacobian=True)``, rigid model).

    ``rms = sqrt(E_q trace Cov)`` is the right comparison with the Monte Carlo's RMS: second
    moments of a sum of independent errors add whatever their distribution, so it is exact to
    first order. A mean norm depends on the distribution; ``mean_gaussian`` samples
    dP ~ N(0, Cov) (one draw per configuration, as a Gaussian-weighted sum of J's columns) and is
    only as good as the Gaussian approximation of a sum of uniform errors.

    Parameters
    ----------
    {model, encoder_resolution, length_quantum, angle_quantum, n_configurations, chunk_size, rng, marker}

    Returns
    -------
    PredictedPrecision
        First-order prediction of the same.
    """
    res, rp, (lo, hi) = _error_model(model, encoder_resolution, length_quantum, angle_quantum)
    n = _count(n_configurations, "n_configurations", 2)
    chunk = _count(chunk_size, "chunk_size", 1)
    if not (0 <= marker < len(model.markers)):
        raise InputError(f"no marker {marker}; the model has {len(model.markers)}", where="marker")
    gen = _generator(rng)
    params = parameter_layout(model)
    p = parameter_vector(model)
    # joint reading j moves theta (revolute) or r (prismatic) of the frames coupled to it
    G = np.zeros((params.n_params, model.n_joints))
    for i, f in enumerate(model.frames):
        if f.joint != "fixed":
            G[params[f"{f.name}.{'theta' if f.joint == 'revolute' else 'r'}"].index] = model.coupling_matrix[i]
    sigma = np.concatenate([res, rp.quanta]) / math.sqrt(12.0)
    trace = np.empty(n)
    norm = np.empty(n)
    for start in range(0, n, chunk):
        m = min(chunk, n - start)
        q = lo + (hi - lo) * gen.random((m, model.n_joints))
        J = evaluate(model, q, p, jacobian=True, compliance=False).jacobian[:, marker, :3, :]
        Js = np.concatenate([J @ G, J[:, :, rp.params]], axis=2) * sigma     # (m, 3, nj + K)
        trace[start:start + m] = np.einsum("nak,nak->n", Js, Js)
        z = gen.standard_normal((m, Js.shape[2]))
        norm[start:start + m] = np.linalg.norm(np.einsum("nak,nk->na", Js, z), axis=1)
    ms = float(trace.mean())
    rms = math.sqrt(ms)
    return PredictedPrecision(
        n_configurations=n, rms=rms,
        rms_standard_error=float(trace.std(ddof=1) / math.sqrt(n) / (2 * rms)) if rms > 0 else 0.0,
        mean_gaussian=float(norm.mean()), mean_gaussian_standard_error=float(norm.std(ddof=1) / math.sqrt(n)),
        marker=model.markers[marker].name)


# -- the limit ---------------------------------------------------------------------------------

def accuracy_limit(repeatability, precision: PrecisionResult) -> AccuracyLimit:
    """The limit of absolute accuracy: repeatability RP + the geometric control's mean deviation.

    ``repeatability`` is RP in metres (a float) or a ``RepeatabilityResult`` (its worst pose's RP).

    Parameters
    ----------
    repeatability : RepeatabilityResult or float
        ISO 9283 repeatability (RP), or its value in m.
    precision : PrecisionResult
        The precision of the geometric control (``controller_precision``).

    Returns
    -------
    AccuracyLimit
        The limit of absolute accuracy and its parts.
    """
    detail = None
    if isinstance(repeatability, RepeatabilityResult):
        detail = repeatability
        rp = repeatability.rp
    else:
        rp = _nonnegative(repeatability, "repeatability")
    if not isinstance(precision, PrecisionResult):
        raise InputError(f"expected a PrecisionResult, got {type(precision).__name__}", where="precision")
    p95 = precision.percentile(95)
    return AccuracyLimit(repeatability=float(rp), precision=precision.mean, precision_p95=p95,
                         limit=float(rp) + precision.mean, limit_p95=float(rp) + p95,
                         precision_statistic="mean", repeatability_detail=detail, precision_detail=precision)
