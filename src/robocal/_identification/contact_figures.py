"""Calibration from contacts (sockets, planes, ball bars, known distances), alone or with a tracker.

The steps of ``calibrate`` for a ``ContactProblem``: the identifiability over the union of the
kinds (each kind's own contribution, and what none of them reaches), the least-squares solve over
the identifiable robot parameters and every nuisance (socket points, planes), the covariance with
one variance factor per kind of row, the checks per kind, and the figures kit users judge a
calibration by: the spread of each socket's points, the error of each known distance and ball
bar, and the distance of plane contacts to their plane, before and after, fitted and held out.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from .._base.arguments import (
    FRACTION,
    checked,
    is_a,
    names_in,
    optional,
    shaped,
)
from .._base.arrays import read_only
from .._base.errors import DegenerateDataError, InputError
from .._model.contacts import Contacts
from .._model.kinematics import evaluate
from .._model.measurements import Measurements, Noise
from .._model.parameters import candidate_parameters, model_from_vector, parameter_layout, parameter_names
from .._model.robot import RobotModel
from .checks import (
    MEAN_NORM_PER_SIGMA,
    OVERFIT_GROSS,
    OVERFIT_GROSS_EXCESS,
    OVERFIT_RATIO,
    Check,
    contact_fit_check,
    convergence_check,
    correlation_check,
    fit_check,
    identifiability_check,
    interchangeable_pairs,
    outlier_check,
    plausibility_check,
    tolerances,
)
from .contact_blocks import ROW_KINDS, ContactProblem
from .estimates import ParameterEstimate, effect_text, workspace_change
from .holdout import AccuracyInUse, paired_excess, use_stats, workspace_readings
from .identifiability import DEFAULT_TOL, WEAK_STD, Absorption, IdentifiabilityResult, analyse, weakly_identifiable
from .problem import Problem, design_measurements, needs_compliance
from .solve import Solution, carried_alone, covariance, solve

# the part of a direction's effect the nuisance parameters leave (relative) below which it is unreachable
UNREACHABLE_TOL = 1e-6

_WHY = {
    "base": "a rigid motion of the whole robot carries every contact with it: the unknown socket points and "
            "planes follow, and nothing in these data is fixed in the measurement frame (a tracker, or a known "
            "plane, fixes it)",
    "scale": "socket and plane contacts fix shape, not size: the robot and every unknown point scaled alike "
             "give the same readings (a known distance between sockets, a ball bar or a tracker fixes it)",
}


@dataclass(frozen=True)
class Unreachable:
    """A direction of the robot's parameters no observation in the data can see, and why.
    ``components``: the parameters it moves (for the base, those of its six it cannot reach);
    ``residual``: the relative part of its effect left once the nuisance parameters take theirs."""

    name: str
    reason: str
    components: tuple[str, ...]
    residual: float


@dataclass(frozen=True, eq=False)
class ContactIdentifiability:
    """The analysis over the union of the kinds. ``analysis`` holds nuisance and robot columns
    (nuisance first: what they absorb is eliminated from the robot); ``identified``/``eliminated``
    are the robot's; ``contributions`` maps each kind present to the robot parameters its rows
    identify alone, ``lost_without`` to those the others cannot identify without it; ``together``
    those only the kinds together identify; ``unreachable`` the directions no kind reaches."""

    analysis: IdentifiabilityResult
    identified: tuple[str, ...]
    eliminated: tuple[Absorption, ...]
    contributions: dict
    together: tuple[str, ...]
    unreachable: tuple[Unreachable, ...]
    lost_without: dict = field(default_factory=dict)


def _kind_groups(kinds: np.ndarray) -> dict:
    """Row masks per kind present, tracker positions and rotations together."""
    names = np.array(["tracker" if k < 2 else ROW_KINDS[k] for k in kinds], dtype=object)
    return {str(n): names == n for n in dict.fromkeys(names)}


def _unabsorbed(v: np.ndarray, N: np.ndarray, ref: float) -> float:
    """The norm of ``v`` outside the span of the columns of ``N``, relative to ``ref`` (the size of
    the direction's effect on the marker positions: a ball bar sees a rotation of the whole robot
    as round-off, not as zero)."""
    if ref == 0:
        return 0.0
    if N.shape[1] == 0:
        return float(np.linalg.norm(v) / ref)
    c = np.linalg.lstsq(N, v, rcond=None)[0]
    return float(np.linalg.norm(v - N @ c) / ref)


def _unreachable(problem: ContactProblem, p: np.ndarray) -> tuple[Unreachable, ...]:
    """The base's components and the scale whose effect the nuisance parameters absorb entirely."""
    lay = parameter_layout(problem.model)
    base = tuple(n for n in lay.names if lay[n].role == "base")
    lengths = tuple(n for n in lay.names if lay[n].quantity == "length" and lay[n].role != "base")
    met = problem.at_contact().over(base + lengths)
    J = met.jacobian(p)
    N = J[:, len(base) + len(lengths):]
    N = N / np.maximum(np.linalg.norm(N, axis=0), 1e-300)
    # the effect on the marker positions, in the rows' weights: what "absorbed" is relative to
    k = len(base) + len(lengths)
    Jm = (met.marker_jacobian(p[:met.n_robot]) / met.contacts.sigma[:, None, None]).reshape(-1, k)
    Jm = np.vstack([J[:int(np.sum(met.row_kinds() < 2)), :k], Jm])     # tracker rows as they are
    out = []
    hidden = [(n, _unabsorbed(J[:, i], N, float(np.linalg.norm(Jm[:, i])))) for i, n in enumerate(base)]
    gone = tuple(n for n, r in hidden if r < UNREACHABLE_TOL)
    if gone:
        out.append(Unreachable("base", _WHY["base"], gone, max(r for n, r in hidden if n in gone)))
    v = p[lay.indices(lengths)]
    scale = J[:, len(base):len(base) + len(lengths)] @ v
    r = _unabsorbed(scale, N, float(np.linalg.norm(Jm[:, len(base):] @ v)))
    if r < UNREACHABLE_TOL:
        out.append(Unreachable("scale", _WHY["scale"], lengths, r))
    return tuple(out)


