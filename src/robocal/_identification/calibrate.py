"""``calibrate``: identify a robot's parameters from any observations and judge the result, as one
sequence of steps (``steps``, ``judgement``); ``compare``: identifications nested in one another,
judged in use. The arguments are checked here, once; the steps below never check again."""

from __future__ import annotations

import inspect
from typing import cast, overload

import numpy as np

from .._base.arguments import (
    FLAG,
    FRACTION,
    NAMES,
    POSITIVE,
    accepts,
    both,
    is_a,
    measured_on,
    noise_of,
    number,
    optional,
    whole,
)
from .._base.errors import InputError, check_choice
from .._base.options import DEFAULT_INSTRUMENT, INITIAL_BASES, INSTRUMENT_NOISE, LOSSES, OUTLIER_ACTIONS, WEAK_ACTIONS
from .._base.threads import one_blas_thread
from .._model.contacts import Contacts
from .._model.measurements import Measurements, Noise
from .._model.parameters import transmission_names
from .._model.robot import RobotModel
from .holdout import DEFAULT_FOLDS, FoldProblems, holdout_of
from .identifiability import DEFAULT_TOL
from .judgement import (
    alone_check,
    campaign_coverage,
    estimates,
    fit_checks,
    in_use,
    input_checks,
    placed_better,
    point_misfit,
    reach,
    record,
    result_checks,
    use_checks,
    warn_checks,
)
from .registration import rigid_base
from .result import CalibrationResult, Comparison, NestedTest, compared_name
from .solve import covariance
from .steps import Options, analyse, choose, observed_markers, prepare, registered_nominal


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
    options = dict(parameters=parameters, known=known, loss=loss, f_scale=f_scale, tol=tol, max_nfev=max_nfev,
                   initial_base=initial_base, limit=limit, noise=noise, on_outliers=on_outliers, weak=weak,
                   nonnegative_compliance=nonnegative_compliance, folds=folds, register_validation=register_validation)
    check_inputs(model, data, contacts, validation, options)
    return run(model, data, contacts, validation, _options(options))


def _options(o: dict) -> Options:
    """The options of ``calibrate`` (checked) as the steps take them."""
    noise, limit = o["noise"], o["limit"]
    return Options(parameters=_as_tuple(o["parameters"]), known=_as_tuple(o["known"]),
                   noise=noise if isinstance(noise, Noise) else Noise.of(noise or DEFAULT_INSTRUMENT), tol=o["tol"],
                   loss=o["loss"], f_scale=o["f_scale"], max_nfev=o["max_nfev"], on_outliers=o["on_outliers"],
                   weak=o["weak"], nonnegative_compliance=o["nonnegative_compliance"], folds=o["folds"],
                   limit_m=None if limit is None else float(getattr(limit, "limit", limit)),
                   initial_base=o["initial_base"], register_validation=o["register_validation"])


def run(model: RobotModel, data: Measurements | None, contacts: Contacts | None, validation,
        options: Options) -> CalibrationResult:
    """The steps of a calibration, in order, for every kind of observation (arguments checked)."""
    inputs = prepare(model, data, contacts, validation, options, rigid_base)
    analysis = analyse(inputs, options)
    holdout = holdout_of(analysis.problem, options.folds)
    folds = FoldProblems(holdout)
    chosen, choice_notes = choose(analysis, options, holdout, folds)
    before, before_notes = registered_nominal(chosen.design)
    cov = covariance(chosen.solution)
    found = estimates(chosen.design, chosen.solution.p, cov)
    in_use_record, validation_errors, use_notes = in_use(chosen, before, inputs, holdout, folds, options)
    notes = inputs.notes + analysis.notes + chosen.notes + choice_notes + before_notes + use_notes
    where = reach(inputs, chosen.design, chosen.solution.p)
    cover = campaign_coverage(chosen, cov, where)
    use, limit = use_checks(in_use_record, cover, options, point_misfit(chosen, options), where)
    better = placed_better(in_use_record, where, chosen.problem, inputs.validation)
    checks = (input_checks(inputs, analysis) + list(chosen.outliers.checks)
              + fit_checks(chosen, options, in_use_record, better)
              + result_checks(chosen, cov, found, where, better, observed_markers(inputs.data, inputs.contacts))
              + alone_check(chosen) + use)
    warn_checks(checks)
    judged = (checks, in_use_record, validation_errors, cover, limit)
    return record(inputs, analysis, chosen, before, cov, found, judged, options, notes)


def _as_tuple(v) -> tuple:
    return (v,) if isinstance(v, str) else tuple(v)


def check_inputs(model: RobotModel, data: Measurements | None, contacts: Contacts | None, validation,
                 options: dict) -> None:
    """Every argument of ``calibrate`` checked before any work: InputError naming the argument and
    what is allowed."""
    is_a(RobotModel)(model, "model", None)
    if contacts is None:
        is_a(Measurements)(data, "data", None)
        optional(is_a(Measurements))(validation, "validation", None)
    else:
        is_a(Contacts)(contacts, "contacts", None)
        optional(is_a(Measurements))(data, "data", None)
        optional(is_a(Contacts, Measurements))(validation, "validation", None)
    _check_options(options)
    for what, d in (("data", data), ("validation", validation), ("contacts", contacts)):
        if d is not None:
            _check_observed(model, d, what)


