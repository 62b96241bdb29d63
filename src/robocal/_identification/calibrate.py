"""Identification: least squares on the identifiable parameters, with uncertainty, the accuracy
in use and the checks.

``calibrate`` is a sequence of named steps, each returning a record (no step writes into another's):
check the inputs, register the base (if asked), analyse identifiability at the data, choose the
model by its cross-validated error (weak parameters held back only where that costs nothing in
use; points that stand out set aside only where that helps), take the covariance, judge the
result (the accuracy in use, what the robot does over its workspace, the campaign's coverage),
compute the error statistics, record the provenance.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field, replace
from datetime import datetime, timezone
from typing import TYPE_CHECKING, cast, overload

import numpy as np
from scipy.spatial.transform import Rotation

from .._base.arguments import FLAG, FRACTION, both, checked, is_a, measured_on, optional
from .._base.errors import (
    CheckWarning,
    ConvergenceWarning,
    DegenerateDataError,
    IdentifiabilityWarning,
    InputError,
    MisfitWarning,
    check_choice,
    warn,
)
from .._base.options import DEFAULT_INSTRUMENT, INITIAL_BASES, LOSSES, OUTLIER_ACTIONS, WEAK_ACTIONS
from .._base.threads import one_blas_thread
from .._model.contacts import Contacts
from .._model.kinematics import evaluate
from .._model.measurements import Measurements, Noise
from .._model.parameters import (
    candidate_parameters,
    matched_by_pattern,
    model_from_vector,
    parameter_layout,
    parameter_vector,
)
from .._model.robot import RobotModel
from .._version import __version__
from .checks import (
    FIT_RATIO,
    GROSS_FACTOR,
    OUTLIER_RUN,
    OUTLIER_SHARE_MAX,
    Check,
    WorkspaceChange,
    backlash_sign_check,
    cloud_size_check,
    compliance_sign_check,
    convergence_check,
    correlation_check,
    coverage_check,
    expected_noise,
    fit_check,
    identifiability_check,
    in_use_check,
    interchangeable_pairs,
    limit_check,
    markers_check,
    outlier_bar,
    outlier_check,
    outlier_scores,
    plausibility_check,
    reading_units_check,
    readings_check,
    support_check,
    tolerances,
    verdict,
)
from .estimates import (
    REGISTRATION_TOL,
    ErrorStats,
    ParameterEstimate,
    effect_text,
    error_stats,
    workspace_change,
)
from .holdout import (
    DEFAULT_FOLDS,
    AccuracyInUse,
    Coverage,
    FoldProblems,
    HeldOut,
    accuracy_in_use,
    coverage,
    cross_validate,
    evaluated,
    fold_labels,
    paired_excess,
    with_points_aside,
    workspace_readings,
)
from .identifiability import (
    DEFAULT_TOL,
    WEAK_STD,
    IdentifiabilityResult,
    analyse,
    backlash_reasons,
    theoretical_identifiability,
    weakly_identifiable,
)
from .identifiability import eliminate as eliminate_parameters
from .misfit import characteristic_length, misfit_notes
from .problem import Problem, design_measurements, needs_compliance
from .solve import Covariance, Solution, covariance, solve

if TYPE_CHECKING:
    from .contact_figures import ContactFigures

# the limit is a mean-error bar; within this factor of it counts as reaching it
LIMIT_REACHED_WITHIN = 1.15


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
    """The mean error in use after calibration (``compared``: "validation_after" for a validation
    set, "cross-validation" otherwise) against the limit of absolute accuracy, metres; ``reached``
    within ``LIMIT_REACHED_WITHIN`` of it."""

    limit_m: float
    compared: str
    mean_error_m: float
    ratio: float
    reached: bool


def judge_against_limit(limit, in_use: AccuracyInUse) -> LimitJudgement:
    """The mean error in use after calibration against the limit of absolute accuracy (an
    AccuracyLimit or metres)."""
    value = float(getattr(limit, "limit", limit))
    key = "cross-validation" if in_use.method == "cross-validation" else "validation_after"
    mean = float(cast(float, in_use.position_after.mean))
    ratio = mean / value
    return LimitJudgement(limit_m=value, compared=key, mean_error_m=mean, ratio=ratio,
                          reached=bool(ratio <= LIMIT_REACHED_WITHIN))


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

    A calibration that fitted contacts holds the kit's figures in ``contacts`` (``ContactFigures``:
    socket consistency and spacing error, fitted and held out, what each kind of contact reaches);
    its per-point fields are those of the tracker data fitted beside them (no rows without), and
    its ``in_use`` the socket consistency of each placement predicted by the others (or of the
    held-out placements).
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
    in_use: AccuracyInUse | None = None
    coverage: Coverage | None = None
    contacts: ContactFigures | None = None

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


@checked(model=is_a(RobotModel), data=both(is_a(Measurements), measured_on()))
def register_base(model: RobotModel, data: Measurements) -> RobotModel:
    """The model with ``X_WB`` from a closed-form rigid registration (Kabsch/Horn, via scipy).

    The nominal marker positions in frame 0 are matched to the measured ones in W; needs three
    non-collinear measured points.

    Parameters
    ----------
    {model, data}

    Returns
    -------
    RobotModel
        ``model`` with the registered base pose.
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
class _Analysis:
    """What the data can identify, before asking what they can pin down: the problem over the
    candidates, its Jacobian at the start, the rank analysis and what these poses lose."""

    problem: Problem
    J: np.ndarray
    names: tuple[str, ...]
    identifiability: IdentifiabilityResult
    lost: tuple[str, ...]
    compliance: bool
    notes: tuple[str, ...] = ()


@dataclass(frozen=True, eq=False)
class _Design:
    """One model choice: the start, the problem over the parameters it frees, and what the structure
    allows but these poses lose (``lost``) or cannot pin down (``weak``: found, and held at nominal
    unless ``weak_kept``). ``judged_at``: the per-axis scatter (m) weak parameters were judged at."""

    start: RobotModel
    p0: np.ndarray
    problem: Problem
    identifiability: IdentifiabilityResult
    compliance: bool
    lost: tuple[str, ...] = ()
    weak: tuple[tuple[str, str], ...] = ()
    weak_kept: bool = False
    judged_at: float = 0.0
    kept_in_use: bool = False


@dataclass(frozen=True)
class _Options:
    """How to solve and what to do with outliers, weak parameters and the folds."""

    loss: str
    f_scale: float | None
    max_nfev: int | None
    on_outliers: str
    weak: str
    nonnegative_compliance: bool
    folds: int


