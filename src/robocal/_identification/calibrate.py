"""The identification of a calibration as one sequence of steps (``run``: ``steps``, ``judgement``) for
every kind of observation, the check of ``calibrate``'s arguments (once: the steps below never check
again) and the F test of identifications nested in one another. The public ``calibrate`` and
``compare`` run it and then the diagnosis, one layer up (``robocal._diagnosis.calibrate``)."""

from __future__ import annotations

from typing import cast

import numpy as np

from .._base.arguments import (
    FLAG,
    NAMES,
    POSITIVE,
    accepts,
    both,
    is_a,
    measured_on,
    noise_of,
    number,
    optional,
    unobserved,
    whole,
)
from .._base.errors import InputError, check_choice
from .._base.options import DEFAULT_INSTRUMENT, INITIAL_BASES, INSTRUMENT_NOISE, LOSSES, OUTLIER_ACTIONS, WEAK_ACTIONS
from .._model.contacts import Contacts
from .._model.measurements import Measurements, Noise
from .._model.robot import RobotModel
from .checks import error_where_used
from .holdout import FoldProblems, holdout_of
from .judgement import (
    alone_check,
    campaign_coverage,
    cross_validated,
    estimates,
    fit_checks,
    fit_errors,
    held_out_nominal,
    in_use,
    input_checks,
    noise_cost,
    placed_better,
    point_misfit,
    reach,
    record,
    result_checks,
    use_checks,
    warn_checks,
)
from .registration import rigid_base
from .result import CalibrationResult, NestedTest
from .solve import covariance
from .steps import Fit, Options, analyse, choose, observed_markers, prepare, registered_nominal


def options_of(o: dict) -> Options:
    """The options of ``calibrate`` (checked) as the steps take them."""
    noise, limit = o["noise"], o["limit"]
    return Options(parameters=_as_tuple(o["parameters"]), known=_as_tuple(o["known"]),
                   noise=noise if isinstance(noise, Noise) else Noise.of(noise or DEFAULT_INSTRUMENT), tol=o["tol"],
                   loss=o["loss"], f_scale=o["f_scale"], max_nfev=o["max_nfev"], on_outliers=o["on_outliers"],
                   weak=o["weak"], nonnegative_compliance=o["nonnegative_compliance"], folds=o["folds"],
                   limit_m=None if limit is None else float(getattr(limit, "limit", limit)),
                   initial_base=o["initial_base"], register_validation=o["register_validation"])


def run(model: RobotModel, data: Measurements | None, contacts: Contacts | None, validation,
        options: Options) -> tuple[CalibrationResult, Fit]:
    """The steps of a calibration, in order, for every kind of observation (arguments checked): its
    record, and the fit chosen (its problem and solution, which the diagnosis takes up)."""
    inputs = prepare(model, data, contacts, validation, options, rigid_base)
    analysis = analyse(inputs, options)
    checked = input_checks(inputs, analysis)      # at the start, while its evaluation is at hand
    holdout = holdout_of(analysis.problem, options.folds)
    folds = FoldProblems(holdout)
    chosen, choice_notes = choose(analysis, options, holdout, folds)
    before, before_at, before_notes = registered_nominal(chosen.design)
    cov = covariance(chosen.solution)
    found = estimates(chosen.design, chosen.solution.p, cov)
    held_before = held_out_nominal(chosen, before, holdout, folds, before_at) if cross_validated(inputs, holdout) \
        else None
    in_use_record, validation_errors, use_notes = in_use(chosen, before, inputs, holdout, options, held_before)
    notes = inputs.notes + analysis.notes + chosen.notes + choice_notes + before_notes + use_notes
    where = reach(inputs, chosen.design, chosen.solution.p)
    cover = campaign_coverage(chosen, cov, where)
    fitted = fit_errors(inputs, chosen, before)
    use, limit = use_checks(in_use_record, cover, options, point_misfit(chosen, options), where, validation_errors,
                            fitted, noise_cost(chosen, in_use_record, holdout))
    better = placed_better(in_use_record, where, chosen.problem, inputs.validation)
    checks = (checked + list(chosen.outliers.checks)
              + fit_checks(chosen, options, in_use_record, better)
              + result_checks(chosen, cov, found, where, better, observed_markers(inputs.data, inputs.contacts),
                              unreachable=() if analysis.reach is None else analysis.reach.unreachable)
              + alone_check(chosen) + use)
    warn_checks(checks)
    judged = (checks, in_use_record, validation_errors, cover, limit, fitted)
    return record(inputs, analysis, chosen, before, cov, found, judged, options, notes, held_before), chosen


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
    """Observations of this model: at least one, as many joint columns as it has joints, its markers only."""
    src = d.source or what
    if (lack := unobserved(d)) is not None:
        raise InputError(f"holds no {lack}: nothing to {'judge the calibration on' if what == 'validation' else 'fit'}",
                         source=src, where=what)
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