@checked(problem=is_a(ContactProblem), names=names_in(lambda a: parameter_names(a["problem"].model)), tol=FRACTION,
         p=optional(shaped(None)))
def contact_identifiability(problem: ContactProblem, names, *, tol: float = DEFAULT_TOL,
                            p: np.ndarray | None = None) -> ContactIdentifiability:
    """Which of the robot parameters ``names`` the union of the problem's rows identifies (at ``p``,
    default the start), what each kind identifies alone, and what none reaches.

    Parameters
    ----------
    {problem}
    names : sequence of str
        Candidate parameter names.
    tol : float
        Identifiability tolerance, in (0, 1).
    p : array_like, optional
        Parameter vector the analysis is made at (default: the problem's start).

    Returns
    -------
    ContactIdentifiability
        What the contacts identify, and what they cannot reach.
    """
    p = problem.start_vector() if p is None else p
    lay = parameter_layout(problem.model)
    prob = problem.at_contact().over(tuple(names))
    J = prob.jacobian(p)
    k = len(names)
    # nuisance first in the preference order: what a point or a plane absorbs leaves the robot
    order = np.r_[np.arange(k, J.shape[1]), np.arange(k)]
    all_names = problem.nuisance_names + tuple(names)
    quantities = problem.nuisance_quantities + tuple(lay[n].quantity for n in names)
    result = analyse(J[:, order], all_names, quantities=quantities, tol=tol)
    robot = set(names)
    identified = tuple(n for n in result.identified if n in robot)
    contributions, lost = {}, {}
    groups = _kind_groups(prob.row_kinds())
    for kind, rows in groups.items():
        alone = analyse(J[rows][:, order], all_names, quantities=quantities, tol=tol)
        contributions[kind] = tuple(n for n in alone.identified if n in robot)
        if len(groups) > 1:
            rest = set(analyse(J[~rows][:, order], all_names, quantities=quantities, tol=tol).identified)
            lost[kind] = tuple(n for n in identified if n not in rest)
    seen = set().union(*contributions.values()) if contributions else set()
    return ContactIdentifiability(
        analysis=result, identified=identified, eliminated=tuple(a for a in result.eliminated if a.name in robot),
        contributions=contributions, together=tuple(n for n in identified if n not in seen),
        unreachable=_unreachable(problem, p), lost_without=lost)