@dataclass(frozen=True, eq=False)
class _Fit:
    """A design solved on ``data`` (its mask: the points set aside taken out), the outlier check and
    mask over ``measured`` points (those of the original data, in ``np.nonzero(mask)`` order), its
    cross-validated errors and what it noted."""

    design: _Design
    data: Measurements
    solution: Solution
    outlier_check: Check
    outlying: np.ndarray
    held_out: HeldOut
    notes: tuple[str, ...] = ()


@overload
def calibrate(model: RobotModel, data: Measurements, *, contacts: None = None, **options) -> CalibrationResult: ...


@overload
def calibrate(model: RobotModel, data: Measurements | None = None, *, contacts: Contacts,
              **options) -> CalibrationResult: ...


@one_blas_thread
def calibrate(model: RobotModel, data: Measurements | None = None, *, contacts: Contacts | None = None,
              parameters=("geometric",), known=(), validation=None, loss: str = "linear",
              f_scale: float | None = None, tol: float = DEFAULT_TOL, max_nfev: int | None = None,
              initial_base: str = "model", limit=None, noise=None, on_outliers: str = "refit",
              weak: str = "eliminate", nonnegative_compliance: bool = False, folds: int = DEFAULT_FOLDS,
              register_validation: bool = False):
    """Identify the identifiable parameters of ``model`` from ``data`` (measured points or poses)
    and/or ``contacts`` (sockets, planes, ball bars, known distances), and judge the result.

    Parameters
    ----------
    model : RobotModel
        The nominal robot; the solve starts from it.
    data : Measurements, optional
        The fitted campaign of measured points or poses (may be left out with ``contacts``).
    contacts : Contacts, optional
        Joint-only contact recordings, fitted alone or beside ``data`` in one problem (its rows in
        their stated standard deviations, ``f_scale`` too); the result's ``contacts`` then holds the
        kit's figures (socket consistency, spacing error) fitted and held out by placement, and
        ``validation`` is held-out ``Contacts`` or measured points (without ``data`` the base and
        tool are registered on them). ``initial_base="register"`` needs ``data`` (contacts
        alone fix no frame); ``register_validation`` has nothing to register on held-out contacts
        (their figures do not depend on the frame) and ``folds`` gives way to the placements.
    parameters : str or sequence of str
        What to identify: families (``geometric``, ``compliance``, ``backlash``, ``base``,
        ``markers``, ``frames``) or parameter names and patterns.
    known : str or sequence of str
        Families, names or patterns held at the model's values.
    validation : Measurements or Contacts, optional
        Held-out poses (with ``contacts``: held-out contacts) to judge the result on; without them
        it is judged by ``folds``-fold cross-validation (docs/checks.md, "Accuracy in use"), and
        contacts placement by placement.
    loss : str
        Least-squares loss: ``linear`` or a robust one of scipy's.
    f_scale : float, optional
        For a robust loss, the residual size where it bends (m, or standard deviations when the
        data state them; None: estimated).
    tol : float
        Identifiability tolerance, in (0, 1).
    max_nfev : int, optional
        Evaluations the solver may take.
    initial_base : {"model", "register"}
        Start from the model's base pose, or from a rigid registration of the nominal robot.
    limit : AccuracyLimit or float, optional
        The limit of absolute accuracy (m): the accuracy in use is judged against it, and weak
        parameters are judged at the scatter it implies (never holding back what helps in use).
    noise : Noise or str, optional
        The measurement noise where the data state none (an instrument class of
        ``INSTRUMENT_NOISE``; default a laser tracker's).
    on_outliers : {"refit", "flag"}
        Set measured points that stand out aside and fit again without them, or only name them.
    weak : {"eliminate", "flag"}
        Hold weakly identifiable parameters at nominal where that does not worsen the accuracy in
        use, or keep them all and warn.
    nonnegative_compliance : bool
        Keep compliances >= 0.
    folds : int
        Folds of the cross-validation (>= 2), without a validation set or a series column.
    register_validation : bool
        With ``validation`` from another set-up: register base and tool on it (for the models
        before and after alike) before taking its errors.

    Returns
    -------
    CalibrationResult
        Estimates, covariance, errors, the accuracy in use and the checks; ``verdict`` says whether
        it can be trusted (docs/checks.md).
    """
    _check_inputs(model, data, validation, loss=loss, initial_base=initial_base, on_outliers=on_outliers, weak=weak,
                  folds=folds, options=dict(parameters=parameters, known=known, f_scale=f_scale, tol=tol,
                                            max_nfev=max_nfev, limit=limit, noise=noise,
                                            nonnegative_compliance=nonnegative_compliance,
                                            register_validation=register_validation), contacts=contacts)
    if contacts is not None:
        return _from_contacts(model, data, contacts, validation, dict(
            parameters=_as_tuple(parameters), known=_as_tuple(known), loss=loss, f_scale=f_scale, tol=tol,
            max_nfev=max_nfev, noise=noise if isinstance(noise, Noise) else Noise.of(noise or DEFAULT_INSTRUMENT),
            on_outliers=on_outliers, weak=weak, nonnegative_compliance=nonnegative_compliance,
            limit=None if limit is None else float(getattr(limit, "limit", limit))),
            initial_base=initial_base, register_validation=register_validation)
    data = cast(Measurements, data)       # checked above: required without contacts
    parameters, known = _as_tuple(parameters), _as_tuple(known)
    noise = noise if isinstance(noise, Noise) else Noise.of(noise or DEFAULT_INSTRUMENT)
    limit_m = None if limit is None else float(getattr(limit, "limit", limit))
    options = _Options(loss=loss, f_scale=f_scale, max_nfev=max_nfev, on_outliers=on_outliers, weak=weak,
                       nonnegative_compliance=nonnegative_compliance, folds=folds)
    notes = list(model.notes) + list(data.extra.get("notes", ()))  # what the readers decided for the user
    data, copies = _without_copies(data)
    start, said = _starting_model(model, data, initial_base)
    analysis = _analyse(start, data, parameters, known + _unmeasured(model, data), tol, noise=noise)
    labels, k, grouping = fold_labels(data, folds)
    fold_problems = FoldProblems(labels, k)
    chosen, choice_notes = _choose(start, analysis, data, noise, limit_m, options, (labels, k, fold_problems))
    design, solution = chosen.design, chosen.solution
    before, before_notes = _registered_nominal(design)
    notes += (list(copies) + list(said) + list(analysis.notes) + list(chosen.notes) + list(choice_notes)
              + list(before_notes))
    cov = covariance(solution)
    estimates = _estimates(design, solution, cov)
    in_use = _in_use(design, chosen, before, validation, (labels, k, grouping, fold_problems),
                     register_validation)
    reach = _reach(start, design, solution.p, workspace_readings(start))
    square = solution.jacobian.shape[0] == solution.jacobian.shape[1] and solution.row_kinds is None
    cover = coverage(design.problem, solution.p, cov.covariance, reach.predicted,
                     factor=solution.jacobian if square else None)
    checks = [readings_check(model, data), reading_units_check(model, data),
              cloud_size_check(model, data, analysis.problem.predicted(design.p0)[0]), markers_check(model, data),
              chosen.outlier_check]
    checks += _result_checks(design, chosen, cov, estimates, noise, limit_m, reach)
    checks += [in_use_check(in_use), coverage_check(cover, in_use)]
    calibrated = model_from_vector(start, solution.p)
    fit = _PoseErrors.of(model, data, design.problem, before, solution.p, design)
    val = None if validation is None else _PoseErrors.of(model_from_vector(start, before), validation, None, None,
                                                         calibrated, design)
    stats = cast(ErrorSummary, fit.summary(val, rotation=False))     # None only for rotations
    judged = None if limit is None else judge_against_limit(limit, in_use)
    if judged is not None:
        checks.append(limit_check(judged))
    _warn(checks)
    return CalibrationResult(
        nominal_model=model, calibrated_model=calibrated, parameters=estimates,
        covariance=cov.covariance, correlation=cov.correlation, identifiability=design.identifiability,
        success=solution.success, status=solution.status, message=solution.message, nfev=solution.nfev,
        sigma0=float(np.sqrt(cov.s2)), families=parameters, loss=solution.loss, notes=tuple(notes),
        limit=judged, checks=tuple(checks), provenance=provenance(data, validation), stats=stats,
        rotation_stats=fit.summary(val, rotation=True), in_use=in_use, coverage=cover,
        **fit.fields("fit"), **(val.fields("validation") if val is not None else {}),
    )


