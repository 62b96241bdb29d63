"""Identification: least squares on the identifiable parameters, with uncertainty and statistics.

``calibrate`` is a short sequence of named steps: check the inputs, register the base (if asked),
analyse identifiability at the data, solve, take the covariance, run the checks on the result,
compute the error statistics, record the provenance.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from datetime import datetime, timezone

import numpy as np
from scipy.spatial.transform import Rotation

from ._checks import Check, verdict
from ._errors import (ConvergenceWarning, DegenerateDataError, IdentifiabilityWarning, InputError,
                      MisfitWarning, check_choice)
from ._identifiability import DEFAULT_TOL, IdentifiabilityResult, analyse_problem, theoretical_identifiability
from ._kinematics import evaluate
from ._measurements import Measurements
from ._options import INITIAL_BASES, LOSSES
from ._misfit import MAX_STANDARDISED_RMS, characteristic_length, misfit_notes
from ._model import RobotModel
from ._parameters import candidate_parameters, model_from_vector, parameter_layout, parameter_vector
from ._problem import Problem, needs_compliance
from ._solve import Covariance, Solution, covariance, solve
from ._version import __version__

# the limit is a mean-error bar; within this factor of it counts as reaching it
LIMIT_REACHED_WITHIN = 1.15


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
    """What the analysis step decided: the start, the problem over the identifiable parameters."""

    start: RobotModel
    p0: np.ndarray
    problem: Problem
    identifiability: IdentifiabilityResult
    compliance: bool


def calibrate(model: RobotModel, data: Measurements, *, parameters=("geometric",), known=(),
              validation: Measurements | None = None, loss: str = "linear", f_scale: float | None = None,
              tol: float = DEFAULT_TOL, max_nfev: int | None = None, initial_base: str = "model",
              limit=None) -> CalibrationResult:
    """Identify the identifiable parameters of ``model`` from ``data``.

    ``parameters``: families (``geometric``, ``compliance``, ``base``, ``markers``, ``frames``)
    and/or explicit names; ``known``: families or names held at their model values.
    ``initial_base``: ``"model"`` starts from the model's base pose, ``"register"`` from a
    closed-form rigid registration of the nominal robot onto the measurements.
    ``loss``: least-squares loss (``linear`` or a robust one of scipy's); ``f_scale`` the residual
    size (m, or in standard deviations when the data carry them) where a robust loss bends.
    ``limit``: an ``AccuracyLimit`` or a value in metres; the result then states the validation
    error (held-out poses, or the fitted ones without them) against it.
    """
    parameters, known = _as_tuple(parameters), _as_tuple(known)
    _check_inputs(model, data, validation, loss=loss, initial_base=initial_base)
    notes: list[str] = []
    start = _starting_model(model, data, initial_base, notes)
    design = _analyse(start, data, parameters, known, tol, notes)
    solution = solve(design.problem, design.p0, loss=loss, f_scale=f_scale, max_nfev=max_nfev)
    cov = covariance(solution)
    notes += _checks(design, solution, cov, data)
    calibrated = model_from_vector(start, solution.p)
    fit = _PoseErrors.of(model, data, design.problem, design.p0, solution.p, design)
    val = None if validation is None else _PoseErrors.of(model, validation, None, None, calibrated, design)
    stats = fit.summary(val, rotation=False)
    return CalibrationResult(
        nominal_model=model, calibrated_model=calibrated, parameters=_estimates(design, solution, cov),
        covariance=cov.covariance, correlation=cov.correlation, identifiability=design.identifiability,
        success=solution.success, status=solution.status, message=solution.message, nfev=solution.nfev,
        sigma0=float(np.sqrt(cov.s2)), families=parameters, loss=loss, notes=tuple(notes),
        limit=None if limit is None else judge_against_limit(limit, stats),
        provenance=provenance(data, validation), stats=stats, rotation_stats=fit.summary(val, rotation=True),
        **fit.fields("fit"), **(val.fields("validation") if val is not None else {}),
    )


def _as_tuple(v) -> tuple:
    return (v,) if isinstance(v, str) else tuple(v)


def _check_inputs(model: RobotModel, data: Measurements, validation, *, loss: str, initial_base: str) -> None:
    """Every argument checked before any work."""
    check_choice(loss, LOSSES, "loss")
    check_choice(initial_base, INITIAL_BASES, "initial_base")
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


def _starting_model(model: RobotModel, data: Measurements, initial_base: str, notes: list) -> RobotModel:
    """The model the solve starts from: the user's, or with a registered base."""
    if initial_base != "register":
        return model
    notes.append("base pose started from a closed-form registration of the nominal robot on the data")
    notes.append("base parameters are reported against the registered base (nominal column), not the model file's")
    return register_base(model, data)


def _analyse(start: RobotModel, data: Measurements, parameters: tuple, known: tuple, tol: float,
             notes: list) -> _Design:
    """Which candidates the data can identify; refuse data that cannot determine them."""
    orientation = data.has_orientation
    names = candidate_parameters(start, parameters, orientation=orientation, known=known)
    compliance = needs_compliance(start, names)
    theory = theoretical_identifiability(start, parameters, known, orientation, tol)
    n_unique = len(np.unique(data.q, axis=0))
    if n_unique < data.n_poses:
        notes.append(f"{data.n_poses - n_unique} of {data.n_poses} poses repeat an earlier joint configuration "
                     "exactly: they average noise but add no information")
    prob = Problem(start, data, names, compliance=compliance)
    needed = len(theory.identified)
    distinct_rows = prob.n_rows * n_unique // data.n_poses
    if distinct_rows <= needed:
        rows_per_pose = 3 * (1 + int(orientation))
        raise DegenerateDataError(
            f"{data.n_poses} poses ({n_unique} distinct) give {distinct_rows} equations for {needed} identifiable "
            f"parameters; at least {needed // rows_per_pose + 1} distinct poses are needed, and several times "
            "that for a useful estimate")
    ident = analyse_problem(prob, names, tol=tol)
    lost = [n for n in theory.identified if n not in ident.identified]
    if lost:
        msg = (f"the poses cannot separate {len(lost)} parameter(s) that this robot's structure allows to "
               f"identify: {', '.join(lost)}; they are held at their nominal values. Add poses that move "
               "the joints more widely (the design is rank-deficient)")
        notes.append(msg)
        warnings.warn(msg, IdentifiabilityWarning, stacklevel=3)
    if not ident.identified:
        raise DegenerateDataError("no parameter is identifiable from these data")
    free = prob.over(ident.identified)   # the solve starts where the analysis evaluated the model
    if free.n_rows <= len(ident.identified):
        raise DegenerateDataError(f"{free.n_rows} equations for {len(ident.identified)} parameters")
    return _Design(start=start, p0=parameter_vector(start), problem=free, identifiability=ident,
                   compliance=compliance)


def _checks(design: _Design, solution: Solution, cov: Covariance, data: Measurements) -> list[str]:
    """Notes (also issued as warnings) where the result's own figures say something is off."""
    notes = []
    if not solution.success:
        warnings.warn(f"identification did not converge: {solution.message}", ConvergenceWarning, stacklevel=3)
    if solution.f_scale is not None:
        unit = "standard deviations" if data.sigma is not None else "m"
        notes.append(f"robust loss {solution.loss} bends at {solution.f_scale:.3g} {unit} (3 robust standard "
                     "deviations)")
    misfit = []
    if data.sigma is not None and cov.s2 > MAX_STANDARDISED_RMS ** 2:
        misfit.append(f"residuals are {np.sqrt(cov.s2):.1f} times the stated measurement standard deviations: the "
                      "model or the data declaration (units, orientation convention, marker names) does not fit")
    if data.has_orientation:
        # a wrong orientation convention converges quietly: test the rotations, with or without stated sigmas
        vectors = design.problem.errors(solution.p)
        Rp = design.problem.predicted(solution.p)[1][data.rot_mask]
        rot_res = Rotation.from_matrix(Rp @ np.swapaxes(data.rotations[data.rot_mask], -1, -2)).as_rotvec()
        misfit += misfit_notes(vectors[data.mask], rot_res,
                               characteristic_length_m=characteristic_length(data.positions[data.mask]),
                               sigma_rot_rad=None if data.sigma_rot is None else data.sigma_rot[data.rot_mask])
    for msg in misfit:
        warnings.warn(msg, MisfitWarning, stacklevel=3)
    return notes + misfit


def _estimates(design: _Design, solution: Solution, cov: Covariance) -> tuple[ParameterEstimate, ...]:
    """Each identified parameter against the start of the solve: the user's model, or with
    registration the registered base (rotation corrections are small angles about it)."""
    lay = parameter_layout(design.start)
    idx = design.problem.free_idx
    return tuple(ParameterEstimate(n, lay[n].unit, float(design.p0[idx[k]]), float(solution.p[idx[k]]),
                                   float(cov.std[k]))
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
    """Geometric-only against geometric-and-compliance identification on the same data.

    ``f_statistic``/``p_value``: the nested-model F test on the fitted residuals (does adding the
    compliance parameters reduce the residual more than their number explains?). ``helped`` is
    True when p < ``alpha`` and, with held-out poses, the held-out RMS error fell too.
    """

    geometric: CalibrationResult
    combined: CalibrationResult
    f_statistic: float
    p_value: float
    helped: bool
    verdict: str

    @property
    def best(self) -> CalibrationResult:
        return self.combined if self.helped else self.geometric


def compare(model: RobotModel, data: Measurements, *, validation: Measurements | None = None, alpha: float = 0.01,
            **kwargs) -> Comparison:
    """Run geometric and geometric-plus-compliance identifications on the same data (the paper's two).

    Keyword arguments other than ``parameters`` go to both ``calibrate`` calls.
    """
    from scipy.stats import f as f_dist

    kwargs.pop("parameters", None)
    geo = calibrate(model, data, parameters=("geometric",), validation=validation, **kwargs)
    both = calibrate(model, data, parameters=("geometric", "compliance"), validation=validation, **kwargs)
    n_rows = 3 * int(data.mask.sum()) + (3 * int(data.rot_mask.sum()) if data.has_orientation else 0)
    p1, p2 = len(geo.parameters), len(both.parameters)
    ssr1 = geo.sigma0 ** 2 * (n_rows - p1)
    ssr2 = both.sigma0 ** 2 * (n_rows - p2)
    dfn, dfd = max(p2 - p1, 1), n_rows - p2
    F = max((ssr1 - ssr2) / dfn, 0.0) / (ssr2 / dfd)
    p_value = float(f_dist.sf(F, dfn, dfd))
    significant = p_value < alpha
    on = "validation_after" if validation is not None else "fit_after"
    v1, v2 = geo.stats[on].rms, both.stats[on].rms
    helped = significant and (validation is None or v2 < v1)
    detail = f"{'held-out' if validation is not None else 'fitted'} RMS {v1 * 1e3:.4f} mm -> {v2 * 1e3:.4f} mm"
    verdict = (f"compliance helped: {detail}; F = {F:.3g}, p = {p_value:.2g}" if helped else
               f"compliance did not help: {detail}; F = {F:.3g}, p = {p_value:.2g} (threshold {alpha})")
    return Comparison(geometric=geo, combined=both, f_statistic=float(F), p_value=p_value, helped=bool(helped),
                      verdict=verdict)