@dataclass(frozen=True, eq=False)
class ContactErrors:
    """What a kit's user judges a calibration by, for one model on one set of contacts (m):
    ``spread`` per socket (placement/socket) the RMS distance of the marker positions from their
    centroid; ``distance`` per placement and pair the centroids' distance minus the known length;
    ``plane`` per plane the RMS distance of its contacts from the plane (the known one, else the
    best-fitting); ``bar`` per pair the distance of the two ends minus the bar's length;
    ``consistency`` per socket the (mean, max) distance of its seated ball centres from their mean
    centre, the figure socket campaigns are judged by (``distance`` is then the spacing error:
    calibrated spacing minus the known one)."""

    spread: dict
    distance: dict
    plane: dict
    bar: dict
    consistency: dict = field(default_factory=dict)
    seatings: dict = field(default_factory=dict)

    @property
    def mean_spread(self) -> float | None:
        return float(np.mean(list(self.spread.values()))) if self.spread else None

    @property
    def distance_rms(self) -> float | None:
        return float(np.sqrt(np.mean(np.square(list(self.distance.values()))))) if self.distance else None

    @property
    def consistency_mean(self) -> float | None:
        """The mean distance of every seated ball centre from its socket's mean centre (m)."""
        d = list(self.seatings.values())
        return float(np.mean(np.concatenate(d))) if d else None

    @property
    def consistency_max(self) -> float | None:
        """The largest distance of a seated ball centre from its socket's mean centre (m)."""
        return float(max(m for _, m in self.consistency.values())) if self.consistency else None

    @property
    def spacing_mean(self) -> float | None:
        """The mean absolute spacing error (calibrated minus known distance, m)."""
        return float(np.mean(np.abs(list(self.distance.values())))) if self.distance else None

    @property
    def spacing_max(self) -> float | None:
        """The largest absolute spacing error (m)."""
        return float(np.max(np.abs(list(self.distance.values())))) if self.distance else None


@checked(model=is_a(RobotModel), contacts=is_a(Contacts))
def contact_errors(model: RobotModel, contacts: Contacts) -> ContactErrors:
    """The figures of ``ContactErrors`` for ``model`` at the readings of ``contacts``.

    Parameters
    ----------
    {model, contacts}

    Returns
    -------
    ContactErrors
        The residuals of each kind of contact.
    """
    ev = evaluate(model, contacts.q)
    P = ev.positions[np.arange(contacts.n_rows), [model.marker_names.index(m) for m in contacts.marker]]
    centre = {}
    spread, consistency, seatings = {}, {}, {}
    for g in contacts.groups("socket"):
        centre[g.placement, g.target] = P[g.rows].mean(axis=0)
        d = np.linalg.norm(P[g.rows] - centre[g.placement, g.target], axis=1)
        spread[g.label] = float(np.sqrt(np.mean(d ** 2)))
        consistency[g.label] = (float(d.mean()), float(d.max()))
        seatings[g.label] = read_only(d)
    distance = {f"{ga.placement}: {d.a}-{d.b}": float(np.linalg.norm(centre[ga.placement, d.a] -
                                                                      centre[gb.placement, d.b]) - d.length)
                for d, ga, gb in contacts.distance_pairs()}
    plane = {}
    for g in contacts.groups("plane"):
        X = P[g.rows]
        kp = contacts.known_plane(g.target)
        if kp is not None:
            dist = X @ np.asarray(kp.normal) - kp.offset
        else:
            dist = (X - X.mean(axis=0)) @ np.linalg.svd(X - X.mean(axis=0))[2][-1]
        plane[g.label] = float(np.sqrt(np.mean(dist ** 2)))
    bar = {g.label: float(np.linalg.norm(P[g.rows[0]] - P[g.rows[1]]) - contacts.bars[g.target][0])
           for g in contacts.groups("bar")}
    return ContactErrors(spread, distance, plane, bar, consistency, seatings)