@checked(model=is_a(RobotModel), contacts=is_a(Contacts), data=optional(is_a(Measurements)))
def calibrate_contacts(model: RobotModel, contacts: Contacts, *, data: Measurements | None = None, **options):
    """``calibrate(model, data, contacts=contacts, **options)``, kept under this name: calibrations
    from contacts go through ``calibrate`` and give the same ``CalibrationResult``, with the kit's
    figures in its ``contacts``.

    Parameters
    ----------
    {model, contacts}
    data : Measurements, optional
        Tracker measurements to calibrate on beside the contacts.
    **options
        Any option of ``calibrate``.

    Returns
    -------
    CalibrationResult
        The calibrated model, estimates, checks and verdict; ``contacts`` holds the kit's figures.
    """
    return calibrate(model, data, contacts=contacts, **options)


def _from_contacts(model: RobotModel, data: Measurements | None, contacts: Contacts, validation, options: dict, *,
                   initial_base: str, register_validation: bool) -> CalibrationResult:
    """``calibrate`` with contacts: the contact problem solved and checked (``fit_contacts``), and
    its record made as for measured points, the tracker data's errors in the per-point fields."""
    from .contact_figures import contact_in_use, fit_contacts

    notes = list(model.notes) + ([] if data is None else list(data.extra.get("notes", ())))
    start = model
    if initial_base == "register":
        if data is None:
            raise InputError("contacts alone fix no frame to register the base in; give measured points beside "
                             "them, or leave the base at the model's", where="initial_base")
        start = register_base(model, data)
        notes.append("the base started from a rigid registration of the nominal robot on the measured points")
    points = validation if isinstance(validation, Measurements) else None     # measured points held out
    validation = None if points is not None else validation
    if register_validation and points is None:
        notes.append("held-out contacts are judged by socket consistency and spacing, which do not depend on "
                     "the frame: nothing to register")
    out = fit_contacts(start, contacts, data=data, validation=validation, **options)
    sol, calibrated = out.solution, out.calibrated_model
    fit = None if data is None else _PoseErrors.between(model, calibrated, data, out.compliance)
    checks, in_use = list(out.checks), contact_in_use(out.figures, validation is not None)
    fields = fit.fields("fit") if fit is not None else _PoseErrors.no_poses(model)
    val = None
    if points is not None:
        register = register_validation or data is None
        if register and not register_validation:
            notes.append("contacts alone fix no frame: base and tool registered on the validation points, for the "
                         "models before and after alike")
        in_use, val = _points_in_use(start, calibrated, points, fit, out.compliance, options["noise"], register)
        fields.update(val.fields("validation"))
        checks = [replace(c, name="accuracy in use, placements predicted by the others")
                  if c.name == "accuracy in use" else c for c in checks] + [in_use_check(in_use)]
    if fit is not None:
        stats = cast(ErrorSummary, fit.summary(val, rotation=False))
        rotation_stats = fit.summary(val, rotation=True)
    elif val is not None:
        held = cast(ErrorSummary, val.summary(None, rotation=False))     # its own figures, in the validation's place
        stats = ErrorSummary(held.validation_before, held.validation_after, held.fit_before, held.fit_after)
        rotation_stats = None
    else:
        stats, rotation_stats = _PoseErrors.summary_of_none(), None
    candidates = candidate_parameters(model, options["parameters"], known=options["known"])
    ident = out.figures.identifiability
    robot_view = replace(ident.analysis, candidates=candidates, identified=ident.identified,
                         eliminated=ident.eliminated, rank=len(ident.identified),
                         column_scale={k: v for k, v in ident.analysis.column_scale.items() if k in set(candidates)})
    prov = provenance(data, points)
    for key, c in (("contacts", contacts), ("validation_contacts", validation)):
        if c is not None:
            prov[key] = {"source": c.source, "sha256": c.sha256, "n_rows": c.n_rows,
                         "placements": list(c.placements())}
    return CalibrationResult(
        nominal_model=model, calibrated_model=calibrated, parameters=out.parameters, covariance=out.covariance,
        correlation=out.correlation, identifiability=robot_view, success=sol.success, status=sol.status,
        message=sol.message, nfev=sol.nfev, sigma0=float(np.sqrt(out.s2)), families=options["parameters"],
        loss=sol.loss, notes=tuple(notes), checks=tuple(checks), provenance=prov, stats=stats,
        rotation_stats=rotation_stats, in_use=in_use, contacts=out.figures, **fields)


def _points_in_use(start: RobotModel, calibrated: RobotModel, points: Measurements, fit: _PoseErrors | None,
                   compliance: bool, noise: Noise, register: bool) -> tuple[AccuracyInUse, _PoseErrors]:
    """Measured points held out from a calibration on contacts: the nominal (``start``) and the
    calibrated model on them, base and the measured markers registered on them for both when
    ``register`` (contacts alone fix no frame); the accuracy in use they give and their errors."""
    val = Problem(start, points, (), compliance=compliance, noise=noise)
    vectors = [parameter_vector(start), parameter_vector(calibrated)]
    if register:
        vectors = _registered(val, vectors)
    before, after = evaluated(val, vectors[0]), evaluated(val, vectors[1])
    fit_after = np.empty(0) if fit is None else np.linalg.norm(fit.after, axis=2)[fit.data.mask]
    method = "validation, base and tool registered on it" if register else "validation"
    in_use = accuracy_in_use(method, None, "the validation set", before, after, fit_after,
                             noise=_instrument_variance(noise, points))
    return in_use, _PoseErrors(points, before.positions, after.positions, before.rotations, after.rotations)


