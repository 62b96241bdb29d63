"""Identification: least squares on the identifiable parameters, with uncertainty and statistics.

``calibrate`` is a short sequence of named steps: check the inputs, register the base (if asked),
analyse identifiability at the data, solve, take the covariance, run the checks on the result,
compute the error statistics, record the provenance.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field, replace
from datetime import datetime, timezone

import numpy as np
from scipy.spatial.transform import Rotation

from ._checks import (FIT_RATIO, OUTLIER_SHARE_MAX, ROBOT_RESIDUAL_MAX, Check, backlash_sign_check,
                      cloud_size_check, compliance_sign_check, convergence_check, correlation_check, expected_noise,
                      fit_check, identifiability_check, markers_check, outlier_check, plausibility_check,
                      reading_units_check, readings_check, support_check, tolerances, verdict)
from ._errors import (CheckWarning, ConvergenceWarning, DegenerateDataError, IdentifiabilityWarning, InputError,
                      MisfitWarning, check_choice)
from ._identifiability import (DEFAULT_TOL, IdentifiabilityResult, analyse, backlash_reasons,
                               theoretical_identifiability, weakly_identifiable)
from ._identifiability import eliminate as eliminate_parameters
from ._kinematics import evaluate
from ._measurements import Measurements, Noise
from ._options import DEFAULT_INSTRUMENT, INITIAL_BASES, LOSSES, OUTLIER_ACTIONS, WEAK_ACTIONS
from ._misfit import characteristic_length, misfit_notes
from ._model import RobotModel
from ._parameters import (candidate_parameters, matched_by_pattern, model_from_vector, parameter_layout,
                          parameter_vector)
from ._problem import Problem, needs_compliance
from ._solve import Covariance, Solution, covariance, solve
from ._threads import one_blas_thread
from ._version import __version__

# the limit is a mean-error bar; within this factor of it counts as reaching it
LIMIT_REACHED_WITHIN = 1.15
# The fit of base and markers behind the errors before calibration stops at this tolerance, its
# last step taken: its errors are those of the fit run to 1e-12 within a few 1e-10 m (they are
# shown in micrometres), and it takes one Jacobian and one pass fewer.
REGISTRATION_TOL = 1e-6


@dataclass(frozen=True)
class ErrorStats:
    """Mean, standard deviation, RMS and maximum of ``n`` error norms (m or rad); None when n = 0."""

    n: int
    mean: float | None
    std: float | None
    rms: float | None
    max: float | None


def error_stats(norms) -> ErrorStats:
    """The statistics of error norms; NaN entries were not measured."""
    v = np.asarray(norms, dtype=float).ravel()
    v = v[np.isfinite(v)]
    if v.size == 0:
        return ErrorStats(0, None, None, None, None)
    return ErrorStats(n=int(v.size), mean=float(v.mean()), std=float(v.std(ddof=1)) if v.size > 1 else 0.0,
                      rms=float(np.sqrt(np.mean(v ** 2))), max=float(v.max()))


@dataclass(frozen=True)
class ErrorSummary:
    """Position error statistics before and after calibration on the fitted and held-out poses."""

    fit_before: ErrorStats
    fit_after: ErrorStats
    validation_before: ErrorStats
    validation_after: ErrorStats

    KEYS = ("fit_before", "fit_after", "validation_before", "validation_after")

    def __getitem__(self, key: str) -> ErrorStats:
        return getattr(self, key)


@dataclass(frozen=True)
class LimitJudgement:
    """The mean error after calibration (``compared``: held-out poses, else fitted) against the limit
    of absolute accuracy, metres; ``reached`` within ``LIMIT_REACHED_WITHIN`` of it."""

    limit_m: float
    compared: str
    mean_error_m: float
    ratio: float
    reached: bool


def judge_against_limit(limit, stats: ErrorSummary) -> LimitJudgement:
    """The validation mean error against the limit of absolute accuracy (an AccuracyLimit or metres)."""
    value = float(getattr(limit, "limit", limit))
    key = "validation_after" if stats.validation_after.n else "fit_after"
    mean = stats[key].mean
    ratio = mean / value
    return LimitJudgement(limit_m=value, compared=key, mean_error_m=mean, ratio=ratio,
                          reached=bool(ratio <= LIMIT_REACHED_WITHIN))


@dataclass(frozen=True)
class ParameterEstimate:
    """One identified parameter: its SI unit, the value the solve started from, the estimate and
    its standard deviation."""

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


@dataclass(frozen=True, eq=False)
class CalibrationResult:
    """Everything a calibration produced. Fields are always present; absent data are None.

    Per measured point, on the fitted poses: ``errors_before``/``errors_after`` (n_poses, n_markers)
    position error norms in metres (NaN where not measured), ``residual_vectors`` (n_poses,
    n_markers, 3) calibrated minus measured and ``measured_positions`` likewise, metres in W,
    ``readings`` (n_poses, n_joints) the joint readings (SI), and for 6D data
    ``rotation_errors_before``/``rotation_errors_after`` (n_poses, n_markers) rotation error angles in
    radians (None for point data). The ``validation_*`` fields are the same on held-out poses, or
    None. ``stats`` summarises the position errors, ``rotation_stats`` the rotation errors (rad) or
    None. ``correlation`` is indexed like ``parameters``. ``sigma0`` is the residual standard
    deviation (m, or in stated standard deviations when the data carry them).
    """

    nominal_model: RobotModel
    calibrated_model: RobotModel
    parameters: tuple[ParameterEstimate, ...]
    covariance: np.ndarray
    correlation: np.ndarray
    identifiability: IdentifiabilityResult
    stats: ErrorSummary
    errors_before: np.ndarray
    errors_after: np.ndarray
    residual_vectors: np.ndarray
    measured_positions: np.ndarray
    success: bool
    status: int
    message: str
    nfev: int
    sigma0: float
    families: tuple[str, ...]
    loss: str
    notes: tuple[str, ...] = ()
    limit: LimitJudgement | None = None
    provenance: dict = field(default_factory=dict)
    checks: tuple[Check, ...] = ()
    readings: np.ndarray | None = None
    validation_before: np.ndarray | None = None
    validation_after: np.ndarray | None = None
    rotation_errors_before: np.ndarray | None = None
    rotation_errors_after: np.ndarray | None = None
    rotation_stats: ErrorSummary | None = None
    validation_readings: np.ndarray | None = None
    validation_residual_vectors: np.ndarray | None = None
    validation_positions: np.ndarray | None = None
    rotation_validation_before: np.ndarray | None = None
    rotation_validation_after: np.ndarray | None = None

    @property
    def verdict(self) -> str:
        """"pass", "warn" or "fail": the worst of the checks."""
        return verdict(self.checks)

    def estimate(self, name: str) -> ParameterEstimate:
        return next(p for p in self.parameters if p.name == name)

    @property
    def parameter_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    @property
    def held_nominals(self) -> tuple[tuple[str, float], ...]:
        """``(name, SI value)`` of every non-zero parameter the calibrated model keeps that was not a
        candidate (a fixed mount's gamma and b, a known marker): the report shows them beside the
        identified ones, so nothing the calibrated file holds is hidden."""
        lay = parameter_layout(self.calibrated_model)
        values = parameter_vector(self.calibrated_model)
        considered = set(self.identifiability.candidates) | set(self.parameter_names)
        return tuple((p.name, float(values[p.index])) for p in lay.parameters
                     if p.name not in considered and values[p.index] != 0.0)


def register_base(model: RobotModel, data: Measurements) -> RobotModel:
    """The model with ``X_WB`` from a closed-form rigid registration (Kabsch/Horn, via scipy).

    The nominal marker positions in frame 0 are matched to the measured ones in W; needs three
    non-collinear measured points.
    """
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


@dataclass(frozen=True, eq=False)
class _Design:
    """What the analysis step decided: the start, the problem over the identifiable parameters, and
    what the structure allows but these poses lose (``lost``) or cannot pin down (``weak``)."""

    start: RobotModel
    p0: np.ndarray
    problem: Problem
    identifiability: IdentifiabilityResult
    compliance: bool
    lost: tuple[str, ...] = ()
    weak: tuple[tuple[str, str], ...] = ()
    weak_kept: bool = False


@dataclass(frozen=True, eq=False)
class _Analysis:
    """What the data can identify, before asking what they can pin down: the problem over the
    candidates, its Jacobian at the start, the rank analysis and what these poses lose."""

    problem: Problem
    J: np.ndarray
    names: tuple[str, ...]
    identifiability: IdentifiabilityResult
    lost: tuple[str, ...]
    compliance: bool


@one_blas_thread
def calibrate(model: RobotModel, data: Measurements, *, parameters=("geometric",), known=(),
              validation: Measurements | None = None, loss: str = "linear", f_scale: float | None = None,
              tol: float = DEFAULT_TOL, max_nfev: int | None = None, initial_base: str = "model",
              limit=None, noise=None, on_outliers: str = "refit", weak: str = "eliminate",
              nonnegative_compliance: bool = False) -> CalibrationResult:
    """Identify the identifiable parameters of ``model`` from ``data``, and check the result.

    ``parameters``: families (``geometric``, ``compliance``, ``base``, ``markers``, ``frames``)
    and/or explicit names; ``known``: families or names held at their model values.
    ``initial_base``: ``"model"`` starts from the model's base pose, ``"register"`` from a
    closed-form rigid registration of the nominal robot onto the measurements.
    ``loss``: least-squares loss (``linear`` or a robust one of scipy's); ``f_scale`` the residual
    size (m, or in standard deviations when the data carry them) where a robust loss bends.
    ``limit``: an ``AccuracyLimit`` or a value in metres; the result then states the validation
    error (held-out poses, or the fitted ones without them) against it, and the checks expect
    residuals of the robot's own size. ``noise``: the measurement noise where the data state none,
    a ``Noise`` or an instrument class (``INSTRUMENT_NOISE``; default a laser tracker's); it weighs
    6D rows and sets the bar of the checks. ``on_outliers``: ``"refit"`` refits with a robust loss
    when a few measured points stand out, ``"flag"`` only names them. ``weak``: ``"eliminate"``
    holds weakly identifiable parameters at nominal, ``"flag"`` keeps them and warns.
    ``nonnegative_compliance``: keep compliances >= 0. The result's ``checks`` and ``verdict``
    say whether it can be trusted (docs/checks.md).
    """
    parameters, known = _as_tuple(parameters), _as_tuple(known)
    _check_inputs(model, data, validation, loss=loss, initial_base=initial_base, on_outliers=on_outliers, weak=weak)
    noise = noise if isinstance(noise, Noise) else Noise.of(noise or DEFAULT_INSTRUMENT)
    limit_m = None if limit is None else float(getattr(limit, "limit", limit))
    checks = [readings_check(model, data), reading_units_check(model, data), markers_check(model, data)]
    notes = list(model.notes) + list(data.extra.get("notes", ()))  # what the readers decided for the user
    start = _starting_model(model, data, initial_base, notes)
    design, (solution, outlier_check, outlying) = _identify(
        start, data, parameters, known + _unmeasured(model, data), tol, notes, noise=noise, limit_m=limit_m,
        weak=weak, solve_options=dict(loss=loss, f_scale=f_scale, max_nfev=max_nfev, on_outliers=on_outliers,
                                      nonnegative_compliance=nonnegative_compliance))
    # the nominal robot's spread, from the analysis' evaluation of the start (a base pose changes no spread)
    checks.insert(2, cloud_size_check(model, data, design.problem.predicted(design.p0)[0]))
    cov = covariance(solution)
    estimates = _estimates(design, solution, cov)
    checks += [outlier_check] + _result_checks(design, solution, cov, estimates, data, noise, limit_m, outlying)
    calibrated = model_from_vector(start, solution.p)
    before = _registered_nominal(design, notes)
    fit = _PoseErrors.of(model, data, design.problem, before, solution.p, design)
    val = None if validation is None else _PoseErrors.of(model_from_vector(start, before), validation, None, None,
                                                         calibrated, design)
    stats = fit.summary(val, rotation=False)
    _warn(checks)
    return CalibrationResult(
        nominal_model=model, calibrated_model=calibrated, parameters=estimates,
        covariance=cov.covariance, correlation=cov.correlation, identifiability=design.identifiability,
        success=solution.success, status=solution.status, message=solution.message, nfev=solution.nfev,
        sigma0=float(np.sqrt(cov.s2)), families=parameters, loss=solution.loss, notes=tuple(notes),
        limit=None if limit is None else judge_against_limit(limit, stats), checks=tuple(checks),
        provenance=provenance(data, validation), stats=stats, rotation_stats=fit.summary(val, rotation=True),
        **fit.fields("fit"), **(val.fields("validation") if val is not None else {}),
    )


def _as_tuple(v) -> tuple:
    return (v,) if isinstance(v, str) else tuple(v)


def _check_inputs(model: RobotModel, data: Measurements, validation, *, loss: str, initial_base: str,
                  on_outliers: str, weak: str) -> None:
    """Every argument checked before any work."""
    check_choice(loss, LOSSES, "loss")
    check_choice(initial_base, INITIAL_BASES, "initial_base")
    check_choice(on_outliers, OUTLIER_ACTIONS, "on_outliers")
    check_choice(weak, WEAK_ACTIONS, "weak")
    for what, d in (("data", data), ("validation", validation)):
        if d is None:
            continue
        src = d.source or what
        if d.q.shape[1] != model.n_joints:
            raise InputError(f"{d.q.shape[1]} joint columns for a model with {model.n_joints} joints "
                             f"({', '.join(model.joint_names)})", source=src)
        for n in d.marker_names:
            if n not in model.marker_names:
                raise InputError(f"marker {n!r} is not in the model (markers: {', '.join(model.marker_names)})",
                                 source=src)


def _unmeasured(model: RobotModel, data: Measurements) -> tuple[str, ...]:
    """The parameter names of markers the data never measured: nothing can identify them."""
    seen = {n for j, n in enumerate(data.marker_names) if data.mask[:, j].any()}
    lay = parameter_layout(model)
    return tuple(p.name for p in lay.parameters if p.role == "marker" and p.owner not in seen)


def _starting_model(model: RobotModel, data: Measurements, initial_base: str, notes: list) -> RobotModel:
    """The model the solve starts from: the user's, or with a registered base."""
    if initial_base != "register":
        return model
    notes.append("base pose started from a closed-form registration of the nominal robot on the data")
    notes.append("base parameters are reported against the registered base (nominal column), not the model file's")
    return register_base(model, data)


def _identify(start: RobotModel, data: Measurements, parameters: tuple, known: tuple, tol: float, notes: list, *,
              noise: Noise, limit_m: float | None, weak: str, solve_options: dict):
    """The design and its solution. Weak parameters are first judged at the noise expected. When the
    fit leaves residuals well above it, spread over every point (no outlier) and of a size a robot's
    repeatability or an unmodelled effect explains, they are judged again at the scatter the fit
    shows, and the fit repeated without those it cannot pin down. Larger residuals are a mistake in
    the data or the model, which the checks name; they are left to them."""
    analysis = _analyse(start, data, parameters, known, tol, notes, noise=noise)
    design = _pin_down(start, analysis, noise, limit_m, weak)
    solved = _solve(design, data, noise, notes, **solve_options)
    expected, _ = expected_noise(noise, limit_m)
    scatter = _scatter(design, solved[0], data, solved[2])
    if weak != "eliminate" or solved[2].any() or not FIT_RATIO * expected < scatter <= ROBOT_RESIDUAL_MAX:
        return design, solved
    try:
        wider = _pin_down(start, analysis, noise, limit_m, weak, scatter)
    except DegenerateDataError:
        return design, solved
    if wider.identifiability.identified == design.identifiability.identified:
        return design, solved
    notes.append(f"residuals of {scatter * 1e3:.3g} mm per axis, {scatter / expected:.3g} times the expected "
                 f"{expected * 1e3:.3g} mm: the parameters these poses cannot pin down at that scatter are held at "
                 "nominal and the fit repeated")
    return wider, _solve(wider, data, noise, notes, **solve_options)


def _scatter(design: _Design, solution: Solution, data: Measurements, outlying: np.ndarray) -> float:
    """Per-axis RMS (m) of the position residuals, outliers left out."""
    r = design.problem.errors(solution.p)[data.mask][~outlying]
    return float(np.sqrt(np.mean(r ** 2))) if r.size else 0.0


def _analyse(start: RobotModel, data: Measurements, parameters: tuple, known: tuple, tol: float,
             notes: list, *, noise: Noise) -> _Analysis:
    """Which candidates the data can identify; refuse data that cannot determine them."""
    orientation = data.has_orientation
    names = candidate_parameters(start, parameters, orientation=orientation, known=known)
    notes += [f"parameters {p!r} matched: {', '.join(m)}" for p, m in matched_by_pattern(start, parameters,
                                                                                       orientation=orientation)]
    compliance = needs_compliance(start, names)
    measured = tuple(n for j, n in enumerate(data.marker_names) if data.mask[:, j].any())
    theory = theoretical_identifiability(start, parameters, known, orientation, tol, measured)
    n_unique = _distinct_rows(data.q)
    if n_unique < data.n_poses:
        notes.append(f"{data.n_poses - n_unique} of {data.n_poses} poses repeat an earlier joint configuration "
                     "exactly: they average noise but add no information")
    prob = Problem(start, data, names, compliance=compliance, noise=noise)
    needed = len(theory.identified)
    distinct_rows = prob.n_rows * n_unique // data.n_poses
    if distinct_rows <= needed:
        rows_per_pose = 3 * (1 + int(orientation))
        raise DegenerateDataError(
            f"{data.n_poses} poses ({n_unique} distinct) give {distinct_rows} equations for {needed} identifiable "
            f"parameters; at least {needed // rows_per_pose + 1} distinct poses are needed, and several times "
            "that for a useful estimate")
    J = prob.reduced_jacobian(parameter_vector(start))
    lay = parameter_layout(start)
    ident = analyse(J, names, tol=tol, quantities=[lay[n].quantity for n in names], n_rows=prob.n_rows)
    ident = backlash_reasons(ident, prob)
    lost = tuple(n for n in theory.identified if n not in ident.identified and n in names)
    return _Analysis(prob, J, names, ident, lost, compliance)


def _distinct_rows(q: np.ndarray) -> int:
    """The number of distinct rows of ``q``. Rows with distinct projections on a fixed direction
    are distinct: only when two projections tie are the rows compared, as bytes (+ 0.0 makes -0.0
    and 0.0 alike)."""
    rows = np.ascontiguousarray(q + 0.0)
    h = np.sort(rows @ (1.0 / np.sqrt(np.arange(2.0, rows.shape[1] + 2.0))))
    if np.all(h[1:] != h[:-1]):
        return len(rows)
    return len(np.unique(rows.view(np.dtype((np.void, rows.dtype.itemsize * rows.shape[1]))).ravel()))


def _pin_down(start: RobotModel, analysis: _Analysis, noise: Noise, limit_m: float | None, weak: str,
              scatter: float = 0.0) -> _Design:
    """The design over what the data can also pin down at the expected noise (or at ``scatter``, m,
    when the fit showed more)."""
    prob = analysis.problem
    ident, weak_found = _weak(prob, analysis.J, analysis.names, analysis.identifiability, noise, limit_m, scatter,
                              eliminate=weak == "eliminate")
    if not ident.identified:
        raise DegenerateDataError("no parameter is identifiable from these data")
    free = prob.over(ident.identified)   # the solve starts where the analysis evaluated the model
    if free.n_rows <= len(ident.identified):
        raise DegenerateDataError(f"{free.n_rows} equations for {len(ident.identified)} parameters")
    return _Design(start=start, p0=parameter_vector(start), problem=free, identifiability=ident,
                   compliance=analysis.compliance, lost=analysis.lost, weak=weak_found, weak_kept=weak == "flag")


def _weak(prob: Problem, J: np.ndarray, names, ident: IdentifiabilityResult, noise: Noise, limit_m,
          scatter: float, *, eliminate: bool):
    """The analysis with weakly identifiable parameters eliminated (or only named), and those
    parameters with their predicted standard deviations. Eliminating one may let an equivalent one
    in (a member of the same dependent group): the analysis repeats until none is weak."""
    lay = parameter_layout(prob.model)
    p0 = parameter_vector(prob.model)
    expected = max(expected_noise(noise, limit_m)[0], scatter)
    sigma = expected / noise.position if prob.weighted else expected   # weighted rows are in noise units
    quantities = [lay[n].quantity for n in names]
    moments = prob.compliance_moments(p0)
    dropped: dict[str, str] = {}
    said: list[tuple[str, str]] = []
    result = ident
    while True:
        cols = [list(names).index(n) for n in result.identified]
        found = weakly_identifiable(J[:, cols], result.identified, [quantities[k] for k in cols], sigma,
                                    moments=moments)
        said += [(n, _effect(e, lay[by].quantity) + ("" if by == n else f" of {by} with it")) for n, by, e, _ in found]
        if not found or not eliminate:
            return result, tuple(said)
        dropped.update({n: "is weakly identifiable: " + (f"predicted std {_effect(e, lay[n].quantity)} exceeds "
                           if by == n else f"with it, {by}'s predicted std {_effect(e, lay[by].quantity)} exceeds ")
                        + _effect(b, lay[by].quantity) for n, by, e, b in found})
        result = eliminate_parameters(ident, J, names, quantities, dropped, n_rows=prob.n_rows)


def _effect(v: float, quantity: str) -> str:
    if quantity == "length":
        return f"{v * 1e3:.3g} mm"
    return f"{np.degrees(v):.3g} deg" + (" of deflection" if quantity == "compliance" else "")


def _solve(design: _Design, data: Measurements, noise: Noise, notes: list, *, loss: str, f_scale, max_nfev,
           on_outliers: str, nonnegative_compliance: bool):
    """The solution, the outlier check and the outlier mask of the measured points; with
    ``on_outliers="refit"`` a linear fit that leaves a few outliers is refitted with a robust loss."""
    lower = None
    if nonnegative_compliance:
        lay = parameter_layout(design.start)
        lower = np.array([0.0 if lay[n].family == "compliance" else -np.inf for n in design.identifiability.identified])
    solution = solve(design.problem, design.p0, loss=loss, f_scale=f_scale, max_nfev=max_nfev, lower=lower)
    check, out = _outliers(design, solution, data, noise)
    if not out.any():
        return solution, check, out
    if out.mean() > OUTLIER_SHARE_MAX:
        return solution, replace(check, cause="so many that the data do not fit the model: see the other checks",
                                 fix="correct the data or the model; a robust loss would hide the misfit"), out
    in_chunks = design.problem.chunked
    if loss == "linear" and on_outliers == "refit" and in_chunks:
        notes.append(f"{out.sum()} outlier(s) found: a campaign solved in chunks is not refitted with a robust loss")
    elif loss == "linear" and on_outliers == "refit":
        solution = solve(design.problem, design.p0, loss="soft_l1", max_nfev=max_nfev, lower=lower)
        notes.append(f"{out.sum()} outlier(s) found by the least-squares fit: refitted with the robust loss soft_l1")
        check, out = _outliers(design, solution, data, noise)
    if (loss != "linear" or on_outliers == "refit") and not in_chunks:
        check = replace(check, status="warn" if out.any() else "pass",
                        summary=check.summary + f"; the robust loss {solution.loss} sets them aside",
                        fix="check those measurements; remove them to fit without them")
    return solution, check, out


def _outliers(design: _Design, solution: Solution, data: Measurements, noise: Noise):
    residuals = design.problem.errors(solution.p)[data.mask]
    labels = _PointLabels(data)
    sigma = None if data.sigma is None else data.sigma[data.mask]
    return outlier_check(residuals, sigma, noise, labels)


class _PointLabels:
    """The label of each measured point (pose, marker), made only for those a check names."""

    def __init__(self, data: Measurements):
        self.data = data
        self.rows, self.markers = np.nonzero(data.mask)

    def __len__(self) -> int:
        return len(self.rows)

    def __getitem__(self, i: int) -> str:
        return f"{self.data.labels[self.rows[i]]}, marker {self.data.marker_names[self.markers[i]]}"


def _result_checks(design: _Design, solution: Solution, cov: Covariance, estimates, data: Measurements,
                   noise: Noise, limit_m, outlying) -> list[Check]:
    """The checks of the solution: convergence, fit, plausibility, support, correlation, identifiability."""
    residuals = design.problem.errors(solution.p)[data.mask]
    sigma = None if data.sigma is None else data.sigma[data.mask]
    moments = design.problem.compliance_moments(solution.p)
    deflections = {e.name: e.estimate * float(np.max(np.abs(moments[e.name]))) for e in estimates
                   if e.name in moments}
    out = [convergence_check(solution.success, solution.message, solution.nfev),
           fit_check(residuals, sigma, noise, limit_m, outlying),
           plausibility_check(estimates, tolerances(design.start), deflections),
           support_check(estimates), compliance_sign_check(estimates), backlash_sign_check(estimates),
           correlation_check([e.name for e in estimates], cov.correlation),
           identifiability_check(design.lost, design.weak, weak_kept=design.weak_kept)]
    if data.has_orientation:
        out.append(_orientation_check(design, solution, data))
    return out


def _orientation_check(design: _Design, solution: Solution, data: Measurements) -> Check:
    """A wrong orientation convention converges quietly: test the rotations, with or without stated sigmas."""
    vectors = design.problem.errors(solution.p)
    rot = design.problem.rotation_errors(solution.p)[data.rot_mask]
    found = misfit_notes(vectors[data.mask], rot, characteristic_length_m=characteristic_length(data.positions[data.mask]),
                         sigma_rot_rad=None if data.sigma_rot is None else data.sigma_rot[data.rot_mask])
    rms = float(np.degrees(np.sqrt(np.mean(np.sum(rot ** 2, axis=1)))))
    if not found:
        return Check("orientation fit", "pass", f"rotation residuals {rms:.3g} deg RMS")
    return Check("orientation fit", "fail", found[0], cause="a wrong orientation convention or angle unit",
                 fix="declare the convention (--orientation) and the angle unit of the rotation columns")


_WARNING_CLASS = {"solver convergence": ConvergenceWarning, "fit against the instrument": MisfitWarning,
                  "orientation fit": MisfitWarning, "identifiability at these poses": IdentifiabilityWarning}


def _warn(checks) -> None:
    """Every check that did not pass, as a warning users can filter."""
    for c in checks:
        if c.status != "pass":
            category = _WARNING_CLASS.get(c.name, CheckWarning)
            warnings.warn(f"{c.name} ({'FAILED' if c.status == 'fail' else 'warning'}): {c.summary}", category,
                          stacklevel=3)


def _registered_nominal(design: _Design, notes: list) -> np.ndarray:
    """The parameter vector errors "before" are taken at: the nominal geometry, with the base and
    marker parameters being identified fitted to the data first (a raw base guess says nothing
    about the robot). The start itself when none of them is free, or nothing else is."""
    lay = parameter_layout(design.start)
    free = design.identifiability.identified
    placed = tuple(n for n in free if lay[n].family in ("base", "markers"))
    if not placed or len(placed) == len(free):
        return design.p0
    sol = solve(design.problem.over(placed), design.p0, tol=REGISTRATION_TOL)
    notes.append("errors before calibration are those of the nominal geometry with its base and markers fitted "
                 f"to the data ({', '.join(placed)})")
    return sol.p


def _estimates(design: _Design, solution: Solution, cov: Covariance) -> tuple[ParameterEstimate, ...]:
    """Each identified parameter against the start of the solve: the user's model, or with
    registration the registered base (rotation corrections are small angles about it)."""
    lay = parameter_layout(design.start)
    idx = design.problem.free_idx
    return tuple(ParameterEstimate(n, lay[n].unit, float(design.p0[idx[k]]), float(solution.p[idx[k]]),
                                   float(cov.std[k]), family=lay[n].family, quantity=lay[n].quantity)
                 for k, n in enumerate(design.identifiability.identified))


@dataclass(frozen=True, eq=False)
class _PoseErrors:
    """Errors before and after calibration on one set of poses: position vectors (n, m, 3) in m and,
    for 6D data, rotation vectors (n, m, 3) in rad; NaN where not measured."""

    data: Measurements
    before: np.ndarray
    after: np.ndarray
    rotation_before: np.ndarray | None
    rotation_after: np.ndarray | None

    @staticmethod
    def of(nominal: RobotModel, data: Measurements, problem, p0, after, design: _Design) -> _PoseErrors:
        """On the fitted poses ``problem`` evaluates both (``after`` a parameter vector); on held-out
        poses (``problem`` None) the nominal and the calibrated model (``after``) are evaluated."""
        if problem is not None and nominal is design.start:
            # the analysis evaluated the start (a compliance deflects nothing there unless the model has one)
            prob_before, p_before = problem, p0
        else:
            prob_before, p_before = _problem_of(nominal, data, nominal.has_compliance)
        vb, rb = prob_before.errors(p_before), prob_before.rotation_errors(p_before)
        if problem is not None:
            prob_after, p_after = problem, after      # the solution's pass is cached from the last Jacobian
        else:
            prob_after, p_after = _problem_of(after, data, design.compliance)
        return _PoseErrors(data, vb, prob_after.errors(p_after), rb, prob_after.rotation_errors(p_after))

    def summary(self, other: _PoseErrors | None, *, rotation: bool) -> ErrorSummary | None:
        """Statistics of the error norms here (fit) and on ``other`` (held out), positions or rotations."""
        if rotation and self.rotation_after is None:
            return None

        def stats(e: _PoseErrors | None, when: str):
            if e is None:
                return error_stats([])
            v = getattr(e, f"rotation_{when}" if rotation else when)
            return error_stats([] if v is None else np.linalg.norm(v, axis=2))

        return ErrorSummary(stats(self, "before"), stats(self, "after"), stats(other, "before"), stats(other, "after"))

    def fields(self, which: str) -> dict:
        """The result fields of this set (``which``: "fit" or "validation")."""
        norms = {k: None if v is None else np.linalg.norm(v, axis=2)
                 for k, v in (("before", self.before), ("after", self.after),
                              ("rotation_before", self.rotation_before), ("rotation_after", self.rotation_after))}
        positions = np.where(self.data.mask[..., None], self.data.positions, np.nan)
        if which == "fit":
            return {"errors_before": norms["before"], "errors_after": norms["after"], "residual_vectors": self.after,
                    "measured_positions": positions, "readings": self.data.q,
                    "rotation_errors_before": norms["rotation_before"],
                    "rotation_errors_after": norms["rotation_after"]}
        return {"validation_before": norms["before"], "validation_after": norms["after"],
                "validation_residual_vectors": self.after, "validation_positions": positions,
                "validation_readings": self.data.q, "rotation_validation_before": norms["rotation_before"],
                "rotation_validation_after": norms["rotation_after"]}


def _problem_of(model: RobotModel, data: Measurements, compliance: bool) -> tuple[Problem, np.ndarray]:
    """The problem of evaluating ``model`` on ``data`` (no free parameter), and its vector."""
    return Problem(model, data, (), compliance=compliance), parameter_vector(model)


def provenance(data: Measurements, validation: Measurements | None = None) -> dict:
    """Software, date and the inputs (source, SHA-256, pose labels in the order of the error rows)."""
    prov = {"software": "robocal", "version": __version__,
            "date": datetime.now(timezone.utc).isoformat(timespec="seconds")}
    for key, d in (("data", data), ("validation", validation)):
        if d is not None:
            prov[key] = {"source": d.source, "sha256": d.sha256, "n_poses": d.n_poses, "labels": list(d.labels)}
    return prov


@dataclass(frozen=True, eq=False)
class Comparison:
    """Geometric-only against geometric-and-compliance identification on the same data, and, when
    asked, against geometric, compliance and backlash together (the third).

    ``f_statistic``/``p_value``: the nested-model F test on the fitted residuals (does adding the
    compliance parameters reduce the residual more than their number explains?). ``helped`` is
    True when p < ``alpha`` and, with held-out poses, the held-out RMS error fell too.
    ``backlash``, ``backlash_f``, ``backlash_p``, ``backlash_helped``: the same test of the third
    against the second (None and False without it). ``verdict`` says both.
    """

    geometric: CalibrationResult
    combined: CalibrationResult
    f_statistic: float
    p_value: float
    helped: bool
    verdict: str
    backlash: CalibrationResult | None = None
    backlash_f: float | None = None
    backlash_p: float | None = None
    backlash_helped: bool = False

    @property
    def best(self) -> CalibrationResult:
        if self.backlash is not None and self.backlash_helped:
            return self.backlash
        return self.combined if self.helped else self.geometric

    @property
    def results(self) -> dict:
        """The identifications side by side, by what they identify."""
        out = {"geometric": self.geometric, "geometric and compliance": self.combined}
        if self.backlash is not None:
            out["geometric, compliance and backlash"] = self.backlash
        return out


def _nested_test(small: CalibrationResult, large: CalibrationResult, data: Measurements, validation, alpha: float,
                 what: str):
    """F test of ``large`` against ``small`` nested in it, and the held-out RMS: (F, p, helped, verdict)."""
    from scipy.stats import f as f_dist

    n_rows = 3 * int(data.mask.sum()) + (3 * int(data.rot_mask.sum()) if data.has_orientation else 0)
    p1, p2 = len(small.parameters), len(large.parameters)
    ssr1 = small.sigma0 ** 2 * (n_rows - p1)
    ssr2 = large.sigma0 ** 2 * (n_rows - p2)
    dfn, dfd = max(p2 - p1, 1), n_rows - p2
    F = max((ssr1 - ssr2) / dfn, 0.0) / (ssr2 / dfd)
    p_value = float(f_dist.sf(F, dfn, dfd))
    on = "validation_after" if validation is not None else "fit_after"
    v1, v2 = small.stats[on].rms, large.stats[on].rms
    helped = p_value < alpha and (validation is None or v2 < v1)
    detail = f"{'held-out' if validation is not None else 'fitted'} RMS {v1 * 1e3:.4f} mm -> {v2 * 1e3:.4f} mm"
    verdict = (f"{what} helped: {detail}; F = {F:.3g}, p = {p_value:.2g}" if helped else
               f"{what} did not help: {detail}; F = {F:.3g}, p = {p_value:.2g} (threshold {alpha})")
    return float(F), p_value, bool(helped), verdict


@one_blas_thread
def compare(model: RobotModel, data: Measurements, *, validation: Measurements | None = None, alpha: float = 0.01,
            backlash: bool = False, **kwargs) -> Comparison:
    """Run geometric and geometric-plus-compliance identifications on the same data (the paper's two),
    and with ``backlash`` a third, geometric + compliance + backlash, tested against the second.

    Keyword arguments other than ``parameters`` go to every ``calibrate`` call.
    """
    kwargs.pop("parameters", None)
    geo = calibrate(model, data, parameters=("geometric",), validation=validation, **kwargs)
    both = calibrate(model, data, parameters=("geometric", "compliance"), validation=validation, **kwargs)
    F, p_value, helped, verdict = _nested_test(geo, both, data, validation, alpha, "compliance")
    third = {}
    if backlash:
        res = calibrate(model, data, parameters=("geometric", "compliance", "backlash"), validation=validation,
                        **kwargs)
        bF, bp, bh, bv = _nested_test(both, res, data, validation, alpha, "backlash")
        third = dict(backlash=res, backlash_f=bF, backlash_p=bp, backlash_helped=bh)
        verdict = f"{verdict}\n{bv}"
    return Comparison(geometric=geo, combined=both, f_statistic=F, p_value=p_value, helped=helped, verdict=verdict,
                      **third)
