"""The last steps of a calibration, for every kind of observation: the accuracy in use, what the
calibrated geometry does over the workspace and where the campaign holds, the checks and the
verdict, the warnings, and the record (``CalibrationResult``)."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import cast

import numpy as np

from .._base.arrays import vector_norms
from .._base.errors import CheckWarning, ConvergenceWarning, IdentifiabilityWarning, MisfitWarning, warn
from .._model.configurations import design_measurements
from .._model.measurements import Measurements, Noise
from .._model.parameters import model_from_vector, parameter_layout, parameter_vector
from .._model.robot import RobotModel
from .checks import (
    OVERFIT_RATIO,
    Check,
    WorkspaceChange,
    backlash_sign_check,
    better_in_use,
    cloud_size_check,
    compliance_sign_check,
    convergence_check,
    correlation_check,
    coverage_check,
    fit_check,
    held_out_outlier_check,
    identifiability_check,
    in_use_check,
    interchangeable_pairs,
    limit_check,
    markers_apart_check,
    markers_check,
    plausibility_check,
    reading_units_check,
    readings_check,
    spacing_check,
    support_check,
    tolerances,
)
from .contact_blocks import CARRIES, ContactRows
from .contact_figures import ContactFigures, figures, recordings
from .estimates import ParameterEstimate, workspace_change
from .holdout import (
    REGISTERED_ON_IT,
    AccuracyInUse,
    Coverage,
    FoldProblems,
    HeldOut,
    Holdout,
    JointOffset,
    accuracy_in_use,
    contact_held_out,
    coverage,
    cross_validate,
    design_like,
    evaluated,
    use_stats,
    workspace_readings,
)
from .identifiability import WEAK_STD
from .misfit import characteristic_length, misfit_notes
from .points import Points
from .problem import Labels, Problem
from .result import (
    CalibrationResult,
    ErrorSummary,
    PoseErrors,
    PoseSet,
    SolverRecord,
    calibrated_description,
    calibration_record,
    judge_against_limit,
    provenance,
)
from .solve import Covariance
from .steps import (
    Analysis,
    Design,
    Fit,
    Inputs,
    Options,
    alone_observations,
    observed_markers,
    placed_parameters,
    registered,
    registration_freedom,
    rehomed_on,
    repeated_in,
)

# the kinds whose held-out errors are positions of the robot: what the accuracy in use is made of
POSITION_KINDS = ("tracker", "socket")


def estimates(design: Design, p: np.ndarray, cov: Covariance) -> tuple[ParameterEstimate, ...]:
    """Each identified parameter against the start of the solve: the user's model, or with
    registration the registered base (rotation corrections are small angles about it)."""
    lay = parameter_layout(design.start)
    idx = design.problem.robot_idx
    return tuple(ParameterEstimate(n, lay[n].unit, float(design.p0[idx[k]]), float(p[idx[k]]),
                                   float(cov.std[k]), family=lay[n].family, quantity=lay[n].quantity)
                 for k, n in enumerate(design.identifiability.identified))


def instrument_variance(noise: Noise | None, data: Measurements, fitted: np.ndarray | None = None
                        ) -> tuple[float, float]:
    """The instrument's per-axis variance of positions and rotations, what the accuracy in use takes
    out: the stated deviations' mean square where the data state them, else the instrument's share
    of the expected noise (a stated noise may hold the robot's repeatability, which is part of its
    error in use: only the instrument class's own noise is taken out of it), and never more than the
    fitted points' own scatter per axis (``fitted``: their residual vectors, n x 3): the data cannot
    hold more instrument noise than they scatter."""
    pos, rot = (0.0, 0.0) if noise is None else tuple(v * v for v in noise.instrument_share())
    if data.sigma is not None:
        pos = float(np.mean(data.sigma[data.mask] ** 2))
    if data.sigma_rot is not None and data.rot_mask is not None and data.rot_mask.any():
        rot = float(np.mean(data.sigma_rot[data.rot_mask] ** 2))
    if fitted is not None and fitted.size:
        pos = min(pos, float(np.mean(fitted ** 2)))
    return pos, rot


def _seatings(problem: Problem) -> np.ndarray | None:
    """The contact observations whose errors are positions of the robot (``POSITION_KINDS``)."""
    if problem.contacts is None:
        return None
    return np.array([k in POSITION_KINDS for k in problem.contacts.obs_kind], dtype=bool)


def _spacings(kinds) -> np.ndarray:
    """The contact observations that are known distances (their held-out errors: the scale in use)."""
    return np.array([k == "distance" for k in kinds], dtype=bool)


def _fitted_seatings(problem: Problem, p: np.ndarray) -> np.ndarray | None:
    """The fitted seatings' distances from their socket's mean centre (m), or None without contacts."""
    if problem.contacts is None:
        return None
    e = problem.contacts.own_errors(p[:problem.n_robot])
    keep = _seatings(problem) & ~problem.contacts.aside
    return np.linalg.norm(e[keep], axis=1)


def held_out_nominal(fit: Fit, before: np.ndarray, holdout: Holdout, folds: FoldProblems,
                     before_at: np.ndarray | None = None) -> HeldOut:
    """The nominal model's errors at each observation predicted by the other groups: its registration
    of base and markers refitted there (``cross_validate``; its fold steps from ``before_at``, where
    the registration's solve took its last Jacobian, as the fit's are), the fit's own held-out errors
    when the fit identified nothing else. The "before" of every cross-validated figure."""
    design, problem = fit.design, fit.problem
    placed = placed_parameters(design)
    if len(placed) == len(design.identifiability.identified):
        return fit.held_out
    return cross_validate(problem.over(placed), before, holdout, folds=folds, at=before_at) if placed \
        else _everywhere(problem, before)


def cross_validated(inputs: Inputs, holdout: Holdout) -> bool:
    """Whether the calibration is judged by its own groups predicted by the others: two groups or more,
    and no held-out set that judges it instead (contacts keep their placements' figures beside held-out
    measured points)."""
    return holdout.k > 0 and inputs.validation_contacts is None and (inputs.validation is None
                                                                       or inputs.contacts is not None)


def in_use(fit: Fit, before: np.ndarray, inputs: Inputs, holdout: Holdout, options: Options,
           held_before: HeldOut | None = None) -> tuple[AccuracyInUse | None, PoseErrors | None, tuple[str, ...]]:
    """The accuracy in use before and after calibration, and the errors on held-out measured points:
    on the validation set when given (base and markers registered on it for both models when asked,
    or when nothing fitted fixes a frame), else each observation predicted by the fit on the other
    groups, against ``held_before`` (``held_out_nominal``; None: nothing cross-validated)."""
    design, problem, p = fit.design, fit.problem, fit.solution.p
    if inputs.validation is not None:
        return _validation_points(fit, before, inputs.validation, options, inputs.model)
    if inputs.validation_contacts is not None:
        return _validation_contacts(fit, before, inputs.validation_contacts), None, ()
    if held_before is None:
        return None, None, ()
    only = len(placed_parameters(design)) == len(design.identifiability.identified)
    pts = problem.points
    fitted = np.zeros((0, 3)) if pts is None else problem.observation_errors(p)["tracker"][0]   # kept by the fit
    noise = (0.0, 0.0) if pts is None else instrument_variance(problem.noise, pts.data, fitted)
    record = accuracy_in_use("cross-validation", holdout.k, holdout.description, held_before, fit.held_out,
                             vector_norms(fitted), registration_only=only, noise=noise, seatings=_seatings(problem),
                             fit_seatings=_fitted_seatings(problem, p),
                             spacings=None if problem.contacts is None else _spacings(problem.contacts.obs_kind))
    return (record if record.position_after.n else None), None, ()


def _everywhere(problem: Problem, p: np.ndarray) -> HeldOut:
    """The errors of ``p`` at every observation (none fitted with it)."""
    held = evaluated(problem.points, p[:problem.n_robot]) if problem.points is not None else \
        HeldOut(np.zeros((0, 0, 3)), None, np.zeros((0, 0)))
    if problem.contacts is None:
        return held
    e, loss = contact_held_out(problem.contacts, p[:problem.n_robot])
    return HeldOut(held.positions, held.rotations, held.loss, e, loss)


def _validation_points(fit: Fit, before: np.ndarray, points: Measurements, options: Options, model: RobotModel):
    """Measured points held out: the nominal and the calibrated model on them, base and the measured
    markers registered on them for both when asked or when the fit fixed no frame (contacts alone),
    else also the nominal ``model`` as given (nothing registered)."""
    design, problem = fit.design, fit.problem
    n = problem.n_robot
    val = Problem(design.start, design.identifiability.identified, data=points, compliance=design.compliance,
                  noise=problem.noise)
    vectors = [before[:n], fit.solution.p[:n]]
    register = options.register_validation or problem.points is None
    other, taken, rows = None, 0, 0
    if register:
        vectors = registered(val, vectors)
    else:       # what registering would give: another set-up is told from overfitting by it
        taken, rows = registration_freedom(val)
        if taken < rows:
            other = registered(val, vectors[1:])[0]
    pts = cast(Points, val.points)
    b, a = evaluated(pts, vectors[0]), evaluated(pts, vectors[1])
    method = REGISTERED_ON_IT if register else "validation"
    fitted = None if problem.points is None else problem.observation_errors(fit.solution.p)["tracker"][0]
    record = accuracy_in_use(method, None, "the validation set", b, a,
                             np.empty(0) if fitted is None else vector_norms(fitted),
                             noise=instrument_variance(problem.noise, points, fitted))
    k = fit.problem.n_points
    held = fit.held_out.observation_norms(fit.problem.point_mask)[:k][fit.steady()[:k]]
    # the registration takes up ``taken`` of the ``rows`` equations: its errors scaled back up as a fit's
    # residuals are for its parameters, so that a few poses do not look explained by its own freedom
    record = replace(record, registered_after=None if other is None else use_stats(
        evaluated(pts, other).norms * np.sqrt(rows / (rows - taken))), cross_validated=use_stats(held),
        rehomed=_rehomed(val, vectors[1], record, taken, rows) if other is not None else None)
    said = () if options.register_validation or not register else (
        "nothing fitted fixes a frame (contacts alone): base and tool registered on the validation points, for "
        "the models before and after alike",)
    raw = None if register else parameter_vector(model)
    return record, PoseErrors(points, b.positions, a.positions, b.rotations, a.rotations,
                              nominal=None if raw is None else pts.errors(raw),
                              rotation_nominal=None if raw is None else pts.rotation_errors(raw)), said


def _rehomed(val: Problem, p: np.ndarray, record: AccuracyInUse, taken: int, rows: int) -> JointOffset | None:
    """With validation errors ``OVERFIT_RATIO`` times the fitted ones or more (as measured), the joint
    whose readings off by a constant there explain them best (``rehomed_on``), its errors scaled as
    the registration's with one more equation taken up; else None (nothing to explain)."""
    fit, seen = record.measured_fit or record.fit_after, record.measured_after or record.position_after
    if not (fit.n and seen.n) or cast(float, seen.mean) <= OVERFIT_RATIO * cast(float, fit.mean) or taken + 1 >= rows:
        return None
    found = rehomed_on(val, p)
    if found is None:
        return None
    name, offset, quantity, moved = found
    errors = evaluated(cast(Points, val.points), moved).norms * np.sqrt(rows / (rows - taken - 1))
    return JointOffset(name, offset, quantity, use_stats(errors))


def _validation_contacts(fit: Fit, before: np.ndarray, contacts) -> AccuracyInUse:
    """Contacts held out: each observation with its own unknowns from its own rows, for the nominal
    and the calibrated model (their figures do not depend on the frame)."""
    design, problem = fit.design, fit.problem
    n = problem.n_robot
    rows = ContactRows.of(design.start, contacts, design.identifiability.identified, compliance=design.compliance)
    b, a = (HeldOut(np.zeros((0, 0, 3)), None, np.zeros((0, 0)), *contact_held_out(rows, v[:n]))
            for v in (before, fit.solution.p))
    seatings = np.array([k in POSITION_KINDS for k in rows.obs_kind], dtype=bool)
    return accuracy_in_use("held-out placements", None, "the held-out placements", b, a, np.empty(0), seatings=seatings,
                           fit_seatings=_fitted_seatings(problem, fit.solution.p), spacings=_spacings(rows.obs_kind))


@dataclass(frozen=True, eq=False)
class Reach:
    """The calibrated model against the nominal one over the workspace: ``predicted`` (n, n_markers,
    3) the calibrated measured markers at random configurations within the limits (None without
    measured points), the judgement of the change (``WorkspaceChange``), and the problem at those
    configurations over the fit's parameters (``design_like``; None unless measured points alone,
    without lost motion), which the coverage carries the parameters' uncertainty to."""

    predicted: np.ndarray | None
    judgement: WorkspaceChange | None
    at: Points | None = None


def reach(inputs: Inputs, design: Design, p: np.ndarray) -> Reach:
    """The calibrated markers at the workspace's configurations, and how far the calibrated geometry
    moves the observed markers from the nominal one's (``workspace_change``): one evaluation there."""
    start, n = design.start, design.problem.n_robot
    q = workspace_readings(start, q=np.vstack([d.q for d in (inputs.data, inputs.contacts) if d is not None]))
    predicted = at = None
    pts = design.problem.points
    if inputs.data is not None and inputs.contacts is None and pts is not None and not pts.backlash:
        at = design_like(pts, q)
        predicted = at.predicted(p[:n])[0]
    elif inputs.data is not None:
        at_q = design_measurements(start, q, markers=inputs.data.marker_names)
        predicted = Points(start, at_q, (), compliance=design.compliance).predicted(p[:n])[0]
    seen = observed_markers(inputs.data, inputs.contacts)
    return Reach(predicted, workspace_change(start, p[:n], q, seen, design.identifiability.identified, at=at), at)


def campaign_coverage(fit: Fit, cov: Covariance, where: Reach) -> Coverage | None:
    """Where the measured points' accuracy in use holds (``coverage``), None without them."""
    problem, solution = fit.problem, fit.solution
    if problem.points is None or where.predicted is None:
        return None
    k = len(problem.robot_idx)
    square = problem.contacts is None and solution.jacobian.shape[0] == solution.jacobian.shape[1] and \
        solution.row_kinds is None
    return coverage(problem.points, solution.p[:problem.n_robot], cov.covariance[:k, :k], where.predicted,
                    factor=solution.jacobian if square else None, workspace=where.at)


# -- the checks ------------------------------------------------------------------------------------

def input_checks(inputs: Inputs, analysis: Analysis) -> list[Check]:
    """The readings within the limits and in their declared units, the measured points' size against
    the robot's, every marker observed."""
    model, data, contacts = inputs.model, inputs.data, inputs.contacts
    parts = [(d.q, d.labels) for d in (data, contacts) if d is not None]
    # one kind of observation: its readings and labels as they are (no copy of every pose's)
    q = parts[0][0] if len(parts) == 1 else np.vstack([a for a, _ in parts])
    labels = parts[0][1] if len(parts) == 1 else [lab for _, labs in parts for lab in labs]
    out = [readings_check(model, q, labels), reading_units_check(model, q)]
    if data is not None:
        pts = cast(Points, analysis.problem.points)
        out.append(cloud_size_check(model, data, pts.predicted(analysis.problem.start_vector()[:pts.lay.n_params])[0]))
    out.append(markers_check(model, observed_markers(data, contacts)))
    if inputs.validation is not None and data is not None:
        out.append(held_apart_check(repeated_in(data, inputs.validation)))
    return out


def held_apart_check(repeated: np.ndarray) -> Check:
    """The validation poses apart from the fitted ones: those a validation set repeats are not held out."""
    name = "validation set apart from the fitted one"
    if not repeated.any():
        return Check(name, "pass", f"none of its {len(repeated)} poses repeats a fitted one")
    return Check(name, "warn", f"{int(repeated.sum())} of its {len(repeated)} poses repeat fitted poses exactly: they "
                 "are not held out, and the accuracy in use counts them as if they were", cause="a validation file "
                 "cut from the fitted one, or the fitted file given again", fix="give poses the fit did not see")


def explained_in_use(in_use, better: bool) -> bool:
    """The calibration places the robot better in use (``better``: ``placed_better``) and its held-out
    errors scatter as its fitted ones do: residuals beyond the instrument's are the robot's own."""
    if not better:
        return False
    seen, fitted = in_use.measured_after, in_use.measured_fit
    return seen is None or fitted is None or not fitted.n or seen.mean <= OVERFIT_RATIO * fitted.mean


def fit_checks(fit: Fit, options: Options, in_use_record: AccuracyInUse | None, better: bool) -> list[Check]:
    """Convergence, then each kind's residuals against what the instrument explains (judged by what
    the accuracy in use shows), and the orientations of 6D data."""
    solution, noise = fit.solution, options.noise
    # a registered base to try: measured points fix the frame, and the fit did not start from one
    can_register = fit.problem.points is not None and options.initial_base != "register"
    out = [convergence_check(solution.success, solution.message, solution.nfev,
                             n_free=solution.jacobian.shape[1], n_rows=fit.problem.n_rows, can_register=can_register,
                             max_nfev=options.max_nfev)]
    errors = fit.problem.observation_errors(solution.p)
    dof = kind_dof(fit.problem, solution, errors)
    explained = explained_in_use(in_use_record, better)
    for kind, (e, s, _) in errors.items():
        out.append(fit_check(e, s, noise, options.limit_m, np.zeros(len(e), dtype=bool),
                             stated=noise.stated, kind=kind, dof=dof[kind], explained=explained))
    pts = fit.problem.points
    if pts is not None and pts.data.has_orientation:
        out.append(_orientation_check(pts, solution.p[:fit.problem.n_robot]))
    return out


def kind_dof(problem: Problem, solution, errors: dict) -> dict:
    """Each kind's residual degrees of freedom: its rows less what the fit takes from them (the sum
    of their leverages). One kind: its rows less the free parameters."""
    if len(errors) == 1:
        kind, (e, _, _) = next(iter(errors.items()))
        return {kind: float(e.size * (1.0 - len(problem.free_idx) / max(problem.n_rows, 1)))}
    J = solution.jacobian if len(solution.jacobian) == problem.n_rows else problem.jacobian(solution.p)
    col = np.linalg.norm(J, axis=0)
    U, s, _ = np.linalg.svd(J / np.where(col > 0, col, 1.0), full_matrices=False)
    rank = int(np.sum(s > s[0] * 1e-10)) if s.size and s[0] > 0 else 0
    leverage = np.sum(U[:, :rank] ** 2, axis=1)
    kinds = problem.observations().kind
    row_kind = np.array([kinds[o] for o in problem.row_observations()], dtype=object)
    return {kind: float(np.sum(1.0 - leverage[row_kind == kind])) for kind in errors}


def _orientation_check(pts: Points, p: np.ndarray) -> Check:
    """A wrong orientation convention converges quietly: test the rotations, with or without stated sigmas."""
    data = pts.data
    vectors = pts.errors(p)
    rot_mask = cast(np.ndarray, data.rot_mask)      # set: called for data with orientations only
    rot = cast(np.ndarray, pts.rotation_errors(p))[rot_mask]
    found = misfit_notes(vectors[data.mask], rot,
                         characteristic_length_m=characteristic_length(data.positions[data.mask]),
                         sigma_rot_rad=None if data.sigma_rot is None else data.sigma_rot[rot_mask])
    rms = float(np.degrees(np.sqrt(np.mean(np.sum(rot ** 2, axis=1)))))
    if not found:
        return Check("orientation fit", "pass", f"rotation residuals {rms:.3g} deg RMS")
    return Check("orientation fit", "fail", found[0], cause="a wrong orientation convention or angle unit",
                 fix="declare the convention (--orientation) and the angle unit of the rotation columns")


def result_checks(fit: Fit, cov: Covariance, found: tuple[ParameterEstimate, ...], where: Reach, better: bool,
                  seen, unreachable=()) -> list[Check]:
    """What the estimates say: plausible changes, support, physical signs, correlations,
    identifiability at these observations (``unreachable``: what no contact reaches)."""
    design = fit.design
    moments = fit.problem.compliance_moments(fit.solution.p)
    deflections = {e.name: e.estimate * float(np.max(np.abs(moments[e.name]))) for e in found if e.name in moments}
    names = [e.name for e in found]
    k = len(names)
    corr = cov.correlation[:k, :k]
    loose = _loose(found, moments)
    unknown = tuple(m.name for m in design.start.markers if not m.rotation_known)
    frames = [m.frame for m in design.start.markers if m.name in set(seen)]
    apart = [] if len(set(frames)) == len(frames) else [markers_apart_check(
        design.start, model_from_vector(design.start, fit.solution.p[:fit.problem.n_robot]), seen)]
    return [plausibility_check(found, tolerances(design.start), deflections, workspace=where.judgement,
                               unknown_rotations=unknown, better=better),
            *apart,
            support_check(found), compliance_sign_check(found), backlash_sign_check(found),
            correlation_check(names, corr, loose),
            identifiability_check(design.lost, design.weak, weak_kept=design.weak_kept,
                                  interchangeable=interchangeable_pairs(names, corr, loose),
                                  kept_in_use=design.kept_in_use,
                                  size_unreached=any(u.name == "scale" for u in unreachable))]


def _loose(found, moments: dict) -> set:
    """The estimates whose standard deviation exceeds the bound of practical identifiability
    (``WEAK_STD``; a compliance's as a deflection at the RMS moment of the poses)."""
    out = set()
    for e in found:
        scale = float(np.sqrt(np.mean(moments[e.name] ** 2))) if e.name in moments else 1.0
        if e.std * scale > WEAK_STD.get(e.quantity, np.inf):
            out.add(e.name)
    return out


def alone_check(fit: Fit) -> list[Check]:
    """Observations one of whose rows alone fixes a quantity of the fit (``alone_observations``): a
    mistake in them moves the calibration and nothing else in the data checks them (a warning)."""
    problem = fit.problem
    obs = problem.observations()
    flagged = alone_observations(problem, fit.solution.p)
    if not flagged.any():
        return []
    idx = np.nonzero(flagged)[0]
    labels = [obs.label[i] for i in idx]
    what = ", ".join(dict.fromkeys(CARRIES.get(obs.kind[i], "a direction of the robot") for i in idx))
    listed = ", ".join(labels[:6]) + (" and more" if len(labels) > 6 else "")
    return [Check("rows carried alone", "warn",
                  f"{listed}: the only rows fixing {what}; kept in full (setting them aside would leave it free), "
                  "so nothing else in these data checks them",
                  cause="one observation alone fixes a quantity of the fit",
                  fix="state a second known distance or more contacts of that kind, so that one mistake shows",
                  items=tuple(labels))]


def placed_better(in_use_record: AccuracyInUse | None, where: Reach, problem: Problem,
                  validation: Measurements | None) -> bool:
    """Whether measured points show that the calibration places the robot better in use
    (``better_in_use``). Contacts alone show how consistent the robot is with itself, not where it
    is: a model that shrinks or twists can make seatings consistent, so they do not vouch for a
    change beyond a tolerance."""
    points = problem.points is not None or validation is not None
    return points and better_in_use(in_use_record, reach_of(where))


def reach_of(where: Reach) -> float | None:
    """The robot's reach (m): the markers' largest distance from the base over the configurations of use."""
    return None if where.judgement is None else where.judgement.reach_m


def noise_cost(fit: Fit, in_use_record: AccuracyInUse | None, holdout: Holdout) -> float:
    """What the stated noise alone costs the fitted robot at positions it was not fitted on (m, RMS):
    k parameters estimated from n positions of per-axis deviation s leave s sqrt(k / n) there (the
    hat matrix's trace is k), n those each held-out position was predicted from (in
    cross-validation, all but its group's). A robot that is its nominal model is that much worse
    after a calibration, which has nothing to correct; the tracker's points and the seatings alike."""
    problem = fit.problem
    errors = problem.observation_errors(fit.solution.p)
    parts = [(errors[kind][1], errors[kind][2]) for kind in POSITION_KINDS if kind in errors]
    if in_use_record is None or not parts:
        return 0.0
    s = np.concatenate([np.full(len(o), options_noise(problem)) if stated is None else stated for stated, o in parts])
    obs = np.concatenate([o for _, o in parts])
    seen = np.full(len(obs), float(len(obs)))
    if in_use_record.method == "cross-validation":
        group = holdout.groups[obs]
        held = group >= 0
        seen = len(obs) - np.bincount(group[held], minlength=holdout.k)[group[held]]
    return float(np.sqrt(np.mean(s ** 2) * len(problem.robot_idx) * np.mean(1.0 / np.maximum(seen, 1))))


def use_checks(in_use_record: AccuracyInUse | None, cover: Coverage | None, options: Options, misfit: float | None,
               where: Reach, held: PoseErrors | None = None, fitted: PoseErrors | None = None, cost: float = 0.0):
    """The accuracy in use (``misfit``: the measured points' fit against the instrument; ``cost``:
    ``noise_cost``), the held-out points that stand out (``held``: a validation set's errors), where
    it holds (against the ``fitted`` points' errors before), and the limit of absolute accuracy."""
    if in_use_record is None:
        return [Check("accuracy in use", "pass", "no position held out (contacts of one placement, or no seating "
                      "among them): judged by the fit's checks alone",
                      fix="measure on two placements or more, or hold out measured points (--validation)")], None
    out = [in_use_check(in_use_record, misfit, reach_of(where), cost)] + spacing_check(in_use_record)
    if held is not None and held.data.mask.any():
        d = held.data
        rows, markers = np.nonzero(d.mask)
        out.append(held_out_outlier_check(held.after[d.mask], None if d.sigma is None else d.sigma[d.mask],
                                          options.noise, Labels(d.labels, d.marker_names, rows, markers)))
    if cover is not None:
        missed = 0.0 if fitted is None else float(np.sqrt(np.nanmean(np.sum(fitted.before ** 2, axis=-1))))
        out.append(coverage_check(cover, in_use_record, where.judgement, missed))
    judged = None if options.limit_m is None else judge_against_limit(options.limit_m, in_use_record)
    if judged is not None:
        out.append(limit_check(judged))
    return out, judged


_WARNING_CLASS = {"solver convergence": ConvergenceWarning, "fit against the instrument": MisfitWarning,
                  "orientation fit": MisfitWarning, "identifiability at these poses": IdentifiabilityWarning,
                  "accuracy in use": MisfitWarning}


def warn_checks(checks) -> None:
    """Every check that did not pass, as a warning users can filter (pointing at the caller's line)."""
    for c in checks:
        if c.status != "pass":
            category = _WARNING_CLASS.get(c.name, MisfitWarning if c.name.startswith("fit of") else CheckWarning)
            warn(f"{c.name} ({'FAILED' if c.status == 'fail' else 'warning'}): {c.summary}", category)


# -- the record ------------------------------------------------------------------------------------

def contact_figures(inputs: Inputs, analysis: Analysis, fit: Fit, before: np.ndarray, cov: Covariance,
                    held_before: HeldOut | None = None) -> ContactFigures | None:
    """What contacts add to the record: the kit's figures before and after, fitted, and on held-out
    contacts or else each placement predicted by the others (``held_before``: the nominal model's
    errors there, ``held_out_nominal``), the nuisance estimates, each kind's residual ratio."""
    problem, p = fit.problem, fit.solution.p
    if problem.contacts is None or inputs.contacts is None or analysis.reach is None:
        return None
    rows, n = problem.contacts, problem.n_robot
    k = len(problem.robot_idx)
    val_rows = None if inputs.validation_contacts is None else ContactRows.of(
        fit.design.start, inputs.validation_contacts, fit.design.identifiability.identified,
        compliance=fit.design.compliance)
    cross_before = cross_after = None
    nominal, calibrated = None if held_before is None else held_before.contact_errors, fit.held_out.contact_errors
    # held-out placements judge the calibration when given: the others' cross-validation is not shown beside
    if val_rows is None and nominal is not None and calibrated is not None and np.isfinite(calibrated[:, 0]).any():
        cross_before, cross_after = figures(rows, nominal), figures(rows, calibrated)
    ratios = {kind: float(np.sqrt(np.mean((e / (s if s is not None else np.full(len(e), options_noise(problem)))
                                           [:, None]) ** 2)))
              for kind, (e, s, _) in problem.observation_errors(p).items()}
    return ContactFigures(
        identifiability=analysis.reach,
        nuisance={name: (float(p[n + i]), float(cov.std[k + i])) for i, name in enumerate(problem.nuisance_names)},
        fit_before=figures(rows, rows.own_errors(before[:n])), fit_after=figures(rows, rows.own_errors(p[:n])),
        validation_before=None if val_rows is None else figures(val_rows, val_rows.own_errors(before[:n])),
        validation_after=None if val_rows is None else figures(val_rows, val_rows.own_errors(p[:n])),
        held_out_before=cross_before, held_out=cross_after, noise_ratio=ratios, weak=fit.design.weak,
        weak_kept=fit.design.weak_kept, rows=recordings(inputs.contacts, inputs.data),
        source=inputs.contacts.source or "")


def point_misfit(fit: Fit, options: Options) -> float | None:
    """The measured points' residual RMS per axis over the expected noise (their stated deviations
    where given), or None without measured points."""
    pts = fit.problem.points
    if pts is None:
        return None
    errors = fit.problem.observation_errors(fit.solution.p)["tracker"]
    e, s = errors[0], errors[1]
    scale = options.noise.position if s is None else s[:, None]
    return float(np.sqrt(np.mean((e / scale) ** 2))) if e.size else None


def options_noise(problem: Problem) -> float:
    """The per-axis noise measured points without stated deviations are weighed by (m)."""
    return problem.noise.position if problem.noise is not None else Noise.of().position


def fit_errors(inputs: Inputs, fit: Fit, before: np.ndarray) -> PoseErrors | None:
    """The errors before and after on the fitted measured points (None without them)."""
    pts = fit.problem.points
    if inputs.data is None or pts is None:
        return None
    n = fit.problem.n_robot
    b, a, raw = before[:n], fit.solution.p[:n], parameter_vector(inputs.model)
    return PoseErrors(inputs.data, pts.errors(b), pts.errors(a), pts.rotation_errors(b), pts.rotation_errors(a),
                      set_aside=inputs.data.mask & ~pts.data.mask, nominal=pts.errors(raw),
                      rotation_nominal=pts.rotation_errors(raw))


def error_summaries(fitted: PoseErrors | None, val: PoseErrors | None) -> tuple[ErrorSummary, ErrorSummary | None]:
    """The statistics of the position and rotation errors, fitted and held out; with held-out
    measured points and no fitted ones (contacts fitted), theirs in the fitted rows."""
    if fitted is not None:
        return cast(ErrorSummary, fitted.summary(val, rotation=False)), fitted.summary(val, rotation=True)
    if val is not None:
        held = cast(ErrorSummary, val.summary(None, rotation=False))     # its own figures, in the validation's place
        return ErrorSummary(held.validation_before, held.validation_after, held.fit_before, held.fit_after,
                            validation_nominal=held.fit_nominal), None
    return PoseErrors.summary_of_none(), None


def record(inputs: Inputs, analysis: Analysis, fit: Fit, before: np.ndarray, cov: Covariance,
           found: tuple[ParameterEstimate, ...], judged: tuple, options: Options, notes: tuple[str, ...],
           held_before: HeldOut | None = None) -> CalibrationResult:
    """The calibration's record: estimates, covariance, errors before and after, the accuracy in
    use, the checks (``held_before``: the nominal model's cross-validated errors, ``held_out_nominal``)."""
    checks, in_use_record, val, cover, limit, fitted = judged
    solution, design = fit.solution, fit.design
    k = len(found)
    stats, rotation_stats = error_summaries(fitted, val)
    result = CalibrationResult(
        nominal_model=inputs.model, calibrated_model=model_from_vector(design.start, solution.p[:fit.problem.n_robot]),
        parameters=found, covariance=cov.covariance[:k, :k], correlation=cov.correlation[:k, :k],
        identifiability=design.identifiability,
        solver=SolverRecord(success=solution.success, status=solution.status, message=solution.message,
                            nfev=solution.nfev, loss=solution.loss, sigma0=float(np.sqrt(cov.s2)),
                            residual_dof=float(cov.dof)),
        families=options.parameters,
        fit=fitted.pose_set() if fitted is not None else PoseSet.empty(inputs.model),
        validation=None if val is None else val.pose_set(), stats=stats, rotation_stats=rotation_stats,
        in_use=in_use_record, coverage=cover, limit=limit,
        contacts=contact_figures(inputs, analysis, fit, before, cov, held_before),
        checks=tuple(checks), notes=notes,
        provenance=provenance(inputs.data, inputs.validation, inputs.contacts, inputs.validation_contacts))
    # the calibrated model says what it is, wherever it is written (never the nominal model's words)
    calibrated = result.calibrated_model
    described = calibrated.replace(description=calibrated_description(calibration_record(result)))
    described.derived(parameter_layout, lambda: parameter_layout(calibrated))     # a description: the same names
    return replace(result, calibrated_model=described)