def _as_tuple(v) -> tuple:
    return (v,) if isinstance(v, str) else tuple(v)


def _check_inputs(model: RobotModel, data: Measurements | None, validation, *, loss: str, initial_base: str,
                  on_outliers: str, weak: str, folds: int = DEFAULT_FOLDS,
                  options: dict | None = None, contacts=None) -> None:
    """Every argument checked before any work: InputError naming the argument and what is allowed.
    ``options``: the other arguments of ``calibrate`` by name; with ``contacts``, ``data`` may be
    None and ``validation`` is held-out contacts."""
    from .._base.arguments import FLAG, NAMES, POSITIVE, is_a, noise_of, number, optional, whole
    from .._base.options import INSTRUMENT_NOISE

    is_a(RobotModel)(model, "model", None)
    if contacts is None:
        is_a(Measurements)(data, "data", None)
        optional(is_a(Measurements))(validation, "validation", None)
    else:
        is_a(Contacts)(contacts, "contacts", None)
        optional(is_a(Measurements))(data, "data", None)
        optional(is_a(Contacts, Measurements))(validation, "validation", None)
    check_choice(loss, LOSSES, "loss")
    check_choice(initial_base, INITIAL_BASES, "initial_base")
    check_choice(on_outliers, OUTLIER_ACTIONS, "on_outliers")
    check_choice(weak, WEAK_ACTIONS, "weak")
    if isinstance(folds, bool) or not isinstance(folds, (int, np.integer)) or folds < 2:
        raise InputError(f"must be an integer of at least 2, got {folds!r}", where="folds")
    o = options or {}
    for name, rule in (("parameters", NAMES), ("known", NAMES), ("f_scale", optional(POSITIVE)),
                       ("max_nfev", optional(whole(1))), ("noise", noise_of(Noise, INSTRUMENT_NOISE)),
                       ("nonnegative_compliance", FLAG), ("register_validation", FLAG)):
        if name in o:
            rule(o[name], name, o)
    if "tol" in o:
        number(o["tol"], "tol", low=0.0, high=1.0, low_open=True, high_open=True)
    limit = o.get("limit")
    if limit is not None:
        number(getattr(limit, "limit", limit), "limit", low=0.0, low_open=True)
    for what, d in (("data", data), ("validation", validation)):
        if d is None or not isinstance(d, Measurements):      # contacts are checked by their own step
            continue
        src = d.source or what
        if d.q.shape[1] != model.n_joints:
            raise InputError(f"{d.q.shape[1]} joint columns for a model with {model.n_joints} joints "
                             f"({', '.join(model.joint_names)})", source=src, where=what)
        for n in d.marker_names:
            if n not in model.marker_names:
                raise InputError(f"marker {n!r} is not in the model (markers: {', '.join(model.marker_names)})",
                                 source=src, where=what)


def _without_copies(data: Measurements) -> tuple[Measurements, tuple[str, ...]]:
    """``data`` with rows that repeat an earlier row exactly (readings and every measured value)
    counted once: a copy adds no measurement, and counting it would shrink the standard deviations
    as if it did. Repeated readings with their own measurements stay (they average the instrument's
    noise)."""
    if _distinct_rows(data.q) == data.n_poses:
        return data, ()
    rows = np.ascontiguousarray(np.hstack([data.q, np.nan_to_num(data.positions.reshape(data.n_poses, -1), nan=1e300),
                                           data.mask.astype(float)]) + 0.0)
    _, first = np.unique(rows.view(np.dtype((np.void, rows.dtype.itemsize * rows.shape[1]))).ravel(),
                         return_index=True)
    if len(first) == data.n_poses:
        return data, ()
    kept = np.sort(first)
    return data.with_approach().subset(kept), (
        f"{data.n_poses - len(kept)} of {data.n_poses} rows repeat an earlier row exactly (readings and measurements): "
        "counted once",)


def _unmeasured(model: RobotModel, data: Measurements) -> tuple[str, ...]:
    """The parameter names of markers the data never measured: nothing can identify them."""
    seen = {n for j, n in enumerate(data.marker_names) if data.mask[:, j].any()}
    lay = parameter_layout(model)
    return tuple(p.name for p in lay.parameters if p.role == "marker" and p.owner not in seen)


def _starting_model(model: RobotModel, data: Measurements, initial_base: str) -> tuple[RobotModel, tuple[str, ...]]:
    """The model the solve starts from (the user's, or with a registered base), and what it noted."""
    if initial_base != "register":
        return model, ()
    return register_base(model, data), (
        "base pose started from a closed-form registration of the nominal robot on the data",
        "base parameters are reported against the registered base (nominal column), not the model file's")