@dataclass(frozen=True, eq=False)
class ContactFigures:
    """What contacts add to the ``CalibrationResult`` of a calibration that fitted them (its
    ``contacts``): ``identifiability`` what each kind of contact reaches and what none does;
    ``nuisance`` name -> (estimate, std) of each socket point coordinate and plane parameter (SI);
    ``fit_before``/``fit_after`` and ``validation_before``/``validation_after`` the kit's figures
    (``ContactErrors``; validation None without held-out contacts); ``held_out`` the figures of each
    placement predicted by the fit on the others (None with a validation set or one placement);
    ``noise_ratio`` per kind of row the RMS residual in stated standard deviations; ``weak`` the
    parameters the rows cannot pin down (name, predicted std), held at nominal unless ``weak_kept``;
    ``rows`` the number of rows of each kind; ``source`` the contact file or folder;
    ``residual_dof`` the fit's degrees of freedom (rows less the robot's and the points' and
    planes' unknowns: what ``compare``'s F test counts)."""

    identifiability: ContactIdentifiability
    nuisance: dict
    fit_before: ContactErrors
    fit_after: ContactErrors
    validation_before: ContactErrors | None = None
    validation_after: ContactErrors | None = None
    held_out: ContactErrors | None = None
    noise_ratio: dict = field(default_factory=dict)
    weak: tuple[tuple[str, str], ...] = ()
    weak_kept: bool = False
    rows: dict = field(default_factory=dict)
    source: str = ""
    residual_dof: float = 0.0


@dataclass(frozen=True, eq=False)
class ContactOutcome:
    """A calibration from contacts solved and checked, before ``calibrate`` makes its record:
    ``figures`` for ``CalibrationResult.contacts``, the estimates with their covariance and
    correlation, the solution, the calibrated model, the checks and whether compliance was modelled."""

    figures: ContactFigures
    parameters: tuple[ParameterEstimate, ...]
    covariance: np.ndarray
    correlation: np.ndarray
    s2: float
    solution: Solution
    calibrated_model: RobotModel
    checks: tuple[Check, ...]
    compliance: bool


def _recordings(contacts: Contacts, data: Measurements | None) -> dict:
    """The number of recordings of each kind: seatings, plane contacts, bar ends, known distances
    (one per placement and pair) and tracker poses."""
    out = {k: int(sum(1 for x in contacts.kind if x == k)) for k in dict.fromkeys(contacts.kind)}
    pairs = len(contacts.distance_pairs())
    out.update({"distance": pairs} if pairs else {})
    out.update({"tracker": int(data.n_poses)} if data is not None else {})
    return out


def _check_inputs(model: RobotModel, contacts: Contacts, data, validation) -> None:
    for what, c in (("contacts", contacts), ("validation", validation)):
        if c is None:
            continue
        if c.q.shape[1] != model.n_joints:
            raise InputError(f"{c.q.shape[1]} joint columns for a model with {model.n_joints} joints "
                             f"({', '.join(model.joint_names)})", source=c.source or what)
        for m in dict.fromkeys(c.marker):
            if m not in model.marker_names:
                raise InputError(f"marker {m!r} is not in the model (markers: {', '.join(model.marker_names)})",
                                 source=c.source or what)
    if data is not None and data.q.shape[1] != model.n_joints:
        raise InputError(f"{data.q.shape[1]} joint columns for a model with {model.n_joints} joints",
                         source=data.source or "data")


def contact_in_use(figures: ContactFigures, validated: bool) -> AccuracyInUse | None:
    """The socket consistency of seatings the fit did not see as the calibration's accuracy in use:
    each seated ball centre's distance from its socket's mean centre, for the nominal and the
    calibrated model, on the held-out placements (``validated``) or on each placement predicted by
    the fit on the others; None when no seating was held out."""
    held = figures.validation_after if validated else figures.held_out
    nominal = figures.validation_before if validated else figures.fit_before
    if held is None or nominal is None:
        return None
    labels = [k for k in held.seatings if k in nominal.seatings]
    if not labels:
        return None
    after = np.concatenate([held.seatings[k] for k in labels])
    before = np.concatenate([nominal.seatings[k] for k in labels])
    fitted = use_stats(np.concatenate(list(figures.fit_after.seatings.values())))
    placements = dict.fromkeys(k.split("/")[0] for k in labels)
    return AccuracyInUse(
        method="socket consistency of the held-out placements" if validated else
        "socket consistency of each placement predicted by the others", folds=None if validated else len(placements),
        grouping="placement", position_before=use_stats(before), position_after=use_stats(after),
        rotation_before=None, rotation_after=None, fit_after=fitted, errors_before=read_only(before),
        errors_after=read_only(after), measured_after=use_stats(after), measured_fit=fitted)