def _check_options(o: dict) -> None:
    check_choice(o["loss"], LOSSES, "loss")
    check_choice(o["initial_base"], INITIAL_BASES, "initial_base")
    check_choice(o["on_outliers"], OUTLIER_ACTIONS, "on_outliers")
    check_choice(o["weak"], WEAK_ACTIONS, "weak")
    folds = o["folds"]
    if isinstance(folds, bool) or not isinstance(folds, (int, np.integer)) or folds < 2:
        raise InputError(f"must be an integer of at least 2, got {folds!r}", where="folds")
    for name, rule in (("parameters", NAMES), ("known", NAMES), ("f_scale", optional(POSITIVE)),
                       ("max_nfev", optional(whole(1))), ("noise", noise_of(Noise, INSTRUMENT_NOISE)),
                       ("nonnegative_compliance", FLAG), ("register_validation", FLAG)):
        rule(o[name], name, o)
    number(o["tol"], "tol", low=0.0, high=1.0, low_open=True, high_open=True)
    if o["limit"] is not None:
        number(getattr(o["limit"], "limit", o["limit"]), "limit", low=0.0, low_open=True)


def _check_observed(model: RobotModel, d, what: str) -> None:
    """Observations of this model: as many joint columns as it has joints, its markers only."""
    src = d.source or what
    if d.q.shape[1] != model.n_joints:
        raise InputError(f"{d.q.shape[1]} joint columns for a model with {model.n_joints} joints "
                         f"({', '.join(model.joint_names)})", source=src, where=what)
    markers = d.marker_names if isinstance(d, Measurements) else tuple(dict.fromkeys(d.marker))
    for n in markers:
        if n not in model.marker_names:
            raise InputError(f"marker {n!r} is not in the model (markers: {', '.join(model.marker_names)})",
                             source=src, where=what)


@accepts(model=is_a(RobotModel), data=both(is_a(Measurements), measured_on()))
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
    return rigid_base(model, data)


def _nested_test(small: CalibrationResult, large: CalibrationResult, validation, alpha: float,
                 what: str) -> NestedTest:
    """F test of ``large`` against ``small`` nested in it, and the held-out RMS."""
    from scipy.special import fdtrc  # the F distribution's survival function (scipy.stats takes 1.8 s to import)

    dof1, dof2 = small.solver.residual_dof, large.solver.residual_dof
    ssr1, ssr2 = small.solver.sigma0 ** 2 * dof1, large.solver.sigma0 ** 2 * dof2
    dfn, dfd = max(dof1 - dof2, 1), dof2
    F = max((ssr1 - ssr2) / dfn, 0.0) / (ssr2 / dfd)
    p_value = float(fdtrc(dfn, dfd, F))
    # in use: the held-out set's RMS, or the cross-validated one (the same folds for both fits)
    if small.in_use is None or large.in_use is None:    # contacts of one placement: nothing held out
        verdict = (f"{what} not judged in use: no placement held out, the simpler identification is kept; "
                   f"F = {F:.3g}, p = {p_value:.2g}")
        return NestedTest(float(F), p_value, False, verdict)
    v1, v2 = cast(float, small.in_use.position_after.rms), cast(float, large.in_use.position_after.rms)
    helped = p_value < alpha and v2 < v1
    kind = "held-out" if validation is not None else "cross-validated"
    if small.contacts is not None:
        kind = "held-out placements' socket consistency" if validation is not None else \
            "socket consistency of each placement predicted by the others,"
    detail = f"{kind} RMS {v1 * 1e3:.4f} mm -> {v2 * 1e3:.4f} mm"
    verdict = (f"{what} helped: {detail}; F = {F:.3g}, p = {p_value:.2g}" if helped else
               f"{what} did not help: {detail}; F = {F:.3g}, p = {p_value:.2g} (threshold {alpha})")
    return NestedTest(float(F), p_value, bool(helped), verdict)


@accepts(model=is_a(RobotModel), data=optional(both(is_a(Measurements), measured_on())),
         contacts=optional(is_a(Contacts)), validation=optional(is_a(Measurements, Contacts)), alpha=FRACTION,
         backlash=FLAG, transmission=FLAG)