def _analyse(start: RobotModel, data: Measurements, parameters: tuple, known: tuple, tol: float, *,
             noise: Noise) -> _Analysis:
    """Which candidates the data can identify; refuse data that cannot determine them."""
    orientation = data.has_orientation
    names = candidate_parameters(start, parameters, orientation=orientation, known=known)
    notes = [f"parameters {p!r} matched: {', '.join(m)}" for p, m in matched_by_pattern(start, parameters,
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
    return _Analysis(prob, J, names, ident, lost, compliance, tuple(notes))


def _distinct_rows(q: np.ndarray) -> int:
    """The number of distinct rows of ``q``. Rows with distinct projections on a fixed direction
    are distinct: only when two projections tie are the rows compared, as bytes (+ 0.0 makes -0.0
    and 0.0 alike)."""
    rows = np.ascontiguousarray(q + 0.0)
    h = np.sort(rows @ (1.0 / np.sqrt(np.arange(2.0, rows.shape[1] + 2.0))))
    if np.all(h[1:] != h[:-1]):
        return len(rows)
    return len(np.unique(rows.view(np.dtype((np.void, rows.dtype.itemsize * rows.shape[1]))).ravel()))


def _pin_down(start: RobotModel, analysis: _Analysis, noise: Noise, limit_m: float | None, *, eliminate: bool,
              scatter: float = 0.0, data: Measurements | None = None) -> _Design:
    """The design over what the data can also pin down at the expected noise (or at ``scatter``, m,
    when the fit showed more); with ``eliminate`` False every identifiable parameter stays free
    (the weak ones named). ``data``: the points to fit (default the analysis'), e.g. with some set aside."""
    prob = analysis.problem
    ident, weak_found, judged = _weak(prob, analysis.J, analysis.names, analysis.identifiability, noise, limit_m,
                                      scatter, eliminate=eliminate)
    if not ident.identified:
        raise DegenerateDataError("no parameter is identifiable from these data")
    free = prob.over(ident.identified) if data is None else Problem(start, data, ident.identified,
                                                                    compliance=analysis.compliance, noise=noise)
    if free.n_rows <= len(ident.identified):
        raise DegenerateDataError(f"{free.n_rows} equations for {len(ident.identified)} parameters")
    return _Design(start=start, p0=parameter_vector(start), problem=free, identifiability=ident,
                   compliance=analysis.compliance, lost=analysis.lost, weak=weak_found, weak_kept=not eliminate,
                   judged_at=judged)


def _weak(prob: Problem, J: np.ndarray, names, ident: IdentifiabilityResult, noise: Noise, limit_m,
          scatter: float, *, eliminate: bool):
    """The analysis with weakly identifiable parameters eliminated (or only named), those parameters
    with their predicted standard deviations, and the scatter (m per axis) they were judged at.
    Eliminating one may let an equivalent one in (a member of the same dependent group): the
    analysis repeats until none is weak."""
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
        said += [(n, effect_text(e, lay[by].quantity) + ("" if by == n else f" of {by} with it"))
                 for n, by, e, _ in found]
        if not found or not eliminate:
            return result, tuple(said), expected
        if {n for n, _, _, _ in found} | set(dropped) >= set(ident.identified):
            raise DegenerateDataError(f"no parameter can be pinned down at a scatter of {expected * 1e3:.3g} mm")
        dropped.update({n: "is weakly identifiable: " + (f"predicted std {effect_text(e, lay[n].quantity)} exceeds "
                           if by == n else f"with it, {by}'s predicted std {effect_text(e, lay[by].quantity)} exceeds ")
                        + effect_text(b, lay[by].quantity) for n, by, e, b in found})
        result = eliminate_parameters(ident, J, names, quantities, dropped, n_rows=prob.n_rows)


def _choose(start: RobotModel, analysis: _Analysis, data: Measurements, noise: Noise, limit_m: float | None,
            options: _Options, folds: tuple) -> tuple[_Fit, tuple[str, ...]]:
    """The model choice the accuracy in use supports.

    The first design holds weakly identifiable parameters at nominal (judged at the expected noise:
    the instrument's, and the robot's own with a limit); it is fitted, and measured points that stand
    out are set aside when that helps (``_fit``). Two more designs are then fitted on the same points
    where they differ from it: every identifiable parameter free, and weak parameters judged again at
    the scatter the fit shows when it is well above the expected noise. Of the designs, simplest
    first, the first whose cross-validated loss is within one standard error of the best one's is
    chosen: a stated noise, a limit or stated deviations hold back parameters only where that costs
    nothing in use. With ``weak="flag"`` every identifiable parameter is kept.
    """
    eliminate = options.weak == "eliminate"
    first = _fit(_pin_down(start, analysis, noise, limit_m, eliminate=eliminate), data, noise, options, folds)
    if not eliminate:
        return first, ()
    used = first.data
    expected = expected_noise(noise, limit_m)[0]
    scatter = _scatter(first)
    designs = []
    if scatter > FIT_RATIO * expected:
        with contextlib.suppress(DegenerateDataError):   # nothing pinned down at that scatter: the fit stands
            designs.append(_pin_down(start, analysis, noise, limit_m, eliminate=True, scatter=scatter, data=used))
    designs += [first.design, _pin_down(start, analysis, noise, limit_m, eliminate=False, data=used)]
    # simplest first; a design equal to one before it is the same fit
    fits, seen = [], {}
    for d in designs:
        key = d.identifiability.identified
        if key not in seen:
            seen[key] = first if d is first.design or key == first.design.identifiability.identified else \
                _fit(d, used, noise, replace(options, on_outliers="flag"), folds, outliers=first)
            fits.append(seen[key])
    if len(fits) == 1:
        return first, ()
    mask = _steady(first)
    best = min(fits, key=lambda f: float(f.held_out.loss[mask].mean()))
    for f in fits:
        excess, se = paired_excess(f.held_out.loss, best.held_out.loss, mask)
        if excess <= se:
            break
    names = {id(f): len(f.design.identifiability.identified) for f in fits}
    rms = {id(g): float(np.sqrt(np.nanmean(g.held_out.norms[mask] ** 2))) for g in fits}
    said = "; ".join(f"{names[id(g)]} parameters: {rms[id(g)] * 1e3:.4g} mm" for g in fits)
    note = (f"model choice by cross-validated error (RMS held out): {said}; kept the {names[id(f)]} parameters, "
            "the simplest within one standard error of the best")
    if f.design.weak_kept:
        f = replace(f, design=replace(f.design, kept_in_use=True))
    return f, (note,)


def _steady(fit: _Fit) -> np.ndarray:
    """(n_poses, n_markers) the points a model choice is judged on: fitted, and not standing out."""
    mask = fit.data.mask.copy()
    rows, markers = np.nonzero(fit.data.mask)
    out = fit.outlying if len(fit.outlying) == len(rows) else np.zeros(len(rows), dtype=bool)
    mask[rows[out], markers[out]] = False
    return mask


def _scatter(fit: _Fit) -> float:
    """Per-axis RMS (m) of the fitted position residuals, points set aside or standing out left out."""
    r = fit.design.problem.errors(fit.solution.p)[_steady(fit)]
    return float(np.sqrt(np.mean(r ** 2))) if r.size else 0.0


def _fit(design: _Design, data: Measurements, noise: Noise, options: _Options, folds: tuple, *,
         outliers: _Fit | None = None) -> _Fit:
    """``design`` solved and cross-validated. With the linear loss and ``on_outliers="refit"``,
    measured points that stand out alone (not in runs of consecutive poses, which are systematic)
    are set aside and the design fitted again without them, kept when its cross-validated loss on
    the other points is lower (the model is then the one the rows' deletion gives). ``outliers``: a
    fit whose outlier check and mask stand (a design fitted on the points it left)."""
    solution = _solve(design, options)
    labels, k, subs = folds
    held = cross_validate(design.problem, solution.p, labels, k, folds=subs)
    if outliers is not None:
        return _Fit(design, data, solution, outliers.outlier_check, outliers.outlying, held)
    check, out, gross = _outliers(design.problem, solution, data, noise)
    if not out.any():
        return _Fit(design, data, solution, check, out, held)
    rows, markers = np.nonzero(data.mask)
    runs = _in_runs(rows[out])
    if out.mean() > OUTLIER_SHARE_MAX:
        check = replace(check, status="warn", cause="so many that the data do not fit the model as it is: unmodelled "
                        "effects or a mistake (see the other checks)", fix="read the diagnosis; a robust loss would "
                        "hide the misfit")
        return _Fit(design, data, solution, check, out, held)
    blunder = np.zeros(len(rows), dtype=bool)
    blunder[np.nonzero(out)[0][~runs]] = True
    blunder &= gross
    notes = []
    if runs.any():
        notes.append(f"{int(runs.sum())} point(s) standing out in runs of consecutive poses "
                     f"({_listed_rows(data, rows[out][runs])}): a systematic error, not blunders; kept in the fit")
    if (out & ~gross).any():
        notes.append(f"{int((out & ~gross).sum())} point(s) beyond the outlier bar but within "
                     f"{GROSS_FACTOR:g} times it: the tail of an effect the model leaves out as much as blunders; "
                     "kept in the fit")
    if not blunder.any() or options.loss != "linear" or options.on_outliers != "refit":
        return _Fit(design, data, solution, _outlier_status(check, runs, aside=False), out, held, tuple(notes))
    aside = np.zeros(data.mask.shape, dtype=bool)
    aside[rows[blunder], markers[blunder]] = True
    kept = with_points_aside(data, aside)
    again = replace(design, problem=Problem(design.start, kept, design.identifiability.identified,
                                            compliance=design.compliance, noise=noise))
    solution2 = _solve(again, options)
    # judged on every point, those set aside too (predicted without them): blunders are no better
    # predicted either way, while points whose only fault is an effect the model leaves out are
    # predicted worse once their like are set aside
    held2 = cross_validate(again.problem, solution2.p, labels, k, on=design.problem, folds=subs)
    excess, _ = paired_excess(held2.norms, held.norms, data.mask)
    if excess > 0:
        notes.append(f"{int(blunder.sum())} outlier(s) named; setting them aside did not lower the cross-validated "
                     "error of the other points, so they stay in the fit")
        return _Fit(design, data, solution, _outlier_status(check, runs, aside=False), out, held, tuple(notes))
    notes.append(f"{int(blunder.sum())} outlier(s) set aside and the calibration fitted again without them")
    held2 = HeldOut(np.where(kept.mask[..., None], held2.positions, np.nan),
                    None if held2.rotations is None else np.where(kept.mask[..., None], held2.rotations, np.nan),
                    np.where(kept.mask, held2.loss, 0.0))
    return _Fit(again, kept, solution2, _outlier_status(check, runs, aside=True), out, held2, tuple(notes))


def _in_runs(rows: np.ndarray) -> np.ndarray:
    """For sorted pose indices, whether each lies in a run of at least ``OUTLIER_RUN`` consecutive poses."""
    if not len(rows):
        return np.zeros(0, dtype=bool)
    poses = np.unique(rows)
    start = np.r_[True, np.diff(poses) != 1]
    run_id = np.cumsum(start) - 1
    length = np.bincount(run_id)[run_id]
    long_ = dict(zip(poses, length >= OUTLIER_RUN))
    return np.array([long_[r] for r in rows], dtype=bool)


def _listed_rows(data: Measurements, rows: np.ndarray) -> str:
    poses = np.unique(rows)
    return f"{data.labels[poses[0]]} to {data.labels[poses[-1]]}" if len(poses) > 1 else data.labels[poses[0]]


def _outlier_status(check: Check, runs: np.ndarray, *, aside: bool) -> Check:
    """The outlier check once its points are handled: set aside (named, a warning), kept."""
    said = "; set aside, and the calibration fitted again without them" if aside else "; kept in the fit"
    if runs.all():
        return replace(check, status="warn", summary=check.summary + "; they come in runs of consecutive poses: "
                       "a systematic error (a bump, a payload, a drift), kept in the fit",
                       cause="an effect that changes along the campaign", fix="read the diagnosis")
    return replace(check, status="warn", summary=check.summary + said,
                   fix="check those measurements; the result is the one their deletion gives" if aside else
                   "check those measurements; remove them, or calibrate with --on-outliers refit")


def _solve(design: _Design, options: _Options) -> Solution:
    lower = None
    if options.nonnegative_compliance:
        lay = parameter_layout(design.start)
        lower = np.array([0.0 if lay[n].family == "compliance" else -np.inf for n in design.identifiability.identified])
    return solve(design.problem, design.p0, loss=options.loss, f_scale=options.f_scale, max_nfev=options.max_nfev,
                 lower=lower)


def _outliers(problem: Problem, solution: Solution, data: Measurements, noise: Noise):
    residuals = problem.errors(solution.p)[data.mask]
    labels = _PointLabels(data)
    sigma = None if data.sigma is None else data.sigma[data.mask]
    check, out = outlier_check(residuals, sigma, noise, labels)
    return check, out, out & (outlier_scores(residuals, sigma, noise) > GROSS_FACTOR * outlier_bar(len(out)))


class _PointLabels:
    """The label of each measured point (pose, marker), made only for those a check names."""

    def __init__(self, data: Measurements):
        self.data = data
        self.rows, self.markers = np.nonzero(data.mask)

    def __len__(self) -> int:
        return len(self.rows)

    def __getitem__(self, i: int) -> str:
        return f"{self.data.labels[self.rows[i]]}, marker {self.data.marker_names[self.markers[i]]}"


def _result_checks(design: _Design, fit: _Fit, cov: Covariance, estimates, noise: Noise, limit_m,
                   reach: _Reach) -> list[Check]:
    """The checks of the solution: convergence, fit, plausibility, support, correlation, identifiability."""
    solution, data = fit.solution, fit.data
    residuals = design.problem.errors(solution.p)[data.mask]
    sigma = None if data.sigma is None else data.sigma[data.mask]
    moments = design.problem.compliance_moments(solution.p)
    deflections = {e.name: e.estimate * float(np.max(np.abs(moments[e.name]))) for e in estimates
                   if e.name in moments}
    names = [e.name for e in estimates]
    loose = _loose(estimates, moments)
    out = [convergence_check(solution.success, solution.message, solution.nfev),
           fit_check(residuals, sigma, noise, limit_m, np.zeros(len(residuals), dtype=bool),
                     stated=noise.source.startswith("stated")),
           plausibility_check(estimates, tolerances(design.start), deflections, workspace=reach.judgement,
                              unknown_rotations=_unknown_rotations(design.start)),
           support_check(estimates), compliance_sign_check(estimates), backlash_sign_check(estimates),
           correlation_check(names, cov.correlation, loose),
           identifiability_check(design.lost, design.weak, weak_kept=design.weak_kept,
                                 interchangeable=interchangeable_pairs(names, cov.correlation, loose),
                                 kept_in_use=design.kept_in_use)]
    if data.has_orientation:
        out.insert(2, _orientation_check(design, solution, data))
    return out


def _loose(estimates, moments: dict) -> set:
    """The estimates whose standard deviation exceeds the bound of practical identifiability
    (``WEAK_STD``; a compliance's as a deflection at the RMS moment of the poses)."""
    out = set()
    for e in estimates:
        scale = float(np.sqrt(np.mean(moments[e.name] ** 2))) if e.name in moments else 1.0
        if e.std * scale > WEAK_STD.get(e.quantity, np.inf):
            out.add(e.name)
    return out


def _unknown_rotations(model: RobotModel) -> tuple[str, ...]:
    """The markers whose orientation the model declares unknown: their rotation gets no tolerance."""
    return tuple(m.name for m in model.markers if not m.rotation_known)


def _orientation_check(design: _Design, solution: Solution, data: Measurements) -> Check:
    """A wrong orientation convention converges quietly: test the rotations, with or without stated sigmas."""
    vectors = design.problem.errors(solution.p)
    rot_mask = cast(np.ndarray, data.rot_mask)      # set: called for data with orientations only
    rot = cast(np.ndarray, design.problem.rotation_errors(solution.p))[rot_mask]
    found = misfit_notes(vectors[data.mask], rot,
                         characteristic_length_m=characteristic_length(data.positions[data.mask]),
                         sigma_rot_rad=None if data.sigma_rot is None else data.sigma_rot[rot_mask])
    rms = float(np.degrees(np.sqrt(np.mean(np.sum(rot ** 2, axis=1)))))
    if not found:
        return Check("orientation fit", "pass", f"rotation residuals {rms:.3g} deg RMS")
    return Check("orientation fit", "fail", found[0], cause="a wrong orientation convention or angle unit",
                 fix="declare the convention (--orientation) and the angle unit of the rotation columns")


@dataclass(frozen=True, eq=False)
class _Reach:
    """The calibrated model against the nominal one over the workspace: ``predicted`` (n, n_markers,
    3) the calibrated markers at random configurations within the limits, and the judgement of the
    change (``WorkspaceChange``)."""

    predicted: np.ndarray
    judgement: WorkspaceChange | None


def _reach(start: RobotModel, design: _Design, p: np.ndarray, q: np.ndarray) -> _Reach:
    """The calibrated markers at the workspace's configurations ``q``, and how far the calibrated
    geometry moves them from the nominal one's (``workspace_change``)."""
    data = design.problem.data
    measured = tuple(n for j, n in enumerate(data.marker_names) if data.mask[:, j].any())
    at_q = design_measurements(start, q, markers=data.marker_names)
    predicted = Problem(start, at_q, (), compliance=design.compliance).predicted(p)[0]
    return _Reach(predicted=predicted, judgement=workspace_change(start, p, q, measured,
                                                                  design.identifiability.identified))


def _in_use(design: _Design, fit: _Fit, before: np.ndarray, validation: Measurements | None,
            folds: tuple, register: bool) -> AccuracyInUse:
    """The accuracy in use before and after calibration: on ``validation`` when given (with base and
    markers registered on it for both models when ``register``), else cross-validated on the fitted
    poses (the nominal's registration of base and markers refitted on each fold's complement too)."""
    labels, k, grouping, subs = folds
    problem, p = design.problem, fit.solution.p
    fit_after = problem.error_norms(p)[fit.data.mask]
    noise = _instrument_variance(problem.noise, fit.data)
    if validation is None:
        lay = parameter_layout(design.start)
        placed = tuple(n for n in design.identifiability.identified if lay[n].family in ("base", "markers"))
        only = len(placed) == len(design.identifiability.identified)
        held_before = fit.held_out if only else (
            cross_validate(problem.over(placed), before, labels, k, folds=subs) if placed else
            evaluated(problem, before))
        return accuracy_in_use("cross-validation", k, grouping, held_before, fit.held_out, fit_after,
                               registration_only=only, noise=noise)
    start = design.start
    val = Problem(start, validation, design.identifiability.identified, compliance=design.compliance,
                  noise=problem.noise)
    vectors = [before, p]
    if register:
        vectors = _registered(val, vectors)
    method = "validation, base and tool registered on it" if register else "validation"
    return accuracy_in_use(method, None, "the validation set", evaluated(val, vectors[0]), evaluated(val, vectors[1]),
                           fit_after, noise=_instrument_variance(problem.noise, validation))


def _registered(val: Problem, vectors: list[np.ndarray]) -> list[np.ndarray]:
    """``vectors`` with the base and the markers ``val``'s points measure refitted on them: another
    set-up's frame, the same for every model judged there."""
    lay = parameter_layout(val.model)
    placed = tuple(n for n in lay.names if lay[n].family == "base" or (
        lay[n].role == "marker" and lay[n].owner in val.data.marker_names))
    reg = val.over(placed)
    return [solve(reg, v, tol=REGISTRATION_TOL).p for v in vectors]


def _instrument_variance(noise: Noise | None, data: Measurements) -> tuple[float, float]:
    """The instrument's per-axis variance of positions and rotations: the stated deviations' mean
    square where the data state them, else the expected noise's."""
    pos = noise.position ** 2 if noise is not None else 0.0
    rot = noise.rotation ** 2 if noise is not None else 0.0
    if data.sigma is not None:
        pos = float(np.mean(data.sigma[data.mask] ** 2))
    if data.sigma_rot is not None and data.rot_mask is not None and data.rot_mask.any():
        rot = float(np.mean(data.sigma_rot[data.rot_mask] ** 2))
    return pos, rot


_WARNING_CLASS = {"solver convergence": ConvergenceWarning, "fit against the instrument": MisfitWarning,
                  "orientation fit": MisfitWarning, "identifiability at these poses": IdentifiabilityWarning,
                  "accuracy in use": MisfitWarning}


def _warn(checks) -> None:
    """Every check that did not pass, as a warning users can filter (pointing at the caller's line)."""
    for c in checks:
        if c.status != "pass":
            category = _WARNING_CLASS.get(c.name, CheckWarning)
            warn(f"{c.name} ({'FAILED' if c.status == 'fail' else 'warning'}): {c.summary}", category)


def _registered_nominal(design: _Design) -> tuple[np.ndarray, tuple[str, ...]]:
    """The parameter vector errors "before" are taken at: the nominal geometry, with the base and
    marker parameters being identified fitted to the data first (a raw base guess says nothing
    about the robot), and what that noted. For a fit of the base and markers alone that is the
    calibration itself: the robot's kinematics are unchanged."""
    lay = parameter_layout(design.start)
    free = design.identifiability.identified
    placed = tuple(n for n in free if lay[n].family in ("base", "markers"))
    if not placed:
        return design.p0, ()
    sol = solve(design.problem.over(placed), design.p0, tol=REGISTRATION_TOL)
    if len(placed) == len(free):
        return sol.p, ("only the base and markers are identified: a registration; errors before calibration are "
                       "those of the same registration, the robot's kinematics are unchanged",)
    return sol.p, ("errors before calibration are those of the nominal geometry with its base and markers fitted to "
                   f"the data ({', '.join(placed)})",)


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
        if problem is None:
            return _PoseErrors.between(nominal, after, data, design.compliance)
        # the before vector is in the start's layout (its base registered where the fit moves it)
        vb, rb = problem.errors(p0), problem.rotation_errors(p0)
        return _PoseErrors(data, vb, problem.errors(after), rb, problem.rotation_errors(after))

    @staticmethod
    def between(nominal: RobotModel, calibrated: RobotModel, data: Measurements, compliance: bool) -> _PoseErrors:
        """The nominal and the calibrated model (with compliance, if modelled) evaluated on ``data``."""
        prob_before, p_before = _problem_of(nominal, data, nominal.has_compliance)
        prob_after, p_after = _problem_of(calibrated, data, compliance)
        return _PoseErrors(data, prob_before.errors(p_before), prob_after.errors(p_after),
                           prob_before.rotation_errors(p_before), prob_after.rotation_errors(p_after))

    @staticmethod
    def summary_of_none() -> ErrorSummary:
        """The statistics of a calibration that fitted no measured point (each with n = 0)."""
        return ErrorSummary(*(error_stats([]) for _ in ErrorSummary.KEYS))

    @staticmethod
    def no_poses(model: RobotModel) -> dict:
        """The per-point fields of a calibration that fitted no measured point: arrays of no rows."""
        m = len(model.marker_names)
        return {"errors_before": np.zeros((0, m)), "errors_after": np.zeros((0, m)),
                "residual_vectors": np.zeros((0, m, 3)), "measured_positions": np.zeros((0, m, 3)),
                "readings": np.zeros((0, model.n_joints))}

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


def provenance(data: Measurements | None, validation: Measurements | None = None) -> dict:
    """Software, date and the inputs (source, SHA-256, pose labels in the order of the error rows)."""
    prov: dict[str, object] = {"software": "robocal", "version": __version__,
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
    True when p < ``alpha`` and the RMS error in use (held-out poses, else cross-validated on the
    same folds) fell too: a model choice is checked by what it does in use.
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


def _nested_test(small: CalibrationResult, large: CalibrationResult, data: Measurements | None, validation,
                 alpha: float, what: str):
    """F test of ``large`` against ``small`` nested in it, and the held-out RMS: (F, p, helped, verdict)."""
    from scipy.stats import f as f_dist

    if small.contacts is not None and large.contacts is not None:     # the points and planes are fitted too
        dof1, dof2 = small.contacts.residual_dof, large.contacts.residual_dof
    else:
        data = cast(Measurements, data)
        n_rows = 3 * int(data.mask.sum()) + (3 * int(cast(np.ndarray, data.rot_mask).sum())
                                             if data.has_orientation else 0)
        dof1, dof2 = n_rows - len(small.parameters), n_rows - len(large.parameters)
    ssr1, ssr2 = small.sigma0 ** 2 * dof1, large.sigma0 ** 2 * dof2
    dfn, dfd = max(dof1 - dof2, 1), dof2
    F = max((ssr1 - ssr2) / dfn, 0.0) / (ssr2 / dfd)
    p_value = float(f_dist.sf(F, dfn, dfd))
    # in use: the held-out set's RMS, or the cross-validated one (the same folds for both fits)
    if small.in_use is None or large.in_use is None:    # contacts of one placement: nothing held out
        verdict = (f"{what} not judged in use: no placement held out, the simpler identification is kept; "
                   f"F = {F:.3g}, p = {p_value:.2g}")
        return float(F), p_value, False, verdict
    v1, v2 = cast(float, small.in_use.position_after.rms), cast(float, large.in_use.position_after.rms)
    helped = p_value < alpha and v2 < v1
    kind = "held-out" if validation is not None else "cross-validated"
    if small.contacts is not None:
        kind = "held-out placements' socket consistency" if validation is not None else \
            "socket consistency of each placement predicted by the others,"
    detail = f"{kind} RMS {v1 * 1e3:.4f} mm -> {v2 * 1e3:.4f} mm"
    verdict = (f"{what} helped: {detail}; F = {F:.3g}, p = {p_value:.2g}" if helped else
               f"{what} did not help: {detail}; F = {F:.3g}, p = {p_value:.2g} (threshold {alpha})")
    return float(F), p_value, bool(helped), verdict


@checked(model=is_a(RobotModel), data=optional(both(is_a(Measurements), measured_on())),
         contacts=optional(is_a(Contacts)), validation=optional(is_a(Measurements, Contacts)), alpha=FRACTION,
         backlash=FLAG)
@one_blas_thread
def compare(model: RobotModel, data: Measurements | None = None, *, contacts: Contacts | None = None,
            validation=None, alpha: float = 0.01, backlash: bool = False, **kwargs) -> Comparison:
    """Run geometric and geometric-plus-compliance identifications on the same data (the paper's two),
    and with ``backlash`` a third, geometric + compliance + backlash, tested against the second.

    Keyword arguments other than ``parameters`` go to every ``calibrate`` call.

    Parameters
    ----------
    model : RobotModel
        The nominal robot.
    data : Measurements, optional
        The fitted campaign (may be left out with ``contacts``).
    contacts : Contacts, optional
        Contacts fitted alone or beside ``data``; each calibration is then judged in use by the
        socket consistency of its held-out placements (none with one placement: the simpler kept).
    validation : Measurements or Contacts, optional
        Held-out poses (with ``contacts``: held-out contacts) to judge the calibrations on (None:
        cross-validation, or each placement predicted by the others).
    alpha : float
        Significance level of the F tests, in (0, 1).
    backlash : bool
        Also calibrate with backlash and test it against geometric + compliance.
    **kwargs
        Further arguments of ``calibrate`` (``parameters`` excepted), for every calibration.

    Returns
    -------
    Comparison
        The calibrations, the F statistics, p-values and the verdict on what helped.
    """
    kwargs.pop("parameters", None)
    if data is None and contacts is None:
        raise InputError("give measurements or contacts to compare the identifications on", where="data")
    kwargs["contacts"] = contacts
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