def fit_contacts(model: RobotModel, contacts: Contacts, *, data: Measurements | None, validation: Contacts | None,
                 parameters: tuple, known: tuple, noise: Noise, tol: float, loss: str, f_scale: float | None,
                 max_nfev: int | None, on_outliers: str, weak: str, limit: float | None,
                 nonnegative_compliance: bool) -> ContactOutcome:
    """The steps of ``calibrate`` for contacts (its arguments checked there), up to its record.

    ``validation``: held-out contacts (e.g. a placement) judged with the calibrated model; without
    them and with two placements or more, each placement is held out in turn. Each contact row
    weighs by its stated deviation, tracker rows by their own or ``noise``. ``on_outliers="refit"``
    refits with the robust loss soft_l1 when rows stand out (every row is in its own standard
    deviations, so one bend serves every kind; ``f_scale`` in those units), keeping in full the rows
    that alone carry a quantity. Parameters the rows cannot pin down (their predicted standard
    deviation, the points and planes taken out, beyond the bound of practical identifiability at the
    stated deviations, or at the scatter ``limit`` implies) are held at nominal with
    ``weak="eliminate"``, unless each placement predicted by the others is worse without them.
    """
    _check_inputs(model, contacts, data, validation)
    names = candidate_parameters(model, parameters, known=known)
    compliance = needs_compliance(model, names)
    prob = ContactProblem(model, contacts, names, compliance=compliance, data=data, noise=noise)
    p0 = prob.start_vector()
    ident = contact_identifiability(prob, names, tol=tol, p=p0)
    if not ident.identified:
        raise DegenerateDataError(f"no robot parameter is identifiable from these contacts ({prob.n_rows} rows)")
    weak_found = _weak(prob.over(ident.identified), p0, _row_scatter(contacts, limit))
    settings = _Settings(data, noise, loss, f_scale, max_nfev, on_outliers, nonnegative_compliance,
                         validation is None and len(contacts.placements()) > 1)
    held_back = tuple(n for n in ident.identified if n not in {w for w, _ in weak_found})
    fit, kept_in_use = _choose(prob, p0, ident.identified, held_back if weak == "eliminate" else None, settings)
    free, sol = fit.design.free_names, fit.solution
    cov = covariance(sol)
    k = len(free)
    lay = parameter_layout(model)
    estimates = tuple(ParameterEstimate(n, lay[n].unit, float(p0[lay[n].index]), float(sol.p[lay[n].index]),
                                        float(cov.std[i]), family=lay[n].family, quantity=lay[n].quantity)
                      for i, n in enumerate(free))
    calibrated = model_from_vector(model, sol.p[:prob.n_robot])
    reach = workspace_change(model, sol.p[:prob.n_robot], workspace_readings(model),
                             tuple(dict.fromkeys(contacts.marker)), free)
    loose = {e.name for e in estimates if e.std > WEAK_STD.get(e.quantity, np.inf)}
    corr = cov.correlation[:k, :k]
    kept = weak != "eliminate" or kept_in_use
    checks = list(fit.checks) + [
        plausibility_check(estimates, tolerances(model), {}, workspace=reach),
        correlation_check([e.name for e in estimates], corr, loose),
        identifiability_check((), weak_found, weak_kept=kept, kept_in_use=kept_in_use,
                              interchangeable=interchangeable_pairs(list(free), corr, loose))]
    held = fit.held_out if validation is None else contact_errors(calibrated, validation)
    if held is not None:
        checks.append(_held_out_check(contact_errors(model, contacts if validation is None else validation),
                                      contact_errors(calibrated, contacts), held,
                                      "each placement predicted by the others" if validation is None else
                                      "the held-out placements"))
    figures = ContactFigures(
        identifiability=ident,
        nuisance={n: (float(sol.p[prob.n_robot + i]), float(cov.std[k + i]))
                  for i, n in enumerate(prob.nuisance_names)},
        fit_before=contact_errors(model, contacts), fit_after=contact_errors(calibrated, contacts),
        validation_before=None if validation is None else contact_errors(model, validation),
        validation_after=None if validation is None else contact_errors(calibrated, validation),
        held_out=fit.held_out, noise_ratio=fit.ratios, weak=tuple(weak_found), weak_kept=kept,
        rows=_recordings(contacts, data),
        source=contacts.source or "", residual_dof=float(cov.dof))
    return ContactOutcome(figures, estimates, cov.covariance[:k, :k], corr, float(cov.s2), sol, calibrated,
                          tuple(checks), compliance)


