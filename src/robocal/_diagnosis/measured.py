"""Diagnosis: why a fit is bad, tested against the data themselves (docs/diagnosis.md).

Each hypothesis is one function ``(model, data, result, noise, *, fit=None) -> Finding | None``: it
changes the data (or the model) the way one mistake would have, refits with the project's
``solve`` (or, for small effects, takes the Gauss-Newton step of the refit from the calibration's
solution), and returns what it found with the refitted residuals against the original. Its score
is the base-10 logarithm of the factor by which the refit reduces the residual variance (the sum
of squares over its degrees of freedom, the hypothesis' own freedom counted), plus
``PLAUSIBLE_BONUS`` when the refit turns implausible changes into plausible ones. ``diagnose``
runs them all and ranks what they found.

Large campaigns are diagnosed on at most ``MAX_POSES`` poses spread evenly along the campaign (the
rows, joints and markers a finding names still refer to the whole campaign).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from itertools import combinations
from typing import cast

import numpy as np

from .._base.arguments import accepts, both, is_a, measured_on, names_in, noise_of, optional
from .._base.errors import DegenerateDataError, InputError
from .._base.options import DEFAULT_INSTRUMENT, INSTRUMENT_NOISE
from .._base.threads import one_blas_thread
from .._identification.checks import outlier_bar, tolerances
from .._identification.points import Points
from .._identification.problem import Problem
from .._identification.registration import rigid_base as register_base
from .._identification.result import CalibrationResult
from .._identification.solve import solve
from .._model.kinematics import evaluate
from .._model.measurements import Measurements, Noise
from .._model.parameters import (
    candidate_parameters,
    model_from_vector,
    needs_compliance,
    parameter_layout,
    parameter_vector,
)
from .._model.robot import Payload, RobotModel

# a hypothesis is named when its refit divides the residual variance by at least this factor
NAMED_FACTOR = 4.0
# others are shown beside the most likely one when their factor is within this factor of its own
CLOSE_FACTOR = 4.0
# added to the score (log10) of a refit that turns implausible changes into plausible ones
PLAUSIBLE_BONUS = 1.0
# the stated noise is called wrong when the scatter is this many times it, or this many times less
NOISE_FACTOR = 5.0
# diagnose at most this many poses, spread evenly along the campaign
MAX_POSES = 1000
# a hypothesis is refitted on at most this many poses, spread evenly
REFIT_POSES = 500
# the cheap rigid matches that choose what to refit look at most at this many poses
SCREEN_POSES = 200
# the solver's budget per refit
MAX_NFEV = 15
# row shifts tried (rows from a row on hold the point of the pose this many rows later)
SHIFTS = (1, 2, 3, -1, -2, -3)
# a change point is looked for with at least this share of the poses on each side
EDGE_SHARE = 0.05
# known factors between units, as the value read over the true one: positions, angles, masses
LENGTH_FACTORS = {1e3: "millimetres read as metres", 1e-3: "metres read as millimetres",
                  10.0: "millimetres read as centimetres", 0.1: "centimetres read as millimetres",
                  25.4: "millimetres read as inches", 1 / 25.4: "inches read as millimetres"}
ANGLE_FACTORS = {180 / np.pi: "degrees read as radians", np.pi / 180: "radians read as degrees"}
MASS_FACTORS = {1e3: "grams read as kilograms", 1e-3: "kilograms read as grams"}
# payloads heavier than this many times the robot's moving links (the model's masses) are implausible
HEAVY_PAYLOAD = 10.0


@dataclass(frozen=True)
class Finding:
    """One hypothesis that explains (part of) the misfit.

    ``cause`` says it in words, ``evidence`` with the refitted residuals against the original,
    ``items`` names the rows, joints or markers involved; ``score`` (log10 of the penalised factor
    by which the refit reduces the residual variance, plus ``PLAUSIBLE_BONUS`` when it makes the
    changes plausible) is comparable across hypotheses; ``rms_before``/``rms_after`` are the
    per-axis position residual RMS (m) of the original fit and of the refit (None when the
    hypothesis needs no refit); ``fix`` says how to act on it.
    """

    hypothesis: str
    cause: str
    evidence: str
    score: float
    items: tuple[str, ...] = ()
    rms_before: float | None = None
    rms_after: float | None = None
    fix: str = ""


@dataclass(frozen=True)
class Diagnosis:
    """The findings, most likely first (the others only when close to it), the hypotheses tested
    and a one-line ``summary``: the most likely cause, or that nothing tested explains the misfit."""

    findings: tuple[Finding, ...]
    tested: tuple[str, ...]
    summary: str
    rms: float

    @property
    def cause(self) -> Finding | None:
        """The most likely cause, or None."""
        return self.findings[0] if self.findings else None


@dataclass(frozen=True, eq=False)
class _Fit:
    """The original fit, redone with the linear loss on the poses diagnosed: what every hypothesis
    compares against. ``J`` the weighted Jacobian (n_rows, n_free), ``r`` the residuals, ``row_pose``
    the pose (of ``data``) of each row, ``positions0`` the nominal robot's marker positions with
    its base at the origin (n_poses, n_markers, 3)."""

    model: RobotModel
    start: RobotModel
    names: tuple[str, ...]
    data: Measurements
    rows: np.ndarray
    noise: Noise
    p: np.ndarray
    r: np.ndarray
    J: np.ndarray
    row_pose: np.ndarray
    ssr: float
    rms: float
    implausible: int
    base_free: bool
    positions0: np.ndarray
    Q: np.ndarray
    load: np.ndarray

    @property
    def dof(self) -> int:
        return max(len(self.r) - len(self.names), 1)


@dataclass(frozen=True, eq=False)
class _Outcome:
    """A refit: its weighted sum of squares over ``n_rows`` rows, position RMS per axis (m), and
    the number of implausible changes."""

    ssr: float
    n_rows: int
    rms: float
    implausible: int


# -- the shared machinery --------------------------------------------------------------------------

def as_noise(noise) -> Noise:
    """A ``Noise`` from a ``Noise``, an instrument class name or None (the default instrument's)."""
    return noise if isinstance(noise, Noise) else Noise.of(noise or DEFAULT_INSTRUMENT)


def _working_rows(n: int, most: int = MAX_POSES) -> np.ndarray:
    """At most ``most`` row indices spread evenly over ``n`` rows.

    >>> _working_rows(5, 3).tolist()
    [0, 2, 4]
    """
    return np.arange(n) if n <= most else np.unique(np.linspace(0, n - 1, most).round().astype(int))


def _row_pose(prob: Points) -> np.ndarray:
    """The pose of each residual row of ``prob`` (markers, then poses, x y z; then rotations)."""
    parts = [np.repeat(s, 3) for s in prob.sel]
    if prob.use_rot:
        parts += [np.repeat(s, 3) for s in prob.sel_r]
    return np.concatenate(parts)


def _position_rms(prob: Points, p: np.ndarray) -> float:
    e = prob.errors(p)[prob.data.mask]
    return float(np.sqrt(np.mean(e ** 2))) if e.size else 0.0


def count_implausible(model: RobotModel, start: np.ndarray, p: np.ndarray, names) -> int:
    """How many of ``names`` moved from ``start`` beyond their family's tolerance (compliances aside)."""
    lay = parameter_layout(model)
    tol = tolerances(model)
    n = 0
    for name in names:
        par = lay[name]
        bound = tol.get((par.family, par.quantity))
        if bound is not None and par.quantity != "compliance" and abs(p[par.index] - start[par.index]) > bound:
            n += 1
    return n


def _base_at_origin(model: RobotModel) -> RobotModel:
    return model.replace(base_position=(0.0, 0.0, 0.0), base_rotation=((1.0, 0, 0), (0, 1.0, 0), (0, 0, 1.0)))


def _nominal_positions(model: RobotModel, data: Measurements) -> np.ndarray:
    """(n_poses, n_data_markers, 3) the nominal robot's marker positions, base at the origin."""
    ev = evaluate(_base_at_origin(model), data.q, payload_mass=data.payload_mass)
    return ev.positions[:, [model.marker_names.index(n) for n in data.marker_names]]


@one_blas_thread
def baseline(model: RobotModel, data: Measurements, result: CalibrationResult, noise=None) -> _Fit:
    """The original fit redone with the linear loss from the calibration's solution, on the poses
    diagnosed (at most ``MAX_POSES``): the reference of every hypothesis."""
    rows = _working_rows(data.n_poses)
    work = data if len(rows) == data.n_poses else data.subset(rows)
    names = tuple(result.parameter_names)
    start = result.calibrated_model
    fit_noise = as_noise(noise)
    prob = Problem(start, names, data=work, compliance=needs_compliance(start, names), noise=fit_noise)
    sol = solve(prob, parameter_vector(start), max_nfev=MAX_NFEV)
    J = np.array(prob.jacobian(sol.p))
    lay = parameter_layout(model)
    return _Fit(model=model, start=start, names=names, data=work, rows=rows, noise=as_noise(noise), p=sol.p,
                r=sol.residuals, J=J, row_pose=_row_pose(cast(Points, prob.points)),
                ssr=float(sol.residuals @ sol.residuals),
                rms=_position_rms(cast(Points, prob.points), sol.p),
                implausible=count_implausible(model, parameter_vector(model), sol.p, names),
                base_free=any(lay[n].family == "base" for n in names),
                positions0=_nominal_positions(model, work), Q=np.linalg.qr(J)[0], load=_load_columns(start, work,
                                                                                                   sol.p, fit_noise))


def _fit_of(model, data, result, noise, fit: _Fit | None) -> _Fit:
    return fit if fit is not None else baseline(model, data, result, noise)


@one_blas_thread
def _refit(fit: _Fit, data: Measurements, *, model: RobotModel | None = None, registered: bool = True
           ) -> _Outcome | None:
    """The fit of ``data`` (changed as a hypothesis says; all its rows, or ``REFIT_POSES`` of them),
    from the nominal model with its base registered on them (``registered``), or from the
    calibration's solution; None when the changed data cannot be fitted."""
    rows = _working_rows(data.n_poses, REFIT_POSES)
    work = data if len(rows) == data.n_poses else data.subset(rows)
    m = model if model is not None else (fit.model if registered else fit.start)
    try:
        if registered and fit.base_free:
            m = register_base(m, work)
        prob = Problem(m, fit.names, data=work, compliance=needs_compliance(m, fit.names), noise=fit.noise)
        p0 = parameter_vector(m)
        sol = solve(prob, p0, max_nfev=MAX_NFEV)
    except (DegenerateDataError, InputError, np.linalg.LinAlgError, ValueError):
        return None
    ssr = float(sol.residuals @ sol.residuals)
    if not np.isfinite(ssr):
        return None
    start = parameter_vector(fit.model if model is None else model) if not registered else p0
    return _Outcome(ssr=ssr, n_rows=len(sol.residuals), rms=_position_rms(cast(Points, prob.points), sol.p),
                    implausible=count_implausible(m, start, sol.p, fit.names))


def _score(fit: _Fit, ssr: float, n_rows: int, freedom: float, implausible: int | None = None) -> float:
    """log10 of the factor by which a refit (``ssr`` over ``n_rows`` rows, ``freedom`` parameters of
    its own) divides the residual variance, with ``PLAUSIBLE_BONUS`` when it makes the changes
    plausible (and less when it makes them implausible)."""
    after = max(ssr, 1e-300) / max(n_rows - len(fit.names) - freedom, 1.0)
    before = max(fit.ssr, 1e-300) / fit.dof
    score = float(np.log10(before / after))
    if implausible is not None:
        if fit.implausible and not implausible:
            score += PLAUSIBLE_BONUS
        elif implausible and not fit.implausible:
            score -= PLAUSIBLE_BONUS
    return score


def _bic(ssr: float, n_rows: int, k: int) -> float:
    """The Bayesian information criterion of a fit of ``k`` more parameters leaving ``ssr``: which of
    several groups of parameters a step or a drift moved (the fewest that explain it)."""
    return float(n_rows * np.log(max(ssr, 1e-300) / n_rows) + k * np.log(n_rows))


def _mm(v: float) -> str:
    return f"{v * 1e3:.3g} mm"


def _found(fit: _Fit, out: _Outcome, hypothesis: str, cause: str, how: str, freedom: float, items=(), fix="",
           scale: float = 1.0) -> Finding:
    """A finding from a refit: the evidence is its residuals against the original fit's. ``scale``:
    the factor from the refitted positions' unit back to the data's as given (the sums of squares
    are compared in the data's)."""
    evidence = f"refitted {how}: {_mm(out.rms)} against {_mm(fit.rms)} RMS per axis"
    if fit.implausible and not out.implausible:
        evidence += f", and the {fit.implausible} implausible change(s) become plausible"
    score = _score(fit, out.ssr * scale ** 2, out.n_rows, freedom, out.implausible)
    return Finding(hypothesis, cause, evidence, score, tuple(items), fit.rms, out.rms, fix)


def _screen(fit: _Fit, data: Measurements, model: RobotModel | None = None) -> float:
    """How well the nominal robot (or ``model``), moved rigidly, matches ``data`` (at most
    ``SCREEN_POSES`` of its poses): cheap, to choose which changed data to refit."""
    rows = _working_rows(data.n_poses, SCREEN_POSES)
    work = data if len(rows) == data.n_poses else data.subset(rows)
    same_q = model is None and data.n_poses == fit.data.n_poses and np.array_equal(data.q, fit.data.q)
    P = fit.positions0[_working_rows(fit.data.n_poses, SCREEN_POSES)] if same_q else \
        _nominal_positions(model or fit.model, work)
    return float(rigid_misfit(_moments(P, work.positions, work.mask).sum(0)))


def _with(data: Measurements, **changes) -> Measurements:
    """``data`` with some arrays replaced (the approach directions of its own order kept)."""
    return replace(data.with_approach(), **changes)


def _paired(data: Measurements, q_rows: np.ndarray, point_rows: np.ndarray) -> Measurements:
    """The readings of ``q_rows`` with the measured values of ``point_rows``."""
    base = data.with_approach().subset(q_rows)

    def take(a):
        return None if a is None else a[point_rows]

    return replace(base, positions=data.positions[point_rows], mask=data.mask[point_rows],
                   rotations=take(data.rotations), rot_mask=take(data.rot_mask), sigma=take(data.sigma),
                   sigma_rot=take(data.sigma_rot))


def shifted_rows(n: int, row: int, k: int, *, cyclic: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The rows of readings and of points to pair when, from ``row`` on, each row holds the point of
    the pose ``k`` rows later (a missed shot for k > 0, an extra one for k < 0): (reading rows, point
    rows). Without ``cyclic`` the rows left without a partner are dropped.

    >>> [a.tolist() for a in shifted_rows(5, 2, 1)]
    [[0, 1, 3, 4], [0, 1, 2, 3]]
    >>> [a.tolist() for a in shifted_rows(4, 0, -1, cyclic=True)]
    [[3, 0, 1, 2], [0, 1, 2, 3]]
    """
    r = np.arange(n)
    if cyclic:
        return np.where(r >= row, row + (r - row + k) % max(n - row, 1), r), r
    src = np.where(r >= row, r + k, r)
    keep = (r < row) | ((src >= row) & (src < n))
    return src[keep], r[keep]


def _moments(P: np.ndarray, Q: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """(n, 18) per row the sufficient statistics of a rigid match of points ``P`` to ``Q`` (n, m, 3)
    over the markers ``mask`` (n, m): count, sums of P and Q, sums of squares, sum of P Q^T."""
    w = mask.astype(float)[..., None]
    P, Q = np.where(w > 0, P, 0.0), np.where(w > 0, Q, 0.0)
    return np.concatenate([w[..., 0].sum(1)[:, None], P.sum(1), Q.sum(1), (P ** 2).sum((1, 2))[:, None],
                           (Q ** 2).sum((1, 2))[:, None], np.einsum("nmi,nmj->nij", P, Q).reshape(len(P), 9)], axis=1)


def rigid_misfit(moments: np.ndarray) -> np.ndarray:
    """Sum of squared distances left by the best rigid motion of P onto Q, from summed ``_moments``
    (..., 18); infinite with fewer than three points."""
    c, sp, sq = moments[..., 0], moments[..., 1:4], moments[..., 4:7]
    cs = np.maximum(c, 1.0)[..., None]
    H = moments[..., 9:].reshape(moments.shape[:-1] + (3, 3)) - sp[..., :, None] * sq[..., None, :] / cs[..., None]
    s = np.linalg.svd(H, compute_uv=False)
    sign = np.sign(np.linalg.det(H))
    spread = moments[..., 7] - np.sum(sp ** 2, -1) / cs[..., 0] + moments[..., 8] - np.sum(sq ** 2, -1) / cs[..., 0]
    out = spread - 2.0 * (s[..., 0] + s[..., 1] + np.where(sign < 0, -1.0, 1.0) * s[..., 2])
    return np.where(c >= 3, np.maximum(out, 0.0), np.inf)


# -- hypotheses: the order of the rows -------------------------------------------------------------

def _all_positions(fit: _Fit, data: Measurements) -> np.ndarray:
    """The nominal robot's marker positions (base at the origin) at every pose of ``data``."""
    return fit.positions0 if fit.data.n_poses == data.n_poses else _nominal_positions(fit.model, data)


def _shift_misfits(P: np.ndarray, data: Measurements, k: int) -> np.ndarray:
    """(n,) per row i (0 unused) the rigid misfit per point of the nominal positions ``P`` to the
    points when, from row i on, each row holds the point of the pose ``k`` rows later: cumulative
    sums of the rigid match's statistics, so every row is tried at once."""
    n = data.n_poses
    same = _moments(P, data.positions, data.mask)
    r = np.arange(n)
    src = np.clip(r + k, 0, n - 1)
    moved = _moments(P[src], data.positions, data.mask) * ((r + k >= 0) & (r + k < n))[:, None]
    before = np.vstack([np.zeros(18), np.cumsum(same, axis=0)])             # rows < i
    after = np.vstack([np.cumsum(moved[::-1], axis=0)[::-1], np.zeros(18)])  # rows >= j
    i = np.arange(n)
    total = before[i] + after[np.minimum(i + max(0, -k), n)]
    return rigid_misfit(total) / np.maximum(total[:, 0], 1.0)


def rows_shifted(model, data: Measurements, result, noise=None, *, fit: _Fit | None = None) -> Finding | None:
    """From some row on, each row holds the point of another pose (a missed or an extra shot): every
    row and shift in ``SHIFTS`` screened at once by a rigid match of the nominal robot (cumulative
    sums), the best refitted."""
    fit = _fit_of(model, data, result, noise, fit)
    n = data.n_poses
    if n < 8:
        return None
    P = _all_positions(fit, data)
    plain = float(rigid_misfit(_moments(P, data.positions, data.mask).sum(0))) / max(data.mask.sum(), 1)
    best = (plain, 0, 0)
    for k in SHIFTS:
        m = _shift_misfits(P, data, k)[1: n - 2]
        j = int(np.argmin(m))
        if m[j] < best[0]:
            best = (float(m[j]), j + 1, k)
    _, row, k = best
    if k == 0:
        return None
    out = _refit(fit, _paired(data, *shifted_rows(n, row, k)))
    if out is None:
        return None
    label = data.labels[row]
    what = "next" if k == 1 else (f"{k} rows later" if k > 0 else ("previous" if k == -1 else f"{-k} rows earlier"))
    pose = f"the {what} pose's point" if abs(k) == 1 else f"the point of the pose {what}"
    return _found(fit, out, "rows shifted", f"rows from {label} on hold {pose} ({'a missed' if k > 0 else 'an extra'}"
                  " shot)", "with that shift", 2.0 + np.log2(n), items=(label,),
                  fix=f"re-pair the rows from {label} on with their poses (or remove them) and calibrate again")


def pose_labels_offset(model, data: Measurements, result, noise=None, *, fit: _Fit | None = None
                       ) -> Finding | None:
    """Readings and points joined with pose labels off by a few (P00.. against P01..): every row
    holds another pose's point, cyclically or with the rows at the end left unpaired."""
    fit = _fit_of(model, data, result, noise, fit)
    n = data.n_poses
    P = _all_positions(fit, data)
    best = (float(rigid_misfit(_moments(P, data.positions, data.mask).sum(0))) / max(data.mask.sum(), 1), 0, False)
    for k in SHIFTS:
        for cyclic in (False, True):
            qr, pr = shifted_rows(n, 0, k, cyclic=cyclic)
            mo = _moments(P[qr], data.positions[pr], data.mask[pr]).sum(0)
            v = float(rigid_misfit(mo)) / max(mo[0], 1.0)
            if v < best[0]:
                best = (v, k, cyclic)
    _, k, cyclic = best
    if k == 0:
        return None
    out = _refit(fit, _paired(data, *shifted_rows(n, 0, k, cyclic=cyclic)))
    if out is None:
        return None
    later = "later" if k > 0 else "earlier"
    return _found(fit, out, "pose labels offset", f"readings and points are paired {abs(k)} pose(s) apart: each row "
                  f"holds the point of the pose {abs(k)} row(s) {later}"
                  + (" (the rows wrap around)" if cyclic else ""),
                  "with the points moved by that offset", 1.0 + np.log2(2 * len(SHIFTS)),
                  fix="join the readings and the points on the right pose labels (check the first label of each "
                      "file)")


# -- hypotheses: the measured values ----------------------------------------------------------------

def _mirror(data: Measurements, axis: int) -> Measurements:
    M = np.ones(3)
    M[axis] = -1.0
    rot = None if data.rotations is None else data.rotations * M[:, None] * M[None, :]
    return _with(data, positions=data.positions * M, rotations=rot)


def mirrored_frame(model, data: Measurements, result, noise=None, *, fit: _Fit | None = None) -> Finding | None:
    """A left-handed measurement frame (one axis mirrored, or two axes swapped throughout): refitted
    with one axis mirrored (all three when the base pose is not identified, since then which one
    matters)."""
    fit = _fit_of(model, data, result, noise, fit)
    data = fit.data     # a change of each row alone: the poses diagnosed are enough
    axes = (0,) if fit.base_free else (0, 1, 2)
    outs = [(a, _refit(fit, _mirror(data, a))) for a in axes]
    outs = [(a, o) for a, o in outs if o is not None]
    if not outs:
        return None
    a, out = min(outs, key=lambda ao: ao[1].ssr)
    which = "one axis" if fit.base_free else f"the {'xyz'[a]} axis"
    return _found(fit, out, "mirrored frame", "the measurement frame is left-handed (an axis mirrored, or two axes "
                  "swapped in every marker's columns)", f"with {which} mirrored", 0.0,
                  fix="check the instrument's axis convention and the order of the x, y, z columns")


def _swap_axes(data: Measurements, marker: int, a: int, b: int) -> Measurements:
    pos = data.positions.copy()
    pos[:, marker, [a, b]] = pos[:, marker, [b, a]]
    return _with(data, positions=pos)


def axes_swapped(model, data: Measurements, result, noise=None, *, fit: _Fit | None = None) -> Finding | None:
    """Two axes swapped in one marker's columns (with two markers or more; in the only marker it is
    a mirrored frame): the swap the nominal robot matches best is refitted."""
    fit = _fit_of(model, data, result, noise, fit)
    data = fit.data     # a change of each row alone: the poses diagnosed are enough
    if len(data.marker_names) < 2:
        return None
    cands = [(m, a, b) for m in range(len(data.marker_names)) for a, b in combinations(range(3), 2)]
    scores = [_screen(fit, _swap_axes(data, *c)) for c in cands]
    m, a, b = cands[int(np.argmin(scores))]
    out = _refit(fit, _swap_axes(data, m, a, b))
    if out is None:
        return None
    name = data.marker_names[m]
    return _found(fit, out, "axes swapped", f"the {'xyz'[a]} and {'xyz'[b]} columns of marker {name} are swapped",
                  "with them swapped back", 1.0, items=(name,), fix=f"swap the {'xyz'[a]} and {'xyz'[b]} columns of "
                  f"marker {name} back")


def _swap_markers(data: Measurements, a: int, b: int) -> Measurements:
    idx = np.arange(len(data.marker_names))
    idx[[a, b]] = idx[[b, a]]

    def take(x):
        return None if x is None else x[:, idx]

    return _with(data, positions=data.positions[:, idx], mask=data.mask[:, idx], rotations=take(data.rotations),
                 rot_mask=take(data.rot_mask), sigma=take(data.sigma), sigma_rot=take(data.sigma_rot))


def markers_swapped(model, data: Measurements, result, noise=None, *, fit: _Fit | None = None) -> Finding | None:
    """Two markers' columns swapped (names or columns): the swap the nominal robot matches best is
    refitted."""
    fit = _fit_of(model, data, result, noise, fit)
    data = fit.data     # a change of each row alone: the poses diagnosed are enough
    pairs = list(combinations(range(len(data.marker_names)), 2))
    if not pairs:
        return None
    a, b = pairs[int(np.argmin([_screen(fit, _swap_markers(data, *p)) for p in pairs]))]
    out = _refit(fit, _swap_markers(data, a, b))
    if out is None:
        return None
    names = (data.marker_names[a], data.marker_names[b])
    return _found(fit, out, "markers swapped", f"markers {names[0]} and {names[1]} are swapped", "with them swapped "
                  "back", 1.0, items=names, fix=f"swap the columns (or names) of markers {names[0]} and {names[1]}")


def marker_copied(model, data: Measurements, result, noise=None, *, fit: _Fit | None = None) -> Finding | None:
    """One marker's values equal to another's (a column filled from the wrong marker), where the
    model sets them apart: no refit, the measured separation against the nominal one."""
    fit = _fit_of(model, data, result, noise, fit)
    best = None
    for a, b in combinations(range(len(data.marker_names)), 2):
        both = fit.data.mask[:, a] & fit.data.mask[:, b]
        if both.sum() < 3:
            continue
        gap = float(np.sqrt(np.mean((fit.data.positions[both, a] - fit.data.positions[both, b]) ** 2)))
        apart = float(np.sqrt(np.mean((fit.positions0[both, a] - fit.positions0[both, b]) ** 2)))
        floor = np.sqrt(2.0) * fit.noise.position
        if gap <= 3.0 * floor and apart > 10.0 * max(gap, floor):
            score = float(2.0 * np.log10(apart / max(gap, floor)))
            if best is None or score > best.score:
                names = (data.marker_names[a], data.marker_names[b])
                best = Finding("marker copied", f"marker {names[1]}'s values equal marker {names[0]}'s",
                               f"the two differ by {_mm(gap)} RMS per axis where the model sets them {_mm(apart)} "
                               "apart", score, names, fit.rms, None,
                               f"fill marker {names[1]}'s columns with its own measurements (or drop them)")
    return best


def blunders(model, data: Measurements, result, noise=None, *, fit: _Fit | None = None) -> Finding | None:
    """A few measured points far from the rest (a mistyped value, a shot while moving): refitted
    without the points beyond the outlier bar, each counted as three parameters."""
    fit = _fit_of(model, data, result, noise, fit)
    d = fit.data
    err = _point_errors(fit)
    norms = np.linalg.norm(err, axis=2)
    comps = err[d.mask].ravel()
    robust = 1.4826 * float(np.median(np.abs(comps - np.median(comps)))) if comps.size else 0.0
    z = np.where(d.mask, norms, 0.0) / max(robust, fit.noise.position)
    out_pts = z > outlier_bar(int(d.mask.sum()))
    k = int(out_pts.sum())
    if not k or k > 0.2 * d.mask.sum():
        return None
    out = _refit(fit, _with(d, mask=d.mask & ~out_pts), registered=False)
    if out is None:
        return None
    rows, cols = np.nonzero(out_pts)
    items = tuple(f"{d.labels[r]}, marker {d.marker_names[c]}" for r, c in zip(rows, cols))
    return _found(fit, out, "blunders", f"{k} measured point(s) are blunders", "without them", 3.0 * k, items=items,
                  fix="check or remove those measurements")


def _point_errors(fit: _Fit) -> np.ndarray:
    """(n_poses, n_markers, 3) the original fit's position errors on the poses diagnosed (0 where
    not measured)."""
    prob = Points(fit.start, fit.data, (), compliance=needs_compliance(fit.start, fit.names), noise=fit.noise)
    e = prob.errors(fit.p)
    return np.where(fit.data.mask[..., None], e, 0.0)


def unit_factor(model, data: Measurements, result, noise=None, *, fit: _Fit | None = None) -> Finding | None:
    """Positions, joint readings or payload masses in another unit than declared: the factor the
    nominal robot matches best is refitted."""
    fit = _fit_of(model, data, result, noise, fit)
    data = fit.data     # a change of each row alone: the poses diagnosed are enough
    cands = []
    for f, why in LENGTH_FACTORS.items():
        cands.append((f"positions: {why}", (), _with(data, positions=data.positions / f), f))
    quantities = np.array(model.reading_quantities)
    for quantity, factors in (("angle", ANGLE_FACTORS), ("length", LENGTH_FACTORS)):
        joints = np.nonzero(quantities == quantity)[0]
        if quantity == "length":
            factors = {f: w for f, w in factors.items() if f in (1e3, 1e-3)}
        for f, why in factors.items():
            groups = ([joints] if len(joints) else []) + ([[j] for j in joints] if len(joints) > 1 else [])
            for g in groups:
                q = data.q.copy()
                q[:, g] = q[:, g] / f
                names = tuple(model.joint_names[j] for j in g)
                cands.append((f"joint readings of {', '.join(names)}: {why}", names, _with(data, q=q), 1.0))
    best = min(cands, key=lambda c: _screen(fit, c[2]) * c[3] ** 2)
    found = _refit_found(fit, best[2], "unit factor", best[0], "in that unit", 1.0, best[1],
                         "declare the unit of those columns (e.g. x_mm, j1_deg) and calibrate again", scale=best[3])
    masses = _payload_unit(fit, data)
    return max((f for f in (found, masses) if f is not None), key=lambda f: f.score, default=None)


def _heavy_payload(model: RobotModel, masses: np.ndarray) -> bool:
    """Whether payload ``masses`` (kg) are implausible for ``model``: heavier than ``HEAVY_PAYLOAD``
    times the mass of its moving links (False when the model states no link masses)."""
    links = sum(f.mass for f in model.frames)
    return bool(links > 0 and masses.size and np.max(masses) > HEAVY_PAYLOAD * links)


def _payload_unit(fit: _Fit, data: Measurements) -> Finding | None:
    """Payload masses in another unit: each factor refitted. Payloads many times heavier than the
    robot's links that the factor brings within reach count as implausible values made plausible
    (``PLAUSIBLE_BONUS``) when the refit also fits better."""
    if data.payload_mass is None or not np.any(data.payload_mass):
        return None
    heavy = _heavy_payload(fit.model, data.payload_mass)
    found = []
    for f, why in MASS_FACTORS.items():
        got = _refit_found(fit, _with(data, payload_mass=data.payload_mass / f), "unit factor",
                           f"payload masses: {why}", "in that unit", 1.0, ("payload",),
                           "declare the payload column's unit (payload_kg) and calibrate again", registered=False)
        if got is not None and heavy and got.score > 0 and not _heavy_payload(fit.model, data.payload_mass / f):
            got = replace(got, score=got.score + PLAUSIBLE_BONUS, evidence=got.evidence + (
                f"; the payloads read, up to {np.max(data.payload_mass):.4g} kg, are over {HEAVY_PAYLOAD:g} "
                f"times the robot's links ({sum(fr.mass for fr in fit.model.frames):.4g} kg)"))
        found.append(got)
    return max((f for f in found if f is not None), key=lambda f: f.score, default=None)


def _refit_found(fit: _Fit, data_h: Measurements, hypothesis: str, cause: str, how: str, freedom: float,
                 items=(), fix: str = "", registered: bool = True, model: RobotModel | None = None,
                 scale: float = 1.0) -> Finding | None:
    out = _refit(fit, data_h, registered=registered, model=model)
    return None if out is None else _found(fit, out, hypothesis, cause, how, freedom, items, fix, scale)


# -- hypotheses: the joints -----------------------------------------------------------------------

def _scaled(data: Measurements, joint: int, factor: float) -> Measurements:
    q = data.q.copy()
    q[:, joint] *= factor
    return _with(data, q=q)


def _joint_scale_columns(fit: _Fit, h: float = 1e-6) -> np.ndarray:
    """(n_rows, n_joints) the change of the residuals per unit relative scale of each joint reading,
    at the original fit (finite differences)."""
    compliance = needs_compliance(fit.start, fit.names)
    cols = []
    for j in range(fit.data.q.shape[1]):
        prob = Problem(fit.start, fit.names, data=_scaled(fit.data, j, 1.0 + h), compliance=compliance, noise=fit.noise)
        cols.append((prob.residuals(fit.p) - fit.r) / h)
    return np.stack(cols, axis=1)


def _projected_gain(fit: _Fit, Z: np.ndarray) -> tuple[float, np.ndarray]:
    """The reduction of the sum of squares and the coefficients (k,) when columns ``Z`` (n_rows, k)
    join the fit's Jacobian (one Gauss-Newton step from the original fit)."""
    Q = fit.Q
    Zp = Z - Q @ (Q.T @ Z)
    rp = fit.r - Q @ (Q.T @ fit.r)
    coef, *_ = np.linalg.lstsq(Zp, -rp, rcond=1e-10)
    return float(rp @ rp - np.sum((rp + Zp @ coef) ** 2)), coef


def joint_scale(model, data: Measurements, result, noise=None, *, fit: _Fit | None = None) -> Finding | None:
    """A joint that turns a little more or less than its reading (a gear ratio off): the joint whose
    scale explains most at the original fit (one Gauss-Newton step each), refitted at that scale."""
    fit = _fit_of(model, data, result, noise, fit)
    data = fit.data     # a change of each row alone: the poses diagnosed are enough
    C = _joint_scale_columns(fit)
    Zp = C - fit.Q @ (fit.Q.T @ C)
    rp = fit.r - fit.Q @ (fit.Q.T @ fit.r)
    norm = np.maximum(np.sum(Zp ** 2, axis=0), 1e-300)
    j = int(np.argmax((Zp.T @ rp) ** 2 / norm))
    s = float(-(Zp[:, j] @ rp) / norm[j])
    if not np.isfinite(s) or abs(s) > 0.5 or s == 0.0:
        return None
    name = model.joint_names[j]
    return _refit_found(fit, _scaled(data, j, 1.0 + s), "joint scale", f"joint {name} moves {1.0 + s:.4g} times its "
                        "reading (a gear ratio or a reading scale off)", "with that scale",
                        1.0 + np.log2(C.shape[1]), (name,), f"correct the gear ratio (or scale) of joint {name} in "
                        "the controller or the readings", registered=False)


def joint_sign(model, data: Measurements, result, noise=None, *, fit: _Fit | None = None) -> Finding | None:
    """A joint reading with the wrong sign: the joints whose flip the nominal robot matches best are
    refitted from the nominal model (a flip a mirrored wrist absorbs fits as well, with implausible
    changes: the refit makes them plausible)."""
    fit = _fit_of(model, data, result, noise, fit)
    data = fit.data     # a change of each row alone: the poses diagnosed are enough
    n_j = data.q.shape[1]
    order = np.argsort([_screen(fit, _scaled(data, j, -1.0)) for j in range(n_j)])
    found = [_refit_found(fit, _scaled(data, j, -1.0), "joint sign", f"joint {model.joint_names[j]}'s readings have "
                          "the wrong sign", "with its sign flipped", np.log2(n_j), (model.joint_names[j],),
                          f"reverse the sign of joint {model.joint_names[j]}'s readings (or its direction in the "
                          "model)") for j in order[:1]]
    return max((f for f in found if f is not None), key=lambda f: f.score, default=None)


def joints_swapped(model, data: Measurements, result, noise=None, *, fit: _Fit | None = None) -> Finding | None:
    """Two joint columns swapped (of the same kind): the swap the nominal robot matches best is
    refitted."""
    fit = _fit_of(model, data, result, noise, fit)
    data = fit.data     # a change of each row alone: the poses diagnosed are enough
    kinds = model.reading_quantities
    pairs = [(a, b) for a, b in combinations(range(data.q.shape[1]), 2) if kinds[a] == kinds[b]]
    if not pairs:
        return None

    def swapped(a, b):
        q = data.q.copy()
        q[:, [a, b]] = q[:, [b, a]]
        return _with(data, q=q)

    a, b = pairs[int(np.argmin([_screen(fit, swapped(*p)) for p in pairs]))]
    names = (model.joint_names[a], model.joint_names[b])
    return _refit_found(fit, swapped(a, b), "joints swapped", f"the columns of joints {names[0]} and {names[1]} are "
                        "swapped", "with them swapped back", np.log2(len(pairs)), names,
                        f"swap the columns of joints {names[0]} and {names[1]}")


def joint_still(model, data: Measurements, result, noise=None, *, fit: _Fit | None = None) -> Finding | None:
    """A joint that never moves in the campaign: the parameters it alone would show are lost. A fact
    of the readings, no refit."""
    q = data.q
    still = [j for j in range(q.shape[1]) if np.ptp(q[:, j]) <= 1e-9 * (1.0 + np.max(np.abs(q[:, j])))]
    if not still:
        return None
    names = tuple(model.joint_names[j] for j in still)
    ident = result.identifiability
    lost = tuple(getattr(ident, "eliminated", ())) and tuple(a.name for a in ident.eliminated)
    said = f"; the parameters the data cannot separate: {', '.join(lost[:6])}" if lost else ""
    return Finding("joint still", f"joint(s) {', '.join(names)} never move in this campaign",
                   f"every reading of {', '.join(names)} is the same{said}", float(np.log10(NAMED_FACTOR)) + 0.5,
                   names, fix="move every joint over its range (robocal plan) and measure again")


# -- hypotheses: the model -----------------------------------------------------------------------------

def model_sign(model, data: Measurements, result, noise=None, *, fit: _Fit | None = None) -> Finding | None:
    """A nominal value with the wrong sign in the model file: each non-zero length or angle of the
    frames flipped in turn, the flip the nominal robot then matches best refitted."""
    fit = _fit_of(model, data, result, noise, fit)
    data = fit.data     # a change of each row alone: the poses diagnosed are enough
    lay = parameter_layout(model)
    p_nom = parameter_vector(model)
    names = [par.name for par in lay.parameters if par.family == "frames" and p_nom[par.index] != 0.0]
    if not names:
        return None

    def flipped(name):
        p = p_nom.copy()
        p[lay[name].index] *= -1.0
        return model_from_vector(model, p)

    best = names[int(np.argmin([_screen(fit, data, flipped(n)) for n in names]))]
    return _refit_found(fit, data, "model sign", f"the model's {best} has the wrong sign", "with its sign flipped",
                        np.log2(len(names)), (best,), f"correct the sign of {best} in the model file",
                        model=flipped(best))


def _robot_scaled(model: RobotModel, s: float) -> RobotModel:
    lay = parameter_layout(model)
    p = parameter_vector(model)
    for par in lay.parameters:
        if par.quantity == "length" and par.family == "frames":
            p[par.index] *= s
    return model_from_vector(model, p)


def robot_size(model, data: Measurements, result, noise=None, *, fit: _Fit | None = None) -> Finding | None:
    """The data come from a robot of another size (another robot's file): the model with every
    length of its frames scaled, by the factor the nominal robot then matches best, is refitted."""
    fit = _fit_of(model, data, result, noise, fit)
    data = fit.data     # a change of each row alone: the poses diagnosed are enough
    coarse = np.exp(np.linspace(np.log(0.5), np.log(2.0), 29))
    s = float(coarse[int(np.argmin([_screen(fit, data, _robot_scaled(model, f)) for f in coarse]))])
    fine = s * np.linspace(0.96, 1.04, 9)
    s = float(fine[int(np.argmin([_screen(fit, data, _robot_scaled(model, f)) for f in fine]))])
    if abs(s - 1.0) < 0.03:
        return None
    return _refit_found(fit, data, "robot size", f"the data come from a robot about {s:.3g} times this model's size "
                        "(another robot's file or model)", "with every length scaled", 2.0,
                        fix="check that the measurement file and the model file are of the same robot",
                        model=_robot_scaled(model, s))


def marker_frame(model, data: Measurements, result, noise=None, *, fit: _Fit | None = None) -> Finding | None:
    """A marker on another frame than the model says: the two frames the nominal robot matches best
    (the marker's coordinates kept) are refitted for each marker."""
    fit = _fit_of(model, data, result, noise, fit)
    data = fit.data     # a change of each row alone: the poses diagnosed are enough
    found = []
    for name in data.marker_names:
        k = model.marker_names.index(name)
        here = model.markers[k].frame
        others = [f for f in range(len(model.frames)) if f != here]
        moved = [model.replace(markers=tuple(replace(mk, frame=f) if i == k else mk
                                             for i, mk in enumerate(model.markers))) for f in others]
        order = np.argsort([_screen(fit, data, m) for m in moved])
        for i in order[:1]:
            frame = model.frames[others[i]].name
            found.append(_refit_found(fit, data, "marker frame", f"marker {name} is on frame {frame}, not "
                                      f"{model.frames[here].name}", "with it there", np.log2(len(others)),
                                      (name, frame), f"put marker {name} on frame {frame} in the model file",
                                      model=moved[i]))
    return max((f for f in found if f is not None), key=lambda f: f.score, default=None)


# -- hypotheses: the campaign's order --------------------------------------------------------------

def _groups(fit: _Fit) -> list[tuple]:
    """(what changes, columns of the fit's Jacobian, items) of the parameter groups a step or a
    drift may move: the base (the instrument against the robot), each marker, everything."""
    lay = parameter_layout(fit.start)
    fam = np.array([lay[n].family for n in fit.names])
    owner = np.array([lay[n].owner for n in fit.names])
    out: list[tuple] = []
    if np.any(fam == "base"):
        out.append(("the measurement frame against the robot (the instrument bumped or the robot moved)",
                    np.nonzero(fam == "base")[0], ()))
    for m in dict.fromkeys(owner[fam == "markers"]):
        out.append((f"marker {m} on the robot (the reflector moved in its nest)",
                    np.nonzero((fam == "markers") & (owner == m))[0], (str(m),)))
    out.append(("the load on the robot (a payload the data do not state)", "load", ()))
    out.append(("the robot itself (another robot, or a load the model does not know)", np.arange(len(fit.names)), ()))
    return out


def _columns(fit: _Fit, cols) -> np.ndarray:
    """The Jacobian columns of a group: of the fit's own parameters (indices), or ``"load"``."""
    return fit.load if isinstance(cols, str) else fit.J[:, cols]


def _load_columns(start: RobotModel, data: Measurements, p: np.ndarray, noise: Noise) -> np.ndarray:
    """(n_rows, n_joints) how the joints' torsional compliances bend the robot under a unit mass at
    its last frame (the robot's own masses left out), at the parameters ``p`` of ``start``."""
    bare = start.replace(frames=tuple(replace(f, mass=0.0) for f in start.frames), payload=Payload(mass=1.0),
                         other_payloads=())
    names = tuple(n for n in candidate_parameters(bare, ("compliance",)) if n.endswith(".k_theta"))
    loaded = _with(data, payload_mass=np.ones(data.n_poses))
    prob = Problem(bare, names, data=loaded, compliance=True, noise=noise)
    lay = parameter_layout(bare)
    q = parameter_vector(bare)
    for par in lay.parameters:
        if par.family != "compliance":
            q[par.index] = p[par.index]
    return np.array(prob.jacobian(q))


def _by_pose(fit: _Fit, A: np.ndarray) -> np.ndarray:
    """(n_poses, rows_per_pose, ...) the rows of ``A`` grouped by pose, zero-padded."""
    order = np.argsort(fit.row_pose, kind="stable")
    pose = fit.row_pose[order]
    first = np.searchsorted(pose, np.arange(fit.data.n_poses))
    place = np.arange(len(pose)) - first[pose]
    out = np.zeros((fit.data.n_poses, int(place.max()) + 1 if len(place) else 1) + A.shape[1:])
    out[pose, place] = A[order]
    return out


def _determined(fit: _Fit, freedom: int) -> bool:
    """Whether a hypothesis adding ``freedom`` parameters leaves at least as many residual degrees
    of freedom as it adds: one that leaves fewer fits systematic residuals of any origin (a 20-pose
    campaign's robot-wide drift) and tells no cause from a fit."""
    return len(fit.r) - len(fit.names) - freedom >= freedom


def _split_gains(fit: _Fit, Z: np.ndarray, edge: int) -> tuple[int, float]:
    """The pose (of the poses diagnosed) from which letting parameters with the Jacobian columns
    ``Z`` (n_rows, g) change reduces the sum of squares most, and the reduction (Gauss-Newton, from
    cumulative sums over the poses of the gradient and the Gram matrices)."""
    n = fit.data.n_poses
    splits = np.arange(edge, n - edge + 1)
    if not len(splits):
        return n // 2, 0.0
    Jp, Zp, rp = _by_pose(fit, fit.J), _by_pose(fit, Z), _by_pose(fit, fit.r[:, None])[..., 0]
    g_n = Z.shape[1]

    def after(x):   # the sums over the poses from each split on
        c = np.concatenate([np.zeros((1,) + x.shape[1:]), np.cumsum(x, axis=0)])
        return c[-1] - c[splits]

    g = after(np.einsum("nrg,nr->ng", Zp, rp))
    HG = after(np.einsum("nrg,nrk->ngk", Zp, Jp))
    M = after(np.einsum("nrg,nrh->ngh", Zp, Zp)) - HG @ np.linalg.pinv(fit.J.T @ fit.J, hermitian=True) \
        @ np.swapaxes(HG, 1, 2)
    ridge = (1e-10 * np.trace(M, axis1=1, axis2=2)[:, None, None] + 1e-300) * np.eye(g_n)
    sol = np.linalg.solve(M + ridge, g[..., None])[..., 0]
    gains = np.einsum("si,si->s", g, sol)
    best = int(np.argmax(gains))
    return int(splits[best]), float(max(gains[best], 0.0))


def step_change(model, data: Measurements, result, noise=None, *, fit: _Fit | None = None) -> Finding | None:
    """A step along the campaign's order: from some row on the base, a marker or the whole robot
    differs (a bumped instrument, a reseated reflector, a payload, a sister robot). Each group's best
    row from cumulative sums of the original fit's gradient and Gram matrix (one Gauss-Newton step)."""
    fit = _fit_of(model, data, result, noise, fit)
    n = fit.data.n_poses
    edge = max(3, int(EDGE_SHARE * n))
    best = None
    for what, cols, items in _groups(fit):
        Z = _columns(fit, cols)
        side = max(edge, Z.shape[1] // 3 + 2)      # each side holds more rows than the group has parameters
        if n - 2 * side < 1 or not _determined(fit, Z.shape[1]):
            continue
        row, gain = _split_gains(fit, Z, side)
        ssr = max(fit.ssr - gain, 0.0)
        score = _score(fit, ssr, len(fit.r), Z.shape[1] + np.log2(max(n, 2)))
        if best is None or _bic(ssr, len(fit.r), Z.shape[1]) < best[0]:
            best = (_bic(ssr, len(fit.r), Z.shape[1]), score, what, row, ssr, items)
    if best is None:
        return None
    _, score, what, row, ssr, items = best
    label = data.labels[int(fit.rows[row])]
    rms = fit.rms * np.sqrt(ssr / max(fit.ssr, 1e-300))
    return Finding("step change", f"from {label} on, {what} changed", f"a fit letting it change at {label} "
                   f"leaves {_mm(rms)} against {_mm(fit.rms)} RMS per axis", score, (label,) + items, fit.rms, rms,
                   f"look at what happened at {label}; calibrate the rows before and after it apart, or measure again")


def drift(model, data: Measurements, result, noise=None, *, fit: _Fit | None = None) -> Finding | None:
    """A slow drift along the campaign's order (warming up, the instrument creeping): the base, or
    the whole robot, changing in proportion to the row (one Gauss-Newton step from the original fit)."""
    fit = _fit_of(model, data, result, noise, fit)
    t = fit.rows[fit.row_pose] / max(data.n_poses - 1, 1) - 0.5
    best = None
    for what, cols, _ in _groups(fit):
        if what.startswith("marker"):
            continue
        Z = _columns(fit, cols) * t[:, None]
        if not _determined(fit, Z.shape[1]):
            continue
        gain, _coef = _projected_gain(fit, Z)
        ssr = max(fit.ssr - gain, 0.0)
        score = _score(fit, ssr, len(fit.r), Z.shape[1])
        if best is None or _bic(ssr, len(fit.r), Z.shape[1]) < best[0]:
            best = (_bic(ssr, len(fit.r), Z.shape[1]), score, what, ssr)
    if best is None:
        return None
    _, score, what, ssr = best
    rms = fit.rms * np.sqrt(ssr / max(fit.ssr, 1e-300))
    first, last = data.labels[0], data.labels[-1]
    return Finding("drift", f"{what.split(' (')[0]} drifts slowly along the campaign (warming up, the instrument "
                   "creeping)", f"a fit letting it change in proportion to the row leaves {_mm(rms)} against "
                   f"{_mm(fit.rms)} RMS per axis", score, (first, last), fit.rms, rms,
                   "let the robot and the instrument warm up, check the instrument's reference, measure again")


# -- hypotheses: orientations and noise ----------------------------------------------------------------

def rotation_convention(model, data: Measurements, result, noise=None, *, fit: _Fit | None = None
                        ) -> Finding | None:
    """Measured orientations in another convention: their inverses (transposes), or Euler angles of
    one sequence read as the same letters intrinsic for extrinsic (or the reverse)."""
    if not data.has_orientation:
        return None
    from scipy.spatial.transform import Rotation

    fit = _fit_of(model, data, result, noise, fit)
    data = fit.data     # a change of each row alone: the poses diagnosed are enough
    rot_mask = cast(np.ndarray, data.rot_mask)      # set: the data have orientations
    R = np.where(rot_mask[..., None, None], cast(np.ndarray, data.rotations), np.eye(3))
    cands = [("the measured rotations are the inverses (transposes) of the marker orientations",
              np.swapaxes(R, -1, -2))]
    flat = Rotation.from_matrix(R.reshape(-1, 3, 3))
    for seq in ("xyz", "zyx", "zyz", "XYZ", "ZYX", "ZYZ"):
        other = seq.swapcase()
        alt = Rotation.from_euler(other, flat.as_euler(seq)).as_matrix().reshape(R.shape)
        cands.append(((f"Euler angles in the sequence {seq} were read as {other} "
                      f"({'intrinsic' if other.isupper() else 'extrinsic'} for "
                      f"{'intrinsic' if seq.isupper() else 'extrinsic'})"), alt))
    found = [_refit_found(fit, _with(data, rotations=np.where(rot_mask[..., None, None], Rh, np.nan)),
                          "rotation convention", why, "in that convention", 1.0 + np.log2(len(cands)),
                          fix="declare the orientation convention of the rotation columns (--orientation)")
             for why, Rh in cands]
    return max((f for f in found if f is not None), key=lambda f: f.score, default=None)


def noise_stated(model, data: Measurements, result, noise=None, *, fit: _Fit | None = None) -> Finding | None:
    """The stated noise (the data's standard deviations, or a noise given rather than an instrument
    class's assumed) against the scatter the fit leaves: ``NOISE_FACTOR`` times more or less. No
    refit: its score is the naming bar, and it is named only when no mistake explains the scatter."""
    fit = _fit_of(model, data, result, noise, fit)
    if data.sigma is None and not fit.noise.source.startswith("stated"):
        return None     # an instrument class's noise was assumed, not stated: nothing to call wrong
    weighted = data.sigma is not None or data.has_orientation
    ratio = float(np.sqrt(fit.ssr / fit.dof)) / (1.0 if weighted else fit.noise.position)
    stated = "the stated standard deviations" if data.sigma is not None else f"the expected {_mm(fit.noise.position)}"
    if ratio >= NOISE_FACTOR:
        return Finding("noise stated", f"the stated noise is too small: the data scatter {ratio:.3g} times "
                       f"{stated} (or the robot adds scatter of its own)", f"the fit leaves {_mm(fit.rms)} RMS per "
                       f"axis, {ratio:.3g} times {stated}, and no mistake tested explains it",
                       float(np.log10(NAMED_FACTOR)), (), fit.rms, None,
                       "state the instrument's real noise (--noise-mm), or give the limit of absolute accuracy "
                       "(--limit-mm) to judge the robot's own scatter")
    if ratio <= 1.0 / NOISE_FACTOR:
        return Finding("noise stated", f"the stated noise is too large: the data scatter {ratio:.3g} times {stated}",
                       f"the fit leaves {_mm(fit.rms)} RMS per axis, {ratio:.3g} times {stated}: the checks judged "
                       "against it are too lenient", float(np.log10(NAMED_FACTOR)), (), fit.rms, None,
                       "state the instrument's real noise (--noise-mm)")
    return None


# -- the ranking -------------------------------------------------------------------------------------

def _identified(value, name, args):
    """Names (at least one) of parameters the calibration ``result`` identified."""
    names_in(lambda a: [e.name for e in a["result"].parameters], "a parameter the calibration identified")(
        value, name, args)
    if not len(value):
        raise InputError("must name at least one parameter the calibration identified (None: all)", where=name)




HYPOTHESES = (rows_shifted, pose_labels_offset, mirrored_frame, axes_swapped, markers_swapped, marker_copied,
              blunders, unit_factor, joint_scale, joint_sign, joints_swapped, joint_still, model_sign, robot_size,
              marker_frame, step_change, drift, rotation_convention)


@accepts(model=is_a(RobotModel), data=both(is_a(Measurements), measured_on()), result=is_a(CalibrationResult),
         noise=noise_of(Noise, INSTRUMENT_NOISE), parameters=optional(_identified))
@one_blas_thread
def diagnose(model: RobotModel, data: Measurements, result: CalibrationResult, *, noise=None, parameters=None
             ) -> Diagnosis:
    """Test specific explanations of a calibration's misfit against the data, and rank them.

    Parameters
    ----------
    model : RobotModel
        The nominal model the calibration started from.
    data : Measurements
        The measurements it fitted (its fitted poses, in their campaign order).
    result : CalibrationResult
        The calibration of ``model`` on ``data``.
    noise : Noise, str or None
        The expected measurement noise (a ``Noise`` or an instrument class); default a laser tracker's.
    parameters : tuple of str, optional
        The parameters refitted; default those the calibration identified.

    Returns
    -------
    Diagnosis
        The findings, most likely first (others only when close to it; none when nothing tested
        explains the misfit), the hypotheses tested and a one-line summary (docs/diagnosis.md).
    """
    if parameters is not None:
        result = replace(result, parameters=tuple(e for e in result.parameters if e.name in set(parameters)))
    fit = baseline(model, data, result, noise)
    found = [f for f in (h(model, data, result, noise, fit=fit) for h in HYPOTHESES) if f is not None]
    return ranked(found, HYPOTHESES + (noise_stated,), fit.rms, f"{_mm(fit.rms)} RMS per axis",
                  lambda: noise_stated(model, data, result, noise, fit=fit))


def ranked(found, hypotheses, rms: float, misfit: str, fallback=None) -> Diagnosis:
    """The diagnosis from the ``found`` findings of ``hypotheses`` (functions): those named (their
    factor at least ``NAMED_FACTOR``), most likely first, the others only within ``CLOSE_FACTOR`` of
    it; when none is, what ``fallback()`` finds (or nothing) and a summary saying so of the
    ``misfit`` (its words) and ``rms`` (m)."""
    named = sorted((f for f in found if f.score >= np.log10(NAMED_FACTOR)), key=lambda f: -f.score)
    if not named and fallback is not None:
        extra = fallback()
        named = [extra] if extra is not None else []
    shown = tuple(f for f in named if f.score >= named[0].score - np.log10(CLOSE_FACTOR)) if named else ()
    tested = tuple(h.__name__.replace("_", " ") for h in hypotheses)
    if shown:
        summary = f"most likely: {shown[0].cause} ({shown[0].evidence})"
    else:
        summary = (f"nothing tested explains the misfit ({misfit}): none of the "
                   f"{len(tested)} explanations tested reduces it by a factor of {NAMED_FACTOR:g}")
    return Diagnosis(findings=shown, tested=tested, summary=summary, rms=rms)
