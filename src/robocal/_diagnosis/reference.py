"""What the diagnosis of measured points compares against, and how a repair is judged
(docs/diagnosis.md, "How a cause is named").

The **reference** is the calibration itself on the poses diagnosed: its residuals and Jacobian at
its solution, no solve. A hypothesis proposes **candidates**, each a repair of the data (or of the
model) with the factor by which cheap statistics predict it divides the residual variance; only
those predicted to divide it by ``SURVIVE_FACTOR`` or more are refitted. A refit is **judged** by
three figures: the factor by which it divides the residual variance (its own freedom counted), the
cross-validated error of the points before and after the repair (paired, in standard errors), and
whether what it leaves is at the expected noise or scatters on held-out poses as on fitted ones
(the robot's own scatter, as the fit check judges it).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import cast

import numpy as np

from .._base.arrays import mean_and_error, read_only
from .._base.errors import DegenerateDataError, InputError
from .._base.options import DEFAULT_INSTRUMENT
from .._identification.checks import (
    FIT_RATIO,
    OVERFIT_RATIO,
    REFIT_GAIN_SIGMAS,
    WORSE_SIGMAS,
    expected_noise,
    tolerances,
)
from .._identification.holdout import FOLD_RCOND, cross_validate, holdout_of
from .._identification.points import Points
from .._identification.problem import Problem
from .._identification.registration import rigid_base
from .._identification.result import CalibrationResult, Finding
from .._identification.solve import solve
from .._identification.steps import without_copies
from .._model.kinematics import evaluate
from .._model.measurements import Measurements, Noise
from .._model.parameters import needs_compliance, parameter_layout, parameter_vector
from .._model.robot import RobotModel

# a hypothesis is named when its repair divides the residual variance by at least this factor
NAMED_FACTOR = 4.0
# others are shown beside the most likely one when their factor is within this factor of its own
CLOSE_FACTOR = 4.0
# a candidate is refitted when the cheap statistics predict it divides the residual variance by at
# least this factor; the others are ruled out without a refit
SURVIVE_FACTOR = 2.0
# ... or, for a cause no robot has of its own (``Candidate.beyond_robot``), at least this factor: the
# screen's one step falls short of the refit for a large change (the WAM's j2 turning 1.02 times its
# reading: 1.91 predicted, 2.3 refitted), and such a cause is possible from SURVIVE_FACTOR refitted
BEYOND_SURVIVE_FACTOR = 1.5
# the Gram matrix of the calibration's unit-scaled columns is taken from the solver's R factor when
# its smallest eigenvalue is above this share of its largest (every direction determined to many
# digits: the same projections to rounding); else from the columns, its pseudo-inverse cutting what
# they leave undetermined
GRAM_RCOND = 1e-6
# ... and columns projected out of their span from one product with them when each keeps more than
# this share of its square norm out of it (far from cancelling)
SPAN_SHARE = 1e-2
# a repair whose cross-validated error is this many times below the calibration's decides though it
# leaves more than the instrument or the robot's own scatter explains (a lag along a fast path: 39 mm
# in use, 0.7 mm once the readings are moved by the lag found, which leaves 0.193 mm against 0.02 mm)
DOMINANT_FACTOR = 10.0
# at most this many candidates are refitted, the best predicted first
MAX_REFITS = 6
# diagnose at most this many poses, spread evenly along the campaign
MAX_POSES = 1000
# a repair is refitted on at most this many poses, spread evenly
REFIT_POSES = 500
# the cheap rigid matches look at most at this many poses
SCREEN_POSES = 200
# the solver's budget per refit
MAX_NFEV = 15
# payloads heavier than this many times the robot's moving links (the model's masses) are implausible
HEAVY_PAYLOAD = 10.0
# the repair of a mistake a calibration can take up exactly, that makes its implausible changes
# plausible, names its cause when it fits at least this share as well (a sign the model absorbs with
# a mirrored joint, a unit a scaled robot absorbs, fit as well: only the changes tell)
PLAUSIBLE_FIT = 0.5
# ... and when its cross-validated error is no worse than by this share (or two standard errors)
PLAUSIBLE_FIT_SHARE = 0.05
# a cross-validated error that moves by less than this share of itself is said unchanged: rounding
# in two fits of the same minimum, far below anything three significant digits can show
UNCHANGED_SHARE = 1e-6


@dataclass(frozen=True, eq=False)
class Reference:
    """The calibration on the poses diagnosed (at most ``MAX_POSES``, spread evenly; points it set
    aside masked): what every hypothesis compares against.

    ``start`` the calibrated model, ``names`` its identified parameters, ``p`` its values, ``r``
    and ``J`` the residuals and Jacobian there (the problem's rows), ``Q`` an orthonormal basis of
    ``J``'s columns, ``ssr`` the sum of squares left once the linearised fit has settled (a robust
    loss's solution is not the linear one), ``rms`` the position residual RMS per axis (m),
    ``errors`` (n_poses, n_markers, 3) the position residuals (calibrated minus measured, m; 0 where
    not measured), ``expected`` the per-axis scatter a good fit leaves (m), ``rows`` the poses'
    rows in the campaign, ``folds`` the calibration's number of folds, ``factor`` the solver's R
    factor of ``J`` when it kept one (``R^T R = J^T J``), ``at`` the vector ``J`` was taken at (the
    solver's last Jacobian, within its tolerances of ``p``; None: at ``p``), where other columns
    are taken too (its evaluation is kept)."""

    model: RobotModel
    start: RobotModel
    names: tuple[str, ...]
    data: Measurements
    campaign: Measurements
    rows: np.ndarray
    noise: Noise
    expected: float
    problem: Problem
    p: np.ndarray
    r: np.ndarray
    J: np.ndarray
    ssr: float
    rms: float
    errors: np.ndarray
    result: CalibrationResult
    folds: int
    _cache: dict
    factor: np.ndarray | None = None
    at: np.ndarray | None = None

    @property
    def dof(self) -> int:
        return max(len(self.r) - len(self.names), 1)

    @property
    def refit_names(self) -> tuple[str, ...]:
        """The parameters a repair frees: those the calibration identified, and of those it held back as
        weakly identifiable (at the scatter a mistake leaves, it holds back what repaired data pin
        down) the ones independent of them at these poses."""
        def make():
            weak = [a.name for a in self.result.identifiability.eliminated if a.reason.startswith("is weakly")]
            names = tuple(self.names) + tuple(n for n in weak if n not in self.names)
            return independent(self.columns(names), names)

        return self.cached("refit_names", make)

    @property
    def implausible(self) -> int:
        """The calibration's changes beyond their tolerances (and payloads beyond a robot's), on the poses
        diagnosed."""
        return self.cached("implausible", lambda: count_implausible(self.model, self.nominal_vector, self.p,
                                                                    self.names, self.data))

    @property
    def nominal_vector(self) -> np.ndarray:
        """The nominal model's parameter vector (read-only)."""
        return self.cached("nominal_vector", lambda: read_only(parameter_vector(self.model)))

    @property
    def shows(self) -> bool:
        """Whether the calibration shows a mistake at all: it misfits beyond ``FIT_RATIO`` times the
        expected scatter, or it made changes beyond their tolerances. One that fits with plausible
        changes holds no gross mistake and no change of the whole robot along the campaign."""
        return self.rms > FIT_RATIO * self.expected or self.implausible > 0

    @property
    def base_free(self) -> bool:
        lay = parameter_layout(self.model)
        return any(lay[n].family == "base" for n in self.names)

    def columns(self, names: tuple[str, ...]) -> np.ndarray:
        """(n_rows, len(names)) the Jacobian's columns of the parameters ``names`` where ``J`` was taken."""
        return np.array(self.problem.over(names).jacobian(self.p if self.at is None else self.at))

    def cached(self, key: str, make: Callable):
        """``make()`` computed once per reference."""
        if key not in self._cache:
            self._cache[key] = make()
        return self._cache[key]

    @property
    def positions0(self) -> np.ndarray:
        """(n_poses, n_markers, 3) the nominal robot's marker positions (its base as the model says:
        a rigid match does not depend on it)."""
        return self.cached("positions0", lambda: nominal_positions(self.model, self.data))

    @property
    def settled(self) -> np.ndarray:
        """The residual rows once the linearised fit has settled (``r`` less its part in ``J``'s span)."""
        return self.cached("settled", lambda: self.project(self.r))

    def project(self, Z: np.ndarray) -> np.ndarray:
        """``Z`` (n_rows, ...) less its part in the span of the calibration's columns ``J``."""
        Js, inverse, _ = self.projector
        if Js is None:
            return Z - self.J @ (self.gram_inverse @ (self.J.T @ Z))
        return Z - Js @ (inverse @ (Js.T @ Z))

    @property
    def projector(self) -> tuple[np.ndarray | None, np.ndarray, np.ndarray]:
        """``J`` with unit columns, the pseudo-inverse of its Gram matrix, and the column norms. Where
        the solver's R factor gives a well conditioned Gram matrix (``GRAM_RCOND``: its inverse holds
        every direction, the same to rounding), the inverse is taken from it and ``J`` is not scaled
        (None in its place)."""
        def make():
            if self.factor is not None:
                col = np.sqrt(np.einsum("ij,ij->j", self.factor, self.factor))
                if np.all(col > 0):
                    Rs = self.factor / col
                    w, V = np.linalg.eigh(Rs.T @ Rs)
                    if w[0] > GRAM_RCOND * w[-1]:
                        return None, (V / w) @ V.T, col
            col = np.linalg.norm(self.J, axis=0)
            col[col == 0] = 1.0
            Js = self.J / col
            return Js, np.linalg.pinv(Js.T @ Js, hermitian=True), col

        return self.cached("projector", make)

    @property
    def gram_inverse(self) -> np.ndarray:
        """The pseudo-inverse of ``J^T J`` (taken in unit-column scaling)."""
        def make():
            _, inverse, col = self.projector
            return inverse / np.outer(col, col)

        return self.cached("gram_inverse", make)

    @property
    def held_out(self) -> np.ndarray:
        """(n_campaign_poses,) each pose's cross-validated error (RMS over its markers, m) under the
        calibration; NaN for a pose not diagnosed."""
        def make():
            out = np.full(self.campaign.n_poses, np.nan)
            out[self.rows] = pose_errors(self.problem, self.p, self.folds)[1]
            return out

        return self.cached("held_out", make)


def independent(J: np.ndarray, names: tuple[str, ...], tol: float = 1e-8) -> tuple[str, ...]:
    """Of ``names``, in order, those whose (unit-scaled) columns of ``J`` are independent of the
    ones kept before them."""
    col = np.linalg.norm(J, axis=0)
    kept: list[int] = []
    basis = np.zeros((J.shape[0], 0))
    for k in range(J.shape[1]):
        if col[k] == 0:
            continue
        v = J[:, k] / col[k]
        v = v - basis @ (basis.T @ v)
        norm = float(np.linalg.norm(v))
        if norm > np.sqrt(tol):
            kept.append(k)
            basis = np.hstack([basis, (v / norm)[:, None]])
    return tuple(names[k] for k in kept)


def as_noise(noise) -> Noise:
    """A ``Noise`` from a ``Noise``, an instrument class name or None (the default instrument's)."""
    return noise if isinstance(noise, Noise) else Noise.of(noise or DEFAULT_INSTRUMENT)


def working_rows(n: int, most: int = MAX_POSES) -> np.ndarray:
    """At most ``most`` row indices spread evenly over ``n`` rows.

    >>> working_rows(5, 3).tolist()
    [0, 2, 4]
    """
    return np.arange(n) if n <= most else np.unique(np.linspace(0, n - 1, most).round().astype(int))


def fitted_campaign(data: Measurements, result: CalibrationResult) -> Measurements:
    """The measurements as the calibration fitted them: exact copies of a row counted once, the points
    it set aside masked (``PoseSet.set_aside``)."""
    data, _ = without_copies(data)
    aside = result.fit.set_aside
    if aside is not None and aside.shape == data.mask.shape and aside.any():
        data = data.without(aside)
    return data.with_approach()


def reference(model: RobotModel, data: Measurements, result: CalibrationResult, noise=None,
              limit_m: float | None = None, folds: int = 5, fitted=None) -> Reference:
    """The reference of a calibration ``result`` of ``model`` on ``data``: no solve, one evaluation of
    the residuals and the Jacobian at its solution on the poses diagnosed. ``fitted``: the
    calibration's own fit (``steps.Fit``), whose residuals and Jacobian are taken instead when it
    fitted exactly the poses diagnosed."""
    campaign = fitted_campaign(data, result)
    rows = working_rows(campaign.n_poses)
    work = campaign if len(rows) == campaign.n_poses else campaign.subset(rows)
    names = tuple(result.parameter_names)
    start = result.calibrated_model
    fit_noise = as_noise(noise)
    compliance = needs_compliance(start, names)
    shared = _solved(fitted, work, names, compliance)
    factor = at = None
    if shared is None:
        prob = Problem(start, names, data=work, compliance=compliance, noise=fit_noise)
        p = parameter_vector(start)
        r, J = prob.residuals(p), np.array(prob.jacobian(p))
    else:
        prob, p, r, J, factor, at = shared
    pts = cast(Points, prob.points)
    e = np.where(work.mask[..., None], pts.errors(p), 0.0)
    rms = float(np.sqrt(np.mean(e[work.mask] ** 2))) if work.mask.any() else 0.0
    ref = Reference(model=model, start=start, names=names, data=work, campaign=campaign, rows=rows, noise=fit_noise,
                    expected=expected_noise(fit_noise, limit_m)[0], problem=prob, p=p, r=r, J=J, ssr=0.0, rms=rms,
                    errors=e, result=result, folds=folds, _cache={}, factor=factor, at=at)
    object.__setattr__(ref, "ssr", float(ref.settled @ ref.settled))
    return ref


def _solved(fitted, work: Measurements, names: tuple[str, ...], compliance: bool):
    """(problem, p, residuals, Jacobian, R factor, the vector the Jacobian was taken at) of the
    calibration's fit when it fitted measured points alone on exactly the poses diagnosed (none set
    aside), over ``names``, without lost motion; else None. Its Jacobian is the solver's last (within
    its tolerances of the solution); its R factor the solver's of it (None where the solver kept the
    Jacobian itself: a robust loss, rows of two kinds)."""
    if fitted is None:
        return None
    prob, sol = fitted.problem, fitted.solution
    pts = prob.points
    if (pts is None or prob.contacts is not None or pts.backlash or pts.compliance != compliance
            or tuple(prob.free_names) != names or prob.point_mask.shape != work.mask.shape
            or not np.array_equal(prob.point_mask, work.mask) or not np.array_equal(pts.data.mask, work.mask)
            or not np.array_equal(pts.data.q, work.q)):
        return None
    J = prob.jacobian(sol.p if sol.jacobian_at is None else sol.jacobian_at)
    R = sol.jacobian
    kept = sol.loss == "linear" and sol.row_kinds is None and R.shape == (len(names), len(names))
    return prob, sol.p, sol.residuals, np.array(J), R if kept else None, sol.jacobian_at


def nominal_positions(model: RobotModel, data: Measurements) -> np.ndarray:
    """(n_poses, n_data_markers, 3) ``model``'s marker positions at ``data``'s readings."""
    ev = evaluate(model, data.q, payload_mass=data.payload_mass)
    return ev.positions[:, [model.marker_names.index(n) for n in data.marker_names]]


def pose_errors(problem: Problem, p: np.ndarray, folds: int) -> tuple[np.ndarray, np.ndarray]:
    """(fitted, cross-validated): each pose's error (RMS over its measured markers, m) under ``p``,
    and under the fits on the other folds (NaN for a pose no fold holds out)."""
    pts = cast(Points, problem.points)
    mask = pts.data.mask
    fitted = np.where(mask, pts.error_norms(p[:problem.n_robot]), np.nan)
    held = cross_validate(problem, p, holdout_of(problem, folds)).norms
    held = np.where(mask, held, np.nan)

    def per_pose(norms):
        n = mask.sum(axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(n > 0, np.sqrt(np.nansum(norms ** 2, axis=1) / np.maximum(n, 1)), np.nan)

    return per_pose(fitted), per_pose(held)


def count_implausible(model: RobotModel, start: np.ndarray, p: np.ndarray, names, data: Measurements | None = None
                      ) -> int:
    """How many of ``names`` moved from ``start`` beyond their family's tolerance (compliances aside),
    and one more for payloads of ``data`` heavier than ``HEAVY_PAYLOAD`` times the robot's links."""
    lay = parameter_layout(model)
    tol = tolerances(model)
    n = 0
    for name in names:
        par = lay[name]
        bound = tol.get((par.family, par.quantity))
        if bound is not None and par.quantity != "compliance" and abs(p[par.index] - start[par.index]) > bound:
            n += 1
    return n + int(data is not None and heavy_payload(model, data))


def heavy_payload(model: RobotModel, data: Measurements) -> bool:
    """Whether ``data``'s payloads are heavier than ``HEAVY_PAYLOAD`` times the mass of ``model``'s moving
    links (never when the model states no link masses)."""
    links = sum(f.mass for f in model.frames)
    masses = data.payload_mass
    return bool(links > 0 and masses is not None and masses.size and np.max(masses) > HEAVY_PAYLOAD * links)


# -- candidates and their repairs -------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class Repair:
    """Data (and model) with one cause repaired, to refit: ``registered`` starts from ``model`` (the
    nominal, by default) with its base registered on the repaired data, else from the calibration;
    ``scale`` takes the repaired positions' unit back to the data's; ``pose_rows`` (n_poses,) the
    campaign's row whose measured point each repaired pose holds (None: the poses diagnosed,
    ``Reference.rows``); ``names`` the parameters refitted (None: the calibration's); ``nominal`` the
    model whose values the refit's changes are judged plausible against (None: ``model`` when it
    repairs the nominal one, else the nominal)."""

    data: Measurements
    model: RobotModel | None = None
    registered: bool = True
    scale: float = 1.0
    pose_rows: np.ndarray | None = None
    names: tuple[str, ...] | None = None
    nominal: RobotModel | None = None


@dataclass(frozen=True, eq=False)
class Candidate:
    """One repair a hypothesis proposes: the finding's words, the factor the cheap statistics predict
    (``predicted``), the freedom the repair takes (parameters of its own, counted against it) and
    how to make it (``repair``, called only when it survives the screen: a ``Repair`` to refit, or
    ``Linear`` columns to step). A ``generic`` candidate (the whole robot changing) explains any
    systematic misfit a little: it ranks after a specific one within ``CLOSE_FACTOR`` of it. A
    ``model_file`` candidate repairs the nominal model: when the calibration took its mistake up, it
    warns (the calibrated model holds what the data say). An ``absorbed`` one is a mistake a calibration
    can take up exactly with implausible changes (a sign, a unit, a mirror): its repair may fit only as
    well, and make them plausible. A ``carried`` one may be the robot's own (its lost motion, a gear's
    scale, its growth as it warms up), which never fails a calibration: the calibration stands on its
    accuracy in use (``finding``); one ``beyond_robot`` is no robot's own (``judged``)."""

    hypothesis: str
    cause: str
    how: str
    fix: str
    items: tuple[str, ...]
    predicted: float
    freedom: float
    repair: Callable[[], Repair | Linear | None]
    generic: bool = False
    model_file: bool = False
    absorbed: bool = False
    carried: bool = False
    beyond_robot: bool = False
    restated: Callable[[Outcome], str] | None = None     # the cause in the refit's figures


@dataclass(frozen=True, eq=False)
class Outcome:
    """A refit: its weighted sum of squares over ``n_rows`` rows and ``n_free`` free parameters, its
    position RMS per axis (m, in the data's unit), the implausible changes it makes, each pose's
    fitted and cross-validated errors (m, data's unit), the campaign's row each one's point is, and
    the model refitted with its solution ``p``."""

    ssr: float
    n_rows: int
    n_free: int
    rms: float
    implausible: int
    fitted: np.ndarray
    held: np.ndarray
    pose_rows: np.ndarray
    model: RobotModel
    p: np.ndarray


_SOLVE_ERRORS = (DegenerateDataError, InputError, np.linalg.LinAlgError, ValueError)


def refit(ref: Reference, repair: Repair) -> Outcome | None:
    """The fit of the repaired data (at most ``REFIT_POSES`` of its poses) and its cross-validation;
    None when it cannot be fitted."""
    rows = working_rows(repair.data.n_poses, REFIT_POSES)
    work = repair.data if len(rows) == repair.data.n_poses else repair.data.subset(rows)
    names = ref.refit_names if repair.names is None else repair.names
    m = repair.model if repair.model is not None else (ref.model if repair.registered else ref.start)
    try:
        if repair.registered and ref.base_free:
            m = rigid_base(m, work)
        prob = Problem(m, names, data=work, compliance=needs_compliance(m, names), noise=ref.noise)
        p0 = parameter_vector(m)
        sol = solve(prob, p0, max_nfev=MAX_NFEV)
        ssr = float(sol.residuals @ sol.residuals)
        if not np.isfinite(ssr):
            return None
        fitted, held = pose_errors(prob, sol.p, ref.folds)
    except _SOLVE_ERRORS:
        return None
    pts = cast(Points, prob.points)
    e = pts.errors(sol.p)[work.mask]
    rms = float(np.sqrt(np.mean(e ** 2))) * repair.scale if e.size else 0.0
    nominal = repair.nominal or (repair.model if repair.registered and repair.model is not None else ref.model)
    start = p0 if nominal is repair.model else parameter_vector(nominal)
    whole = ref.rows if repair.pose_rows is None else np.asarray(repair.pose_rows)
    return Outcome(ssr=ssr * repair.scale ** 2, n_rows=len(sol.residuals), n_free=len(prob.free_idx), rms=rms,
                   implausible=count_implausible(m, start, sol.p, names, work), fitted=fitted * repair.scale,
                   held=held * repair.scale, pose_rows=whole[rows], model=m, p=sol.p)


def factor(ref: Reference, ssr: float, n_rows: int, n_free: int, freedom: float) -> float:
    """The factor by which a refit (``ssr`` over ``n_rows`` rows, ``n_free`` free parameters and
    ``freedom`` of its own) divides the reference's residual variance."""
    after = max(ssr, 1e-300) / max(n_rows - n_free - freedom, 1.0)
    return float(max(ref.ssr, 1e-300) / ref.dof / after)


@dataclass(frozen=True)
class Judgement:
    """A repair judged: ``factor`` (residual variance divided by), the cross-validated error's fall
    (m, per pose) and its standard error, whether what is left is explained (at the expected noise,
    or scattering on held-out poses as on fitted ones), and the status it earns ("fail": decisive,
    "warn": possible, "": not named); ``before``: the calibration's cross-validated error (m, per
    pose) on the poses the fall is taken over."""

    factor: float
    gain: float
    se: float
    explained: bool
    status: str
    plausible: bool = False
    before: float = float("nan")


def judge(ref: Reference, out: Outcome, freedom: float, absorbed: bool = False, beyond_robot: bool = False
          ) -> Judgement:
    """The naming rule (docs/diagnosis.md): decisive when the repair divides the residual variance by
    ``NAMED_FACTOR``, lowers the cross-validated error by ``REFIT_GAIN_SIGMAS`` standard errors and
    leaves what the instrument (or the robot's own scatter) explains; possible when it divides the
    variance as much and lowers the cross-validated error by ``WORSE_SIGMAS`` standard errors. The
    repair of a mistake a calibration can take up exactly (``absorbed``) that fits ``PLAUSIBLE_FIT`` as
    well, no worse in use (within ``PLAUSIBLE_FIT_SHARE``), and makes at least half the calibration's
    implausible changes plausible is decisive too: the calibration took the mistake up with a robot no
    one built."""
    f = factor(ref, out.ssr, out.n_rows, out.n_free, freedom)
    verdict = judged(ref, f, ref.held_out[out.pose_rows], out.held, out.rms, out.fitted, beyond_robot)
    worse = max(WORSE_SIGMAS * verdict.se, PLAUSIBLE_FIT_SHARE * float(np.nanmean(ref.held_out[out.pose_rows])))
    plausible = ref.implausible and out.implausible <= ref.implausible // 2
    if absorbed and not verdict.status and plausible and f >= PLAUSIBLE_FIT and verdict.gain >= -worse:
        return replace(verdict, status="fail", plausible=True)
    return verdict


def judged(ref: Reference, f: float, base: np.ndarray, held: np.ndarray, rms: float, fitted: np.ndarray,
           beyond_robot: bool = False) -> Judgement:
    """The judgement of a repair dividing the residual variance by ``f``, whose cross-validated error
    per pose is ``held`` against the calibration's ``base`` (m; NaN where a pose is not compared),
    leaving ``rms`` (m per axis) and the errors ``fitted`` (m, per pose) on fitted poses; of a cause
    no robot has of its own when ``beyond_robot``."""
    d = base - held
    compared = np.isfinite(d)
    d = d[compared]
    gain, se = mean_and_error(d)
    before = float(base[compared].mean()) if d.size else float("nan")
    explained = bool(rms <= FIT_RATIO * ref.expected or np.nanmean(held) <= OVERFIT_RATIO * np.nanmean(fitted))
    # what the repair leaves unexplained is a small part of the calibration's error in use
    dominant = bool(d.size and before - gain <= before / DOMINANT_FACTOR)
    status = ""
    if f >= NAMED_FACTOR and gain > 0:
        if gain >= REFIT_GAIN_SIGMAS * se and (explained or dominant):
            status = "fail"
        elif gain >= WORSE_SIGMAS * se:
            status = "warn"
    # a cause no robot has of its own (a scale that large, a marker moved) is possible from
    # SURVIVE_FACTOR on when the repair lowers the cross-validated error by REFIT_GAIN_SIGMAS standard
    # errors and leaves what is explained: a robot's own scatter can keep a mistake below NAMED_FACTOR
    # (a gear ratio 1 % off on the WAM, whose 1.3 mm RMS the scale only halves)
    if beyond_robot and not status and f >= SURVIVE_FACTOR and explained and gain >= REFIT_GAIN_SIGMAS * se:
        status = "warn"
    return Judgement(f, gain, se, explained, status, before=before)


# -- repairs that are columns: one Gauss-Newton step from the calibration ---------------------------

@dataclass(frozen=True, eq=False)
class Linear:
    """A repair that adds parameters to the fit, as columns ``Z`` (n_rows, k) of the reference's
    rows: judged by one Gauss-Newton step from the calibration, fitted and cross-validated alike."""

    Z: np.ndarray


def row_layout(ref: Reference) -> tuple[np.ndarray, np.ndarray]:
    """(n_rows,) each row's pose (of the poses diagnosed), and its metres per row unit (NaN for a
    rotation row)."""
    def make():
        pts = cast(Points, ref.problem.points)
        poses, _ = pts.row_points()
        per = np.concatenate([np.repeat(1.0 / np.asarray(w, dtype=float) * np.ones(len(s)), 3)
                              for s, w in zip(pts.sel, pts.w)]) if pts.sel else np.zeros(0)
        metres = np.full(len(poses), np.nan)
        metres[:len(per)] = per
        return poses, metres

    return ref.cached("row_layout", make)


def _per_pose(ref: Reference, rows: np.ndarray) -> np.ndarray:
    """(n_poses,) each pose's position error (RMS over its markers, m) from residual ``rows``."""
    poses, metres = row_layout(ref)
    pos = np.isfinite(metres)
    sq = np.bincount(poses[pos], (rows[pos] * metres[pos]) ** 2, minlength=ref.data.n_poses)
    n = ref.data.mask.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 0, np.sqrt(sq / np.maximum(n, 1)), np.nan)


def _linear_fit(ref: Reference, J: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The residual rows after one Gauss-Newton step over the columns ``J`` from the calibration, and
    the held-out rows of each fold's step (the folds of the calibration's cross-validation)."""
    labels = ref.cached("row_folds", lambda: cast(np.ndarray, holdout_of(ref.problem, ref.folds).pose_labels)
                        [row_layout(ref)[0]])
    col = np.linalg.norm(J, axis=0)
    col[col == 0] = 1.0
    Js = J / col
    A, b = Js.T @ Js, Js.T @ ref.r

    def step(M, v):
        w, V = np.linalg.eigh(0.5 * (M + M.T))
        keep = w > FOLD_RCOND * max(float(w.max()), 0.0)
        return -V[:, keep] @ ((V[:, keep].T @ v) / w[keep])

    fitted = ref.r + Js @ step(A, b)
    held = np.full(len(ref.r), np.nan)
    for g in np.unique(labels[labels >= 0]):
        rows = labels == g
        Jg = Js[rows]
        held[rows] = ref.r[rows] + Jg @ step(A - Jg.T @ Jg, b - Jg.T @ ref.r[rows])
    return fitted, held


def projected_gain(ref: Reference, Z: np.ndarray) -> float:
    """How much columns ``Z`` (n_rows, k) joining the fit lower the reference's sum of squares (one
    Gauss-Newton step from the calibration)."""
    M, b = projected_products(ref, Z)
    return float(max(b @ np.linalg.pinv(M, hermitian=True) @ b, 0.0))


def projected_products(ref: Reference, Z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``Zp^T Zp`` and ``Zp^T settled``, ``Zp`` the columns ``Z`` (n_rows, k) less their part in ``J``'s
    span (``Reference.project``). Where the projector comes from the solver's factor and every column
    keeps more than ``SPAN_SHARE`` of its square norm out of that span, from ``A = J^T Z`` alone (one
    product over the rows, not two): ``Z^T Z - A^T G^+ A``, and ``Z^T settled`` (``settled`` is
    orthogonal to ``J``); else from ``Zp``."""
    if ref.projector[0] is None:
        A, ZZ = ref.J.T @ Z, Z.T @ Z
        M = ZZ - A.T @ ref.gram_inverse @ A
        if np.all(np.diag(M) > SPAN_SHARE * np.diag(ZZ)):
            return M, Z.T @ ref.settled
    Zp = ref.project(Z)
    return Zp.T @ Zp, Zp.T @ ref.settled