@dataclass(frozen=True)
class _Settings:
    """How a design of contacts is fitted: the tracker data beside them, the noise, the solver's
    options, and whether each placement is predicted by the others (``by_placement``)."""

    data: Measurements | None
    noise: Noise
    loss: str
    f_scale: float | None
    max_nfev: int | None
    on_outliers: str
    nonnegative_compliance: bool
    by_placement: bool


@dataclass(frozen=True, eq=False)
class _ContactFit:
    """One design of contacts solved: its problem, solution, row checks, each kind's residual ratio
    and, when asked, each placement's figures predicted by the others."""

    design: ContactProblem
    solution: Solution
    checks: tuple[Check, ...]
    ratios: dict
    held_out: ContactErrors | None


def _lower(problem: ContactProblem, nonnegative_compliance: bool) -> np.ndarray | None:
    """Lower bounds of the free robot parameters and every nuisance: 0 on compliances, if asked."""
    if not nonnegative_compliance:
        return None
    lay = parameter_layout(problem.model)
    return np.r_[[0.0 if lay[n].family == "compliance" else -np.inf for n in problem.free_names],
                 np.full(problem.n_nuisance, -np.inf)]


def _fit_design(prob: ContactProblem, p0: np.ndarray, free: tuple[str, ...], how: _Settings) -> _ContactFit:
    design = prob.over(free)
    if not free or design.n_rows <= len(design.free_idx):
        raise DegenerateDataError(f"{design.n_rows} equations for {len(free)} identifiable robot "
                                  f"parameters and {prob.n_nuisance} unknowns of points and planes")
    sol, checks, ratios = _solve(design, p0, how.data, how.noise, loss=how.loss, f_scale=how.f_scale,
                                 max_nfev=how.max_nfev,
                                 on_outliers=how.on_outliers, lower=_lower(design, how.nonnegative_compliance))
    held = _by_placement(prob.model, prob.contacts, free, sol.p[:prob.n_robot], how) if how.by_placement else None
    return _ContactFit(design, sol, tuple(checks), ratios, held)


def _choose(prob: ContactProblem, p0: np.ndarray, identified: tuple[str, ...], held_back: tuple[str, ...] | None,
            how: _Settings) -> tuple[_ContactFit, bool]:
    """The design the held-out placements support, and whether weak parameters were kept for it.
    ``held_back``: the design without the weak parameters (None: they are kept by choice). As for
    measured points, the simpler design is kept unless each placement predicted by the others is
    worse with it by more than one standard error (over the seatings' squared distances from their
    socket's mean centre); with one placement, or a validation set, it is kept."""
    if held_back is None or held_back == identified:
        return _fit_design(prob, p0, identified, how), False
    if not held_back:
        raise DegenerateDataError("no robot parameter can be pinned down by these contacts at their stated "
                                  "deviations")
    simple = _fit_design(prob, p0, held_back, how)
    if simple.held_out is None:
        return simple, False
    full = _fit_design(prob, p0, identified, how)
    other = full.held_out.seatings if full.held_out is not None else {}
    labels = [k for k in simple.held_out.seatings if k in other]
    if not labels:
        return simple, False
    losses = [np.concatenate([d[k] ** 2 for k in labels]) for d in (simple.held_out.seatings, other)]
    excess, se = paired_excess(losses[0], losses[1], np.ones(len(losses[0]), dtype=bool))
    return (full, True) if excess > se else (simple, False)