@one_blas_thread
def compare(model: RobotModel, data: Measurements | None = None, *, contacts: Contacts | None = None,
            validation=None, alpha: float = 0.01, backlash: bool = False, transmission: bool = True,
            **kwargs) -> Comparison:
    """Run geometric and geometric-plus-compliance identifications on the same data (the paper's two),
    with ``backlash`` a third (geometric, compliance and backlash, tested against the second), and
    with ``transmission`` the transmission terms added to each of these, the terms kept chosen by
    the error in use. A model without link masses skips what needs them and says so (``skipped``).

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
    transmission : bool
        Also calibrate with transmission terms (``TRANSMISSION_LEVELS``) added to each
        identification so far, test them against it, and keep the best in use of those that helped.
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
    # calibrate's options, with its defaults, checked once for the calibrations that share them
    given = inspect.signature(calibrate).bind(model, data, contacts=contacts, validation=validation, **kwargs)
    given.apply_defaults()
    options = {k: v for k, v in given.arguments.items() if k not in ("model", "data", "contacts", "validation")}
    check_inputs(model, data, contacts, validation, options)

    def fit(*families: str) -> CalibrationResult:
        return run(model, data, contacts, validation, _options({**options, "parameters": families}))

    found: dict = {"geometric": fit("geometric"), "skipped": []}
    _compare_compliance(model, fit, found, validation, alpha)
    if backlash:
        _compare_backlash(model, fit, found, validation, alpha)
    if transmission:
        _compare_transmission(model, fit, found, validation, alpha)
    return Comparison(skipped=tuple(found.pop("skipped")), **found)


NO_MASSES = "the model has no link masses (--assume-masses assumes them from the geometry)"


def _compare_compliance(model: RobotModel, fit, found: dict, validation, alpha: float) -> None:
    """Geometric and compliance against geometric, when the model has masses."""
    if not model.has_masses:
        found["skipped"].append(f"compliance not compared: {NO_MASSES}")
        return
    found["combined"] = fit("geometric", "compliance")
    found["compliance_test"] = _nested_test(found["geometric"], found["combined"], validation, alpha, "compliance")


def _compare_backlash(model: RobotModel, fit, found: dict, validation, alpha: float) -> None:
    """Backlash added to geometric and compliance (to geometric alone without masses, when the
    approach-sided model needs none)."""
    if not model.has_masses and model.backlash_side == "gravity":
        found["skipped"].append(f"backlash not compared: its gravity-sided model needs masses and {NO_MASSES}")
        return
    small = found.get("combined", found["geometric"])
    found["backlash"] = fit(*small.families, "backlash")
    found["backlash_test"] = _nested_test(small, found["backlash"], validation, alpha, "backlash")


# the transmission terms the comparison offers, each level adding to the one before: the gears'
# scales (one term a joint), the first harmonic of the joint angle, the second, the motor's (where a
# ratio is stated)
TRANSMISSION_LEVELS = (("gear scale", ("gear_scale",)), ("first harmonic", ("gear_cos1", "gear_sin1")),
                       ("second harmonic", ("gear_cos2", "gear_sin2")),
                       ("motor harmonics", ("motor_cos1", "motor_sin1", "motor_cos2", "motor_sin2")))


def _compare_transmission(model: RobotModel, fit, found: dict, validation, alpha: float) -> None:
    """Transmission terms added, level after level, to each identification so far (a gear's error
    may show only beside the compliance that takes the rest); kept: the one with the smallest error
    in use among those that helped against what they add to and do better in use than the best so
    far (else the one that did best in use, not kept)."""
    bases = [r for r in (found["geometric"], found.get("combined"), found.get("backlash")) if r is not None]
    best_rms = _in_use_rms(Comparison(skipped=(), **{k: v for k, v in found.items() if k != "skipped"}).best)
    names = transmission_names(model)
    tried = [t for small in bases for t in _transmission_levels(small, names, fit, validation, alpha)]
    if not tried:
        found["skipped"].append("transmission not compared: no joint can carry a transmission term")
        return
    helped = [t for t in tried if t[2].helped and _in_use_rms(t[1]) < best_rms]
    _, large, test = min(helped or tried, key=lambda t: _in_use_rms(t[1]))
    if not helped and test.helped:
        test = NestedTest(test.f_statistic, test.p_value, False,
                          test.summary + f"; not kept: the best so far does better in use ({best_rms * 1e3:.4f} mm)")
    others = "".join(f"; {w}: RMS in use {_in_use_rms(r) * 1e3:.4f} mm" for w, r, _ in tried if r is not large)
    found["transmission"] = large
    found["transmission_test"] = NestedTest(test.f_statistic, test.p_value, bool(helped), test.summary + others)


def _transmission_levels(small: CalibrationResult, names, fit, validation, alpha: float) -> list:
    """(what, result, test) of each level of transmission terms added to ``small``."""
    tried = []
    kinds: tuple = ()
    done: tuple = ()
    for label, level in TRANSMISSION_LEVELS:
        kinds += level
        terms = tuple(n for n in names if n.rsplit(".", 1)[1] in kinds)
        if terms == done:
            continue                    # nothing new at this level (no stated ratio)
        done = terms
        large = fit(*small.families, *terms)
        what = f"transmission (up to the {label}, on {compared_name(small.families)})"
        tried.append((what, large, _nested_test(small, large, validation, alpha, what)))
    return tried


def _in_use_rms(r: CalibrationResult) -> float:
    return np.inf if r.in_use is None else cast(float, r.in_use.position_after.rms)