def linear_judgement(ref: Reference, Z: np.ndarray, freedom: float, beyond_robot: bool = False
                     ) -> tuple[Judgement, float]:
    """The judgement of columns ``Z`` joining the fit (one Gauss-Newton step, and the same step on each
    fold's complement), and the position RMS per axis they leave (m)."""
    base_fit, base_held = ref.cached("linear_reference", lambda: _linear_fit(ref, ref.J))
    fitted, held = _linear_fit(ref, np.hstack([ref.J, Z]))
    f = factor(ref, float(fitted @ fitted), len(ref.r), len(ref.names), freedom + Z.shape[1])
    base, after = np.full(ref.campaign.n_poses, np.nan), np.full(ref.campaign.n_poses, np.nan)
    base[ref.rows], after[ref.rows] = _per_pose(ref, base_held), _per_pose(ref, held)
    _, metres = row_layout(ref)
    pos = np.isfinite(metres)
    rms = float(np.sqrt(np.mean((fitted[pos] * metres[pos]) ** 2))) if pos.any() else 0.0
    return judged(ref, f, base, after, rms, _per_pose(ref, fitted), beyond_robot), rms


def mm(v: float) -> str:
    return f"{v * 1e3:.3g} mm"


def held_out_change(verdict: Judgement, before: float) -> str:
    """The cross-validated error's change as text; a change below ``UNCHANGED_SHARE`` of the error
    is rounding in the fits, not a measurement (its standard errors say nothing either)."""
    if abs(verdict.gain) <= UNCHANGED_SHARE * before:
        return f"the cross-validated error is unchanged, {mm(before)} per pose"
    fell = "falls" if verdict.gain > 0 else "rises"
    return (f"the cross-validated error {fell} by {mm(abs(verdict.gain))} per pose from {mm(before)} "
            f"({abs(verdict.gain) / max(verdict.se, 1e-300):.3g} standard errors)")