def _held_out_check(before: ContactErrors, fitted: ContactErrors, held: ContactErrors, how: str) -> Check:
    """The socket consistency of seatings the fit did not see (``held``: the calibrated model on
    them, ``before``: the nominal's), judged as the accuracy in use of measured points is: worse
    than the nominal fails, beyond ``OVERFIT_GROSS`` times the fitted seatings' (and a millimetre
    more) fails, beyond ``OVERFIT_RATIO`` times them warns (overfitting)."""
    name = "accuracy in use"
    a, b, f = held.consistency_mean, before.consistency_mean, fitted.consistency_mean
    if a is None or b is None or f is None:
        return Check(name, "pass", f"no socket seatings held out ({how}): judged by the fit's checks alone")
    summary = (f"socket consistency of {how}: mean {a * 1e3:.4g} mm after, {b * 1e3:.4g} mm before calibration; "
               f"{f * 1e3:.4g} mm on the fitted seatings")
    if a > OVERFIT_GROSS * f and a > f + OVERFIT_GROSS_EXCESS:
        return Check(name, "fail", summary + ": beyond anything the fit explains", cause="a placement or socket "
                     "mislabelled, or a set-up that moved", fix="check the placements' labels and seatings")
    if a >= b:
        return Check(name, "fail", summary + ": no better than before calibration", cause="a model or data "
                     "mistake", fix="read the checks above; check joint order, signs and the contact file")
    if a > OVERFIT_RATIO * f:
        return Check(name, "warn", summary + f": {a / f:.3g} times the fitted seatings' (overfitting)",
                     cause="too few placements or seatings for the parameters", fix="add placements, or hold "
                     "parameters at nominal (--known)")
    return Check(name, "pass", summary)


def _row_scatter(contacts: Contacts, limit: float | None) -> float:
    """The scatter weak parameters are judged at, in the rows' units (stated standard deviations):
    1, or with a limit of absolute accuracy the robot's own scatter it implies beside the stated
    deviations (their median)."""
    if limit is None:
        return 1.0
    return float(np.hypot(1.0, limit / MEAN_NORM_PER_SIGMA / float(np.median(contacts.sigma))))


def _weak(design: ContactProblem, p0: np.ndarray, sigma: float) -> list[tuple[str, str]]:
    """The robot parameters of ``design`` the rows cannot pin down at a scatter ``sigma`` (rows'
    units), with their predicted standard deviation as text: ``weakly_identifiable`` on the robot's
    columns once what the points and planes absorb is taken out of them."""
    J = design.jacobian(p0)
    k = len(design.robot_idx)
    Jr, N = J[:, :k], J[:, k:]
    if N.shape[1]:
        U, s, _ = np.linalg.svd(N / np.maximum(np.linalg.norm(N, axis=0), 1e-300), full_matrices=False)
        U = U[:, s > s[0] * 1e-10]
        Jr = Jr - U @ (U.T @ Jr)
    lay = parameter_layout(design.model)
    moments = {}
    if design.compliance:      # a compliance is judged by the deflection it predicts, as for measured points
        readings = design_measurements(design.model, design.contacts.q, markers=design.model.marker_names[:1])
        moments = Problem(design.model, readings, (), compliance=True).compliance_moments(p0[:design.n_robot])
    found = weakly_identifiable(Jr, design.free_names, [lay[n].quantity for n in design.free_names], sigma,
                                moments=moments)
    return [(n, effect_text(e, lay[by].quantity) + ("" if by == n else f" of {by} with it")) for n, by, e, _ in found]


def _by_placement(model: RobotModel, contacts: Contacts, free, p_robot: np.ndarray, how: _Settings) -> ContactErrors:
    """Each placement's figures predicted by the calibration on the other placements (the points
    and planes of the others refitted, the robot started from the full solution): the held-out
    consistency and spacing error, a placement at a time."""
    start = model_from_vector(model, p_robot)
    compliance = needs_compliance(model, free)
    parts = []
    for placement in contacts.placements():
        rest, held = contacts.split_placements([placement])
        prob = ContactProblem(start, rest, free, compliance=compliance, data=how.data, noise=how.noise)
        try:
            sol = solve(prob, prob.start_vector(), max_nfev=how.max_nfev,
                        lower=_lower(prob, how.nonnegative_compliance))
        except DegenerateDataError:      # the others alone cannot fix the fit: no prediction for it
            continue
        parts.append(contact_errors(model_from_vector(model, sol.p[:prob.n_robot]), held))
    return ContactErrors(*({k: v for e in parts for k, v in getattr(e, f).items()}
                           for f in ("spread", "distance", "plane", "bar", "consistency", "seatings")))