def nested_test(small: CalibrationResult, large: CalibrationResult, validation, alpha: float,
                 what: str) -> NestedTest:
    """F test of ``large`` against ``small`` nested in it, and the accuracy in use: the held-out RMS,
    and over the range of use (``error_where_used``, the check "where the model holds"). The larger
    helps when the test says so and it places the robot better in both: one better where measured
    but worse where the robot is used (terms that extrapolate badly) is not kept."""
    from scipy.special import fdtrc  # the F distribution's survival function (scipy.stats takes 1.8 s to import)

    dof1, dof2 = small.solver.residual_dof, large.solver.residual_dof
    ssr1, ssr2 = small.solver.sigma0 ** 2 * dof1, large.solver.sigma0 ** 2 * dof2
    dfn, dfd = max(dof1 - dof2, 1), dof2
    F = max((ssr1 - ssr2) / dfn, 0.0) / (ssr2 / dfd)
    p_value = float(fdtrc(dfn, dfd, F))
    tested = f"F = {F:.3g}, p = {p_value:.2g}"
    nested = _not_nested(small, large)
    # in use: the held-out set's RMS, or the cross-validated one (the same folds for both fits)
    if small.in_use is None or large.in_use is None:    # contacts of one placement: nothing held out
        verdict = f"{what} not judged in use: no placement held out, the simpler identification is kept; {tested}"
        return NestedTest(float(F), p_value, False, verdict + nested)
    v1, v2 = cast(float, small.in_use.position_after.rms), cast(float, large.in_use.position_after.rms)
    w1, w2 = error_where_used(small.coverage, v1), error_where_used(large.coverage, v2)
    helped = p_value < alpha and v2 < v1 and w2 <= w1
    kind = "held-out" if validation is not None else "cross-validated"
    if small.contacts is not None:
        kind = "held-out placements' socket consistency" if validation is not None else \
            "socket consistency of each placement predicted by the others,"
    detail = f"{kind} RMS {v1 * 1e3:.4f} mm -> {v2 * 1e3:.4f} mm"
    if small.coverage is not None and large.coverage is not None:
        worse = p_value < alpha and v2 < v1 and not helped
        detail += (f"{', but' if worse else ','} over the range of use about {w1 * 1e3:.4f} mm -> {w2 * 1e3:.4f} mm"
                   + (" (where the model holds: the parameters' uncertainty carried to the configurations of use)"
                      if worse else ""))
    verdict = (f"{what} helped: {detail}; {tested}" if helped else
               f"{what} did not help: {detail}; {tested} (threshold {alpha})")
    return NestedTest(float(F), p_value, bool(helped), verdict + nested)


def _not_nested(small: CalibrationResult, large: CalibrationResult) -> str:
    """What the smaller identification frees and the larger holds, said beside the F test (which
    then compares fits that are not nested); "" when the larger holds none."""
    held = [n for n in small.parameter_names if n not in set(large.parameter_names)]
    if not held:
        return ""
    return (f"; not nested: the larger holds {', '.join(held)} at nominal, which the smaller identifies (the F "
            "test compares fits that are not nested)")