def finding(ref: Reference, cand: Candidate, rms: float, verdict: Judgement, how: str, scale: float = 1.0
            ) -> Finding:
    """The finding of a candidate whose repair earned a status: the evidence is what the repair leaves
    (``rms``, m per axis, in the data's declared unit; ``scale`` takes the repair's unit to it) and the
    cross-validated error, against the calibration's."""
    before = verdict.before if np.isfinite(verdict.before) else float(np.nanmean(ref.held_out))
    # a unit repaired: what the repair leaves in its own unit first, then as the file declared it
    own = "" if scale == 1.0 else f"{mm(rms / scale)} RMS per axis in it, "
    figures = (f"{own}{mm(rms)} {'as declared ' if own else ''}against {mm(ref.rms)} RMS per axis (the residual "
               f"variance divided by {verdict.factor:.3g}); {held_out_change(verdict, before)}")
    if verdict.plausible:   # what decides comes first: the figures beside it are no better, no worse
        evidence = (f"{how}: it fits as well, and of the calibration's {ref.implausible} implausible change(s) at most "
                    f"half remain ({figures})")
    else:
        evidence = f"{how}: {figures}"
        if not verdict.explained:
            evidence += "; what is left is more than the instrument or the robot's own scatter explains"
            if verdict.status == "fail":
                evidence += f", and at most 1/{DOMINANT_FACTOR:g} of the calibration's error in use"
    score = float(np.log10(verdict.factor)) - (float(np.log10(CLOSE_FACTOR)) if cand.generic else 0.0)
    # the calibration took up a mistake of the model file: its model holds what the data say
    status = "warn" if verdict.plausible and cand.model_file else verdict.status
    if cand.carried and status == "fail":     # the robot's own, not a mistake in its data
        status = "warn"
        evidence += ("; the robot's own effect, not a mistake in the data: the calibration stands on its accuracy in "
                     "use, and the fix does better")
    return Finding(cand.hypothesis, cand.cause, evidence, score, cand.items, ref.rms, rms, cand.fix, status)


def refitted(ref: Reference, cand: Candidate) -> Finding | None:
    """The candidate's repair refitted (or, for columns, stepped) and judged: its finding, or None when
    it earns no status."""
    repair = cand.repair()
    if repair is None:
        return None
    if isinstance(repair, Linear):
        verdict, rms = linear_judgement(ref, repair.Z, cand.freedom, cand.beyond_robot)
        if not verdict.status:
            return None
        return finding(ref, cand, rms, verdict, "a fit letting it change")
    out = refit(ref, repair)
    if out is None:
        return None
    verdict = judge(ref, out, cand.freedom, cand.absorbed, cand.beyond_robot)
    if not verdict.status:
        return None
    if cand.restated is not None:
        cand = replace(cand, cause=cand.restated(out))
    return finding(ref, cand, out.rms, verdict, f"refitted {cand.how}", repair.scale)


def with_arrays(data: Measurements, **changes) -> Measurements:
    """``data`` with some arrays replaced (the approach directions of its own order kept)."""
    return replace(data.with_approach(), **changes)