def _solve(design: ContactProblem, p0, data, noise: Noise, *, loss: str, f_scale: float | None, max_nfev,
           on_outliers: str, lower=None):
    """The solution, the checks of its rows and each kind's residual ratio; a linear fit that leaves
    outliers is refitted with a robust loss when ``on_outliers`` is "refit" (bending at ``f_scale``
    stated deviations, or where scipy estimates)."""
    sol = solve(design, p0, loss=loss, f_scale=None if loss == "linear" else f_scale, max_nfev=max_nfev, lower=lower)
    checks, ratios, outlying = _row_checks(design, sol, data, noise)
    if not (outlying and loss == "linear" and on_outliers == "refit"):
        return sol, checks, ratios
    alone = carried_alone(design.jacobian(sol.p))
    sol = solve(design, p0, loss="soft_l1", f_scale=f_scale, max_nfev=max_nfev,
                linear_rows=alone if alone.any() else None, lower=lower)
    checks, ratios, _ = _row_checks(design, sol, data, noise)
    said = f"; the robust loss {sol.loss} sets them aside"
    checks = [replace(c, status="warn", summary=c.summary + said, fix="check those rows; remove them to fit "
                      "without them") if c.name.startswith("outliers") and c.status != "pass" else c
              for c in checks]
    if alone.any():
        checks.append(_kept_alone(design, alone))
    return sol, checks, ratios


_CARRIES = {"distance": "the scale", "bar": "the scale", "plane": "a plane's position", "socket": "a socket's point",
            "position": "a direction of the robot", "rotation": "a direction of the robot"}


def _kept_alone(design: ContactProblem, alone: np.ndarray) -> Check:
    """The rows the robust refit kept in full because they alone carry a quantity (``carried_alone``)."""
    labels = np.array(design.row_labels(), dtype=object)[alone]
    kinds = [ROW_KINDS[k] for k in design.row_kinds()[alone]]
    what = ", ".join(dict.fromkeys(_CARRIES[k] for k in kinds))
    listed = ", ".join(dict.fromkeys(str(v) for v in labels[:6])) + (" and more" if len(labels) > 6 else "")
    return Check("rows carried alone", "warn",
                 f"{listed}: the only rows fixing {what}; kept in full in the robust refit (setting them aside would "
                 "leave it free), so nothing else in these data checks them",
                 cause="one observation alone fixes a quantity of the fit",
                 fix="state a second known distance or more contacts of that kind, so that one mistake shows",
                 items=tuple(str(v) for v in labels))


def _row_checks(design: ContactProblem, sol, data, noise: Noise):
    """Convergence, then each kind of row on its own (outliers and fit), each kind's RMS residual in
    stated deviations, and whether any row stands out."""
    checks = [convergence_check(sol.success, sol.message, sol.nfev)]
    ratios = {}
    outlying = False
    labels = design.contact_labels()
    for kind, (r, s) in design.contact_errors(sol.p).items():
        if not len(s):
            continue
        r2 = np.reshape(r, (len(s), -1))
        out_check, out = outlier_check(r2, s, noise, labels[kind])
        outlying |= bool(out.any())
        checks += [replace(out_check, name=f"outliers among the {kind} contacts"),
                   contact_fit_check(kind, r2, s, out)]
        ratios[kind] = float(np.sqrt(np.mean((r2 / s[:, None]) ** 2)))
    if data is not None and design.tracker is not None:
        residuals = design.tracker.problem.errors(sol.p[:design.n_robot])[data.mask]
        sigma = None if data.sigma is None else data.sigma[data.mask]
        rows, markers = np.nonzero(data.mask)
        out_check, out = outlier_check(residuals, sigma, noise, [f"{data.labels[i]}, marker {data.marker_names[j]}"
                                                                 for i, j in zip(rows, markers)])
        outlying |= bool(out.any())
        checks += [out_check, fit_check(residuals, sigma, noise, None, out)]
        ratios["tracker"] = float(np.sqrt(np.mean((residuals / (noise.position if sigma is None else
                                                                 sigma[:, None])) ** 2)))
    return checks, ratios, outlying
