"""The steps of a calibration: one sequence for every kind of observation.

``calibrate`` runs them in order on a ``Problem`` of any stack of blocks (measured points, sockets,
planes, ball bars, known distances): prepare the inputs, analyse what the data identify, choose the
model by its error on held-out observations (weak parameters held back only where that costs
nothing there; observations that stand out set aside only where that helps), take the covariance
and the estimates, judge the accuracy in use. What differs between kinds is a property of the
blocks (how held-out groups are formed, each kind's stated deviations, which rows carry a
quantity alone), never a second sequence. The checks and the record are in ``judgement``.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field, replace

import numpy as np

from .._base.arrays import vector_norms
from .._base.errors import DegenerateDataError, InputError
from .._model.contacts import Contacts
from .._model.measurements import Measurements, Noise
from .._model.parameters import (
    candidate_parameters,
    joint_variable_names,
    matched_by_pattern,
    needs_compliance,
    parameter_layout,
    parameter_vector,
)
from .._model.robot import RobotModel
from .checks import (
    BLUNDER_SEPARATION,
    FIT_RATIO,
    GROSS_FACTOR,
    MEAN_NORM_PER_SIGMA,
    OUTLIER_RUN,
    OUTLIER_SHARE_MAX,
    REFIT_GAIN_SIGMAS,
    Check,
    expected_noise,
    outlier_bar,
    outlier_check,
    outlier_scores,
)
from .contact_blocks import TOGETHER
from .estimates import REGISTRATION_TOL, effect_text, weak_words
from .holdout import FoldProblems, HeldOut, Holdout, cross_validate, first_equal_rows, paired_excess
from .identifiability import (
    ContactIdentifiability,
    IdentifiabilityResult,
    StackAnalysis,
    analyse_stack,
    kinds_reach,
    theoretical_identifiability,
    weakly_identifiable,
)
from .identifiability import eliminate as eliminate_parameters
from .problem import Problem
from .solve import SOLVER_TOL, Solution, carried_alone, solve


@dataclass(frozen=True)
class Options:
    """What ``calibrate`` was asked, checked once at its face: the families and names identified
    and held, the solver's options, what to do with outliers and weak parameters, the folds, the
    instrument's noise and the limit of absolute accuracy (m, or None)."""

    parameters: tuple[str, ...]
    known: tuple[str, ...]
    noise: Noise
    tol: float
    loss: str
    f_scale: float | None
    max_nfev: int | None
    on_outliers: str
    weak: str
    nonnegative_compliance: bool
    folds: int
    limit_m: float | None
    initial_base: str
    register_validation: bool
    # parameters never held back as weak: those of an identification this one is nested on, so that
    # it adds to them (``compare``)
    floor: tuple[str, ...] = ()


@dataclass(frozen=True, eq=False)
class Inputs:
    """What the calibration fits and is judged on: the nominal model and the one the solve starts
    from, measured points (exact copies counted once) and contacts, the held-out measured points
    or contacts, and what preparing them noted."""

    model: RobotModel
    start: RobotModel
    data: Measurements | None
    contacts: Contacts | None
    validation: Measurements | None
    validation_contacts: Contacts | None
    notes: tuple[str, ...]


def prepare(model: RobotModel, data: Measurements | None, contacts: Contacts | None, validation,
            options: Options, register_base) -> Inputs:
    """The inputs of the steps: exact copies of a row counted once, the start (the model, or with
    its base registered on the measured points), and the held-out set by kind."""
    notes = list(model.notes) + ([] if data is None else list(data.extra.get("notes", ())))
    notes += [] if contacts is None else list(contacts.notes)
    copies: tuple[str, ...] = ()
    if data is not None:
        data, copies = without_copies(data)
        _points_move(data)
    start = model
    if options.initial_base == "register":
        if data is None:
            raise InputError("contacts alone fix no frame to register the base in; give measured points beside "
                             "them, or leave the base at the model's", where="initial_base")
        start = register_base(model, data)
        notes += ["base pose started from a closed-form registration of the nominal robot on the data",
                  "base parameters are reported against the registered base (nominal column), not the model file's"]
    points = validation if isinstance(validation, Measurements) else None
    held = validation if isinstance(validation, Contacts) else None
    if points is not None and data is not None:
        _held_apart(data, points)
    if points is not None and (options.register_validation or data is None):
        _registrable(start, points, asked=options.register_validation)
    if held is not None and options.register_validation:
        notes.append("held-out contacts are judged by socket consistency and spacing, which do not depend on "
                     "the frame: nothing to register")
    return Inputs(model, start, data, contacts, points, held, tuple(notes) + copies)


def _registrable(model: RobotModel, points: Measurements, *, asked: bool) -> None:
    """Refuse a validation set the accuracy in use registers base and markers on (``asked``, or
    contacts alone, which fix no frame) when that registration fits every one of its equations."""
    problem = Problem(model, (), data=points, compliance=False)
    if not registration_determined(problem):
        why = "register_validation asks for" if asked else "contacts alone fix no frame, so the accuracy in use needs"
        raise DegenerateDataError(
            f"{points.source or 'the validation set'}: {why} the base and markers registered on the validation "
            f"points, and their {points.n_poses} poses give {problem.n_rows} equations, every one of which that "
            "registration fits: it would absorb every error; give more validation poses"
            + (", or leave register_validation off" if asked else ""))


def _rows_as_bytes(d: Measurements) -> np.ndarray:
    """Each pose's readings and measured values as one comparable item."""
    rows = np.ascontiguousarray(np.hstack([d.q, np.nan_to_num(d.positions.reshape(d.n_poses, -1), nan=1e300)]) + 0.0)
    return rows.view(np.dtype((np.void, rows.dtype.itemsize * rows.shape[1]))).ravel()


# a held-out pose repeats a fitted one when its readings are within this of the fitted one's (rad or m)
# and its measured values within REPEAT_POSITION (m): a copy written with fewer digits, not a pose
# measured again (which differs by the instrument's noise, tens of micrometres)
REPEAT_READING = 2e-5
REPEAT_POSITION = 5e-6


def repeated_in(fitted: Measurements, held: Measurements) -> np.ndarray:
    """(n_held,) whether each held-out pose repeats a fitted one (readings and measured values, exactly
    or to the rounding of a copy: ``REPEAT_READING``, ``REPEAT_POSITION``)."""
    from scipy.spatial import cKDTree

    if fitted.q.shape[1] != held.q.shape[1] or fitted.positions.shape[1:] != held.positions.shape[1:]:
        return np.zeros(held.n_poses, dtype=bool)
    exact = np.isin(_rows_as_bytes(held), _rows_as_bytes(fitted))
    if exact.all() or not len(fitted.q):
        return exact
    dist, near = cKDTree(fitted.q).query(held.q, distance_upper_bound=REPEAT_READING * np.sqrt(held.q.shape[1]))
    close = np.isfinite(dist)
    k = np.minimum(near, len(fitted.q) - 1)
    same = (held.mask == fitted.mask[k]).all(axis=1)
    gap = np.where(held.mask[..., None], np.abs(held.positions - fitted.positions[k]), 0.0).max(axis=(1, 2))
    return exact | (close & same & (gap <= REPEAT_POSITION))


def _held_apart(data: Measurements, validation: Measurements) -> None:
    """Refuse a validation set whose every pose is a fitted one: nothing would be held out."""
    if repeated_in(data, validation).all():
        raise InputError(f"every one of its {validation.n_poses} poses repeats a fitted pose (readings and measured "
                         "values, to the digits a copy keeps): nothing is held out; give poses the fit did not see, or "
                         "leave --validation out (cross-validation)", source=validation.source or "validation",
                         where="validation")


def without_copies(data: Measurements) -> tuple[Measurements, tuple[str, ...]]:
    """``data`` with rows that repeat an earlier row exactly (readings and every measured value)
    counted once: a copy adds no measurement, and counting it would shrink the standard deviations
    as if it did. Repeated readings with their own measurements stay (they average the instrument's
    noise)."""
    if distinct_rows(data.q) == data.n_poses:
        return data, ()
    first = first_equal_rows(np.hstack([data.q, np.nan_to_num(data.positions.reshape(data.n_poses, -1), nan=1e300),
                                        data.mask.astype(float)]))
    kept = None if first is None else np.flatnonzero(first == np.arange(data.n_poses))
    if kept is None or len(kept) == data.n_poses:     # projections may tie where no row repeats
        return data, ()
    return data.with_approach().subset(kept), (
        f"{data.n_poses - len(kept)} of {data.n_poses} rows repeat an earlier row exactly (readings and measurements): "
        "counted once",)


def distinct_rows(q: np.ndarray) -> int:
    """The number of distinct rows of ``q``."""
    first = first_equal_rows(q)
    return len(q) if first is None else int(np.count_nonzero(first == np.arange(len(q))))


# -- what the data identify ------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class Analysis:
    """What the data can identify, before asking what they can pin down: the problem over the
    candidates, its analysis, what the structure allows but these poses lose (``lost``), what each
    kind of observation reaches (with contacts) and what was noted."""

    problem: Problem
    stack: StackAnalysis
    lost: tuple[str, ...]
    compliance: bool
    reach: ContactIdentifiability | None
    notes: tuple[str, ...] = ()
    # the weak parameters among every identifiable one, by the scatter they were judged at (and the
    # floor kept): the model choice's all-free design names those its first design judged there
    weak_at: dict = field(default_factory=dict, repr=False)

    @property
    def identifiability(self) -> IdentifiabilityResult:
        return self.stack.result


def observed_markers(data: Measurements | None, contacts: Contacts | None) -> tuple[str, ...]:
    """The markers some observation sees."""
    seen = [] if data is None else [n for j, n in enumerate(data.marker_names) if data.mask[:, j].any()]
    return tuple(dict.fromkeys(seen + ([] if contacts is None else list(contacts.marker))))


def analyse(inputs: Inputs, options: Options) -> Analysis:
    """Which candidates the data can identify; data that cannot determine them refused."""
    start, data, contacts = inputs.start, inputs.data, inputs.contacts
    orientation = data is not None and data.has_orientation
    seen = set(observed_markers(data, contacts))
    lay = parameter_layout(start)
    unseen = tuple(p.name for p in lay.parameters if p.role == "marker" and p.owner not in seen)
    known = options.known + unseen
    names = candidate_parameters(start, options.parameters, orientation=orientation, known=known)
    notes = [f"parameters {p!r} matched: {', '.join(m)}" for p, m in matched_by_pattern(start, options.parameters,
                                                                                      orientation=orientation)]
    compliance = needs_compliance(start, names)
    problem = Problem(start, names, data=data, contacts=contacts, compliance=compliance, noise=options.noise)
    theory = None
    if data is not None and contacts is None:        # what a measured point's structure allows
        measured = tuple(n for n in data.marker_names if n in seen)
        theory = theoretical_identifiability(start, options.parameters, known, orientation, options.tol, measured)
        notes += _enough_poses(problem, data, len(theory.identified))
    if contacts is not None:
        notes += _repeated_contacts(contacts)
    p0 = problem.start_vector()
    stack = analyse_stack(problem, names, p0, tol=options.tol)
    if not stack.result.identified:
        raise DegenerateDataError(f"no robot parameter is identifiable from these data ({problem.n_rows} rows)")
    lost = () if theory is None else tuple(n for n in theory.identified if n not in stack.result.identified
                                           and n in names)
    reach = kinds_reach(problem, stack, p0) if contacts is not None else None
    return Analysis(problem, stack, lost, compliance, reach, tuple(notes))


def _points_move(data: Measurements) -> None:
    """Refuse a marker whose every measured point is the same while the joints move: no robot puts it
    there, and a fit would bend the geometry into nonsense."""
    for m, name in enumerate(data.marker_names):
        rows = np.flatnonzero(data.mask[:, m])
        if len(rows) < 2 or distinct_rows(data.q[rows]) < 2:
            continue
        points = data.positions[rows, m]
        if np.all(points == points[0]):
            x, y, z = (float(v) for v in points[0])
            raise DegenerateDataError(
                f"every measured point of marker {name} is the same ({x:.6g}, {y:.6g}, "
                f"{z:.6g} m) on {len(rows)} poses whose joints move: the instrument repeated one reading (it lost "
                "the target?), or the tool was held at one point (a pivot: give those poses as contacts of one "
                "socket, --contacts)")


def _repeated_contacts(contacts: Contacts) -> list[str]:
    """Note contact rows whose joint readings repeat an earlier row's exactly: seatings by hand never
    repeat to the encoder count, so they are copied rows, counted as if they added information."""
    n = len(contacts.q)
    repeats = n - distinct_rows(contacts.q)
    if not repeats:
        return []
    return [f"{repeats} of {n} contact rows repeat an earlier row's joint readings exactly: copied rows (a seating "
            "by hand never repeats to the encoder count); they add no information, yet the fit counts them as if "
            "they did (its standard deviations are then too small): remove them"]


def _enough_poses(problem: Problem, data: Measurements, needed: int) -> list[str]:
    """Refuse measured points whose distinct poses give too few equations; note repeated poses."""
    n_unique = distinct_rows(data.q)
    distinct = problem.n_rows * n_unique // data.n_poses
    if distinct <= needed:
        rows_per_pose = 3 * (1 + int(data.has_orientation))
        raise DegenerateDataError(
            f"{data.n_poses} poses ({n_unique} distinct) give {distinct} equations for {needed} identifiable "
            f"parameters; at least {needed // rows_per_pose + 1} distinct poses are needed, and several times "
            "that for a useful estimate")
    if n_unique < data.n_poses:
        return [f"{data.n_poses - n_unique} of {data.n_poses} poses repeat an earlier joint configuration "
                f"exactly: they average noise but add no information{_repeat_gap(data)}"]
    return []


def _repeat_gap(data: Measurements) -> str:
    """How far apart the points of poses with equal readings lie at most (the model puts them at one
    place: what separates them is the robot's repeatability, drift or a wrong row), in words."""
    first = first_equal_rows(data.q)
    if first is None:
        return ""
    again = np.flatnonzero(first != np.arange(data.n_poses))
    both = data.mask[again] & data.mask[first[again]]
    gap = np.where(both, vector_norms(data.positions[again] - data.positions[first[again]]), -1.0).max(axis=1)
    if not (gap >= 0).any():
        return ""
    k = int(np.argmax(gap))
    a, b = (data.labels[i] if data.labels else f"pose {i}" for i in (int(first[again[k]]), int(again[k])))
    return (f"; their points lie up to {gap[k] * 1e3:.4g} mm apart ({a} and {b}): the robot's repeatability and "
            "drift, or a wrong row when far beyond them")


# -- what the data pin down -----------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class Design:
    """One model choice: the start, the problem over the parameters it frees, and what the structure
    allows but these poses lose (``lost``) or cannot pin down (``weak``: found, and held at nominal
    unless ``weak_kept``). ``judged_at``: the scatter (the rows' units) weak parameters were judged at."""

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


def in_metres(problem: Problem) -> bool:
    """Whether the problem's rows are metres (measured points alone, stating no deviation) rather
    than standard deviations."""
    return problem.contacts is None and problem.points is not None and not problem.points.weighted


def row_noise(problem: Problem, noise: Noise, limit_m: float | None) -> float:
    """The scatter a good fit leaves, in the rows' units: the instrument's noise (with a limit of
    absolute accuracy, the robot's own beside it) in metres, or in the rows' stated deviations."""
    expected = expected_noise(noise, limit_m)[0]
    if in_metres(problem):
        return expected
    if problem.contacts is None:
        return expected / noise.position
    typical = float(np.median(problem.contacts.contacts.sigma))
    robot = 0.0 if limit_m is None else limit_m / MEAN_NORM_PER_SIGMA
    return float(np.hypot(1.0, robot / typical))


def pin_down(analysis: Analysis, noise: Noise, limit_m: float | None, *, eliminate: bool, scatter: float = 0.0,
             problem: Problem | None = None, floor: tuple[str, ...] = ()) -> Design:
    """The design over what the data can also pin down at the expected scatter (or at ``scatter``,
    the rows' units, when the fit showed more); with ``eliminate`` False every identifiable
    parameter stays free (the weak ones named). ``problem``: the observations to fit (default the
    analysis', e.g. with some set aside); ``floor``: parameters kept whatever their scatter."""
    prob = analysis.problem if problem is None else problem
    sigma = max(row_noise(prob, noise, limit_m), scatter)
    ident, weak_found = weak_parameters(analysis, sigma, eliminate=eliminate, floor=floor)
    if not ident.identified:
        raise DegenerateDataError("no parameter is identifiable from these data")
    free = prob.over(ident.identified)
    if free.n_rows <= len(free.free_idx):
        more = f" and {free.n_nuisance} unknowns of points and planes" if free.n_nuisance else ""
        raise DegenerateDataError(f"{free.n_rows} equations for {len(ident.identified)} parameters{more}")
    start = analysis.problem.model
    return Design(start=start, p0=analysis.problem.start_vector(), problem=free, identifiability=ident,
                  compliance=analysis.compliance, lost=analysis.lost, weak=weak_found, weak_kept=not eliminate,
                  judged_at=sigma)


def weak_parameters(analysis: Analysis, sigma: float, *, eliminate: bool, floor: tuple[str, ...] = ()):
    """The analysis with weakly identifiable parameters eliminated (or only named) at a scatter
    ``sigma`` (the rows' units), and those parameters with their predicted standard deviations.
    Eliminating one may let an equivalent one in (a member of the same dependent group): the
    analysis repeats until none is weak. The robot's columns are judged once what the nuisance
    parameters absorb is taken out of them. Parameters of ``floor`` are kept unjudged (one the
    analysis found a combination of others takes the place of one of those), the others judged
    beside them."""
    prob, J, names = analysis.problem, analysis.stack.J, analysis.stack.names
    lay = parameter_layout(prob.model)
    quantities = [lay[n].quantity for n in names]
    column = {n: k for k, n in enumerate(names)}
    moments = None
    ident = analysis.identifiability
    dropped = _giving_way(ident, floor)
    said: list[tuple[str, str]] = []
    result = eliminate_parameters(ident, J, names, quantities, dropped, n_rows=prob.n_rows) if dropped else ident
    while True:
        cols = [column[n] for n in result.identified]
        found = analysis.weak_at.get((sigma, floor)) if result is ident else None
        if found is None:
            moments = prob.compliance_moments(prob.start_vector()) if moments is None else moments
            found = weakly_identifiable(J[:, cols], result.identified, [quantities[k] for k in cols], sigma,
                                        moments=moments, floor=floor)
            if result is ident:
                analysis.weak_at[(sigma, floor)] = found
        said += weak_words(found, lay)
        if not found or not eliminate:
            return result, tuple(said)
        if {n for n, _, _, _ in found} | set(dropped) >= set(ident.identified):
            raise DegenerateDataError(f"no parameter can be pinned down at a scatter of {_scatter_text(prob, sigma)}")
        dropped.update({n: "is weakly identifiable: " + (f"predicted std {effect_text(e, lay[n].quantity)} exceeds "
                           if by == n else f"with it, {by}'s predicted std {effect_text(e, lay[by].quantity)} exceeds ")
                        + effect_text(b, lay[by].quantity) for n, by, e, b in found})
        result = eliminate_parameters(ident, J, names, quantities, dropped, n_rows=prob.n_rows)


def _giving_way(ident: IdentifiabilityResult, floor: tuple[str, ...]) -> dict[str, str]:
    """Identified parameters that give way to a parameter of ``floor`` the analysis found a combination
    of them (a member of the same dependent group, preferred by an identification it is nested on):
    for each, the first other one of its combination."""
    out: dict[str, str] = {}
    for a in ident.eliminated:
        other = next((n for n, _ in a.absorbers if n not in floor and n not in out), None) if a.name in floor else None
        if other is not None:
            out[other] = "is a combination of identified parameters"
    return out


def _scatter_text(problem: Problem, sigma: float) -> str:
    return f"{sigma * 1e3:.3g} mm" if in_metres(problem) else f"{sigma:.3g} stated deviations"


# -- fitting, outliers and the model choice -------------------------------------------------------

@dataclass(frozen=True, eq=False)
class Outliers:
    """What stood out in a fit: one check per kind, and over ``observations`` of the first fit's
    problem, those beyond the bar (``out``), beyond ``GROSS_FACTOR`` times it (``gross``: those a
    refit may set aside), of those the ones standing apart from the rest of the scores (``apart``:
    blunders by their scores alone, when no refit judges them), in runs of consecutive poses or rows
    (``runs``) and carrying a quantity alone (``alone``)."""

    checks: tuple[Check, ...]
    out: np.ndarray
    gross: np.ndarray
    apart: np.ndarray
    runs: np.ndarray
    alone: np.ndarray
    kinds: tuple[np.ndarray, ...] = ()


@dataclass(frozen=True, eq=False)
class Fit:
    """A design solved on ``problem`` (observations set aside taken out), what stood out among the
    observations of the design's own problem (``outliers``; ``aside`` those set aside), its held-out
    errors and what it noted."""

    design: Design
    problem: Problem
    solution: Solution
    outliers: Outliers
    aside: np.ndarray
    held_out: HeldOut
    groups: np.ndarray
    notes: tuple[str, ...] = ()

    def steady(self) -> np.ndarray:
        """(n_observations,) the observations a model choice is judged on: fitted, not standing out,
        and held out in some group."""
        keep = ~self.aside if self.aside.any() else ~self.outliers.out
        return keep & (self.groups >= 0)


def solve_design(design: Design, problem: Problem, options: Options, start: np.ndarray,
                 tol: float = SOLVER_TOL) -> Solution:
    """``problem`` (the design's, or with observations set aside) solved from ``start`` (a full
    vector) to the solver's tolerance ``tol``: compliances kept >= 0 if asked, and under a robust
    loss the rows that alone carry a quantity kept linear (nothing else could outvote them)."""
    lower = None
    if options.nonnegative_compliance:
        lay = parameter_layout(design.start)
        lower = np.r_[[0.0 if lay[n].family == "compliance" else -np.inf for n in problem.free_names],
                      np.full(problem.n_nuisance, -np.inf)]
    linear = None
    if options.loss != "linear" and not problem.chunked:
        kept = alone_observations(problem, design.p0) | together(problem)
        rows = kept[problem.row_observations()]
        linear = rows if rows.any() else None
    return solve(problem, start, loss=options.loss, f_scale=options.f_scale, max_nfev=options.max_nfev,
                 lower=lower, linear_rows=linear, tol=tol)


def warm_start(first: Fit, design: Design) -> np.ndarray:
    """Where ``design``, another model choice on the first fit's observations, is solved from: when
    it frees every parameter the first did and more, under the linear loss, where the first fit took
    its last Jacobian (a tolerance from its solution: that evaluation and those columns are kept,
    and its minimum is nearer there than at the nominal); else the design's own start (the nominal,
    whose Jacobian the analysis made)."""
    sol = first.solution
    if sol.loss != "linear" or not set(first.problem.free_idx.tolist()) < set(design.problem.free_idx.tolist()):
        return design.p0
    return sol.p if sol.jacobian_at is None else sol.jacobian_at


def find_outliers(problem: Problem, solution: Solution, noise: Noise) -> Outliers:
    """Each kind's observations that stand out (``outlier_check``: a kind's scale is at least its
    stated deviation, so a kind of a single row is no outlier by construction), those far beyond,
    in runs, or carrying a quantity alone."""
    obs = problem.observations()
    n = len(obs)
    out, gross, alone = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
    standing = np.zeros(n, dtype=bool)
    checks, kinds = [], []
    for kind, (errors, sigma, index) in problem.observation_errors(solution.p).items():
        labels = obs.label.taken(index)
        check, o = outlier_check(errors, sigma, noise, labels)
        checks.append(check if kind == "tracker" else replace(check, name=f"outliers among the {kind} contacts"))
        kinds.append(index)
        out[index] = o
        if o.any():       # else none is gross or apart either
            scores, bar = outlier_scores(errors, sigma, noise), outlier_bar(len(o))
            gross[index] = o & (scores > GROSS_FACTOR * bar)
            standing[index] = o & apart(scores, bar)
    if out.any():
        alone = alone_observations(problem, solution.p)
    runs = np.zeros(n, dtype=bool)
    for kind in obs.kinds():
        sel = obs.of(kind) & out
        runs[sel] = in_runs(obs.order[sel])
    return Outliers(tuple(checks), out, gross, standing, runs, alone, tuple(kinds))


# a group of observations (a measured marker, a socket, a plane, a known distance) this small may hold
# one that alone fixes a quantity of the fit; larger ones are not searched (their rows share the work)
SMALL_GROUP = 20

# the evaluations a design solved only to be compared with the first fit gets (warm-started there, it
# converges in tens): a design the data barely determine can crawl on for thousands, and its
# held-out error would then judge where it stopped rather than a fit
COMPARED_NFEV = 100
# ... and the solver's tolerance it is solved to: its held-out error comes from one Gauss-Newton step
# of each fold from it, which lands about where a fully converged start would (docs/checks.md); the
# design chosen is then solved on to the solver's own tolerance
COMPARED_TOL = 1e-6


def alone_observations(problem: Problem, p: np.ndarray) -> np.ndarray:
    """(n_observations,) the observations (of groups of at most ``SMALL_GROUP``) one of whose rows
    alone carries a direction of the parameters at the full vector ``p`` (``carried_alone``): the
    only known distance fixing the scale, the only points of a marker."""
    groups = problem.observation_groups()
    out = np.zeros(len(groups), dtype=bool)
    fitted = np.zeros(len(groups), dtype=bool)
    row_obs = problem.row_observations()
    fitted[row_obs] = True
    sizes = np.bincount(groups[fitted], minlength=groups.max() + 1 if len(groups) else 0)
    small = fitted & (sizes[groups] <= SMALL_GROUP) if len(groups) else out
    if problem.chunked or not small.any():
        return out
    rows = small[row_obs]
    flags = carried_alone(problem.jacobian(p), rows)
    out[np.unique(row_obs[rows][flags])] = True
    return out


def together(problem: Problem) -> np.ndarray:
    """(n_observations,) those of the kinds whose rows carry the scale together (``TOGETHER``)."""
    return np.array([k in TOGETHER for k in problem.observations().kind], dtype=bool)


def apart(scores: np.ndarray, bar: float) -> np.ndarray:
    """Scores of blunders: beyond ``GROSS_FACTOR`` times the bar and apart from the rest: with no
    score between the bar and that, every one; else only those ``BLUNDER_SEPARATION`` times past the
    largest of them (a continuous tail from the bar on is an effect the model leaves out)."""
    gross = scores > GROSS_FACTOR * bar
    tail = (scores > bar) & ~gross
    if not tail.any():
        return gross
    return gross & (scores > BLUNDER_SEPARATION * float(scores[tail].max()))


def in_runs(order: np.ndarray) -> np.ndarray:
    """For sorted pose (or row) indices, whether each lies in a run of at least ``OUTLIER_RUN``
    consecutive ones."""
    if not len(order):
        return np.zeros(0, dtype=bool)
    poses = np.unique(order)
    start = np.r_[True, np.diff(poses) != 1]
    run_id = np.cumsum(start) - 1
    length = np.bincount(run_id)[run_id]
    long_ = dict(zip(poses, length >= OUTLIER_RUN))
    return np.array([long_[r] for r in order], dtype=bool)


def fit(design: Design, options: Options, holdout: Holdout, folds: FoldProblems, *,
        outliers: Fit | None = None, start: np.ndarray | None = None, tol: float = SOLVER_TOL) -> Fit:
    """``design`` solved and its observations held out in turn. With the linear loss and
    ``on_outliers="refit"``, observations that stand out alone (not in runs, which are systematic,
    and not carrying a quantity alone) are set aside and the design fitted again without them, kept
    when its held-out loss on every observation is not higher (the model is then the one the
    observations' deletion gives). ``outliers``: a fit whose outliers stand (a design fitted on the
    observations it left); ``start``: the full vector its solve starts from (default the design's);
    ``tol``: the solver's tolerance."""
    problem = design.problem
    solution = solve_design(design, problem, options, design.p0 if start is None else start, tol)
    held = cross_validate(problem, solution.p, holdout, folds=folds, at=solution.jacobian_at)
    groups = holdout.groups
    if outliers is not None:      # fitted on what that fit left: its outliers and their notes stand
        return Fit(design, problem, solution, outliers.outliers, outliers.aside, held, groups, outliers.notes)
    found = find_outliers(problem, solution, options.noise)
    none = np.zeros(len(found.out), dtype=bool)
    if not found.out.any():
        return Fit(design, problem, solution, found, none, held, groups)
    return _set_aside(design, solution, found, held, options, holdout, folds)


def _set_aside(design: Design, solution: Solution, found: Outliers, held: HeldOut, options: Options,
               holdout: Holdout, folds: FoldProblems) -> Fit:
    """The outliers of a first fit handled: named, or set aside and refitted where that helps."""
    problem, obs = design.problem, design.problem.observations()
    none = np.zeros(len(found.out), dtype=bool)
    share_max = max((float(found.out[obs.of(k)].mean()) for k in obs.kinds()), default=0.0)
    if share_max > OUTLIER_SHARE_MAX:
        checks = tuple(replace(c, status="warn", cause="so many that the data do not fit the model as it is: "
                               "unmodelled effects or a mistake (see the other checks)", fix="read the diagnosis; a "
                               "robust loss would hide the misfit") if c.status != "pass" else c for c in found.checks)
        return Fit(design, problem, solution, replace(found, checks=checks), none, held, holdout.groups)
    out = found.out
    # candidates: far beyond the bar; whether they are blunders, the refit's cross-validated error says
    blunder = out & ~found.runs & found.gross & ~found.alone & ~together(problem)
    judged = bool((holdout.groups >= 0).any())
    if not judged:          # nothing held out to judge a refit by: blunders by their scores alone
        blunder &= found.apart
    notes = _outlier_notes(problem, found)
    if not blunder.any() or options.loss != "linear" or options.on_outliers != "refit":
        return Fit(design, problem, solution, _outlier_status(found), none, held, holdout.groups, notes)
    kept = problem.without(blunder)
    again = replace(design, problem=kept)
    solution2 = solve_design(again, kept, options, again.p0)
    # judged on every observation, those set aside too (predicted without them): blunders are no
    # better predicted either way, while observations whose only fault is an effect the model leaves
    # out are predicted worse once their like are set aside
    held2 = cross_validate(kept, solution2.p, holdout, on=problem, folds=folds, at=solution2.jacobian_at)
    mask = problem.point_mask
    excess, se = paired_excess(held2.observation_norms(mask), held.observation_norms(mask), holdout.groups >= 0)
    if judged and not excess < -REFIT_GAIN_SIGMAS * se:
        notes += (f"{int(blunder.sum())} point(s) far beyond the outlier bar; setting them aside did not lower the "
                  f"cross-validated error of the points by {REFIT_GAIN_SIGMAS:g} standard errors, so they stay in "
                  "the fit",)
        return Fit(design, problem, solution, _outlier_status(found), none, held, holdout.groups, notes)
    notes += (f"{int(blunder.sum())} outlier(s) set aside and the calibration fitted again without them",)
    return Fit(again, kept, solution2, _outlier_status(found, blunder), blunder, _masked(held2, kept),
               holdout.groups, notes)


def _masked(held: HeldOut, kept: Problem) -> HeldOut:
    """Held-out errors with the observations set aside blanked (NaN errors, no loss)."""
    if kept.points is None:
        return held
    m = kept.points.data.mask
    return replace(held, positions=np.where(m[..., None], held.positions, np.nan),
                   rotations=None if held.rotations is None else np.where(m[..., None], held.rotations, np.nan),
                   loss=np.where(m, held.loss, 0.0))


def _outlier_notes(problem: Problem, found: Outliers) -> tuple[str, ...]:
    obs = problem.observations()
    notes = []
    runs = found.out & found.runs
    if runs.any():
        idx = np.nonzero(runs)[0]
        first, last = obs.label[idx[0]].split(",")[0], obs.label[idx[-1]].split(",")[0]
        said = first if len(np.unique(obs.order[idx])) == 1 else f"{first} to {last}"
        notes.append(f"{int(runs.sum())} point(s) standing out in runs of consecutive poses ({said}): a systematic "
                     "error, not blunders; kept in the fit")
    tail = found.out & ~found.gross
    if tail.any():
        notes.append(f"{int(tail.sum())} point(s) beyond the outlier bar but within {GROSS_FACTOR:g} times it: the "
                     "tail of an effect the model leaves out as much as blunders; kept in the fit")
    alone = found.out & found.gross & found.alone
    if alone.any():
        notes.append(f"{int(alone.sum())} outlier(s) alone fix a quantity of the fit (setting them aside would leave "
                     "it free): kept in the fit")
    return tuple(notes)


def _outlier_status(found: Outliers, aside: np.ndarray | None = None) -> Outliers:
    """The outlier checks once their observations are handled. Blunders warn, set aside or kept:
    those a refit set aside because that lowered the cross-validated error (``aside``), else those
    standing apart from the rest of the scores (``Outliers.apart``), not in a run. Points in the
    tail or in runs of consecutive poses are named and kept: the tail and the runs of effects the
    model leaves out (an elastic arm's extreme poses, a drift), which the accuracy in use judges."""
    checks = []
    for c, index in zip(found.checks, found.kinds or (np.arange(len(found.out)),) * len(found.checks)):
        out = found.out[index]
        if c.status == "pass" or not out.any():
            checks.append(c)
            continue
        blunders = (found.apart & ~found.runs if aside is None else aside)[index][out]
        runs = found.runs[index][out]
        if not blunders.any():
            said = ("in runs of consecutive poses (an effect that changes along the campaign: a drift, a payload)"
                    if runs.all() else "in a tail that runs on from the bar or in runs: effects the model leaves "
                    "out rather than blunders")
            checks.append(replace(c, status="pass", summary=c.summary + f"; {said}, kept in the fit", cause="",
                                  fix=""))
        else:
            said = "; set aside, and the calibration fitted again without them" if aside is not None else \
                "; kept in the fit"
            checks.append(replace(c, status="warn", summary=c.summary + said,
                                  fix="check those measurements; the result is the one their deletion gives"
                                  if aside is not None
                                  else "check those measurements; remove them, or calibrate with --on-outliers refit"))
    return replace(found, checks=tuple(checks))


def scatter(f: Fit) -> float:
    """The RMS residual per axis of the observations fitted and not standing out, in the rows'
    units (m for measured points alone, else stated deviations)."""
    keep = ~f.aside if f.aside.any() else ~f.outliers.out
    parts = []
    metres = in_metres(f.problem)
    errors = f.problem.observation_errors(f.solution.p)
    for kind, (e, s, index) in errors.items():
        sel = keep[index]
        if kind == "tracker" and not metres:
            s = np.full(len(e), f.problem.noise.position if f.problem.noise is not None else 1.0) if s is None else s
        parts.append((e[sel] if metres else e[sel] / s[sel, None]).ravel())
    r = np.concatenate(parts) if parts else np.zeros(0)
    r = r[np.isfinite(r)]
    return float(np.sqrt(np.mean(r ** 2))) if r.size else 0.0


def choose(analysis: Analysis, options: Options, holdout: Holdout, folds: FoldProblems) -> tuple[Fit, tuple[str, ...]]:
    """The model choice the held-out observations support.

    The first design holds weakly identifiable parameters at nominal (judged at the expected
    scatter: the instrument's, and the robot's own with a limit); it is fitted, and observations that
    stand out are set aside when that helps (``fit``). Two more designs are then fitted on the same
    observations where they differ from it: every identifiable parameter free, and weak parameters
    judged again at the scatter the fit shows when it is well above the expected one. Of the
    designs, simplest first, the first whose held-out loss is within one standard error of the best
    one's is chosen: a stated noise, a limit or stated deviations hold back parameters only where
    that costs nothing in use. With ``weak="flag"`` every identifiable parameter is kept.
    """
    eliminate = options.weak == "eliminate"
    noise, limit_m = options.noise, options.limit_m
    floor = options.floor
    first = fit(pin_down(analysis, noise, limit_m, eliminate=eliminate, floor=floor), options, holdout, folds)
    if not eliminate:
        return first, ()
    used = first.problem
    designs = []
    seen_scatter = scatter(first)
    if seen_scatter > FIT_RATIO * row_noise(used, noise, limit_m):
        with contextlib.suppress(DegenerateDataError):   # nothing pinned down at that scatter: the fit stands
            designs.append(pin_down(analysis, noise, limit_m, eliminate=True, scatter=seen_scatter, problem=used,
                                    floor=floor))
    designs.append(first.design)
    if analysis.identifiability.identified != first.design.identifiability.identified:   # else it is the first
        designs.append(pin_down(analysis, noise, limit_m, eliminate=False, problem=used, floor=floor))
    return _simplest(first, designs, options, holdout, folds)


def _simplest(first: Fit, designs: list, options: Options, holdout: Holdout, folds: FoldProblems):
    """Of ``designs`` (simplest first), the first within one standard error of the best held-out loss.
    A design other than the first is solved to ``COMPARED_TOL`` within ``COMPARED_NFEV`` evaluations
    (or the ``max_nfev`` given) and left out of the choice, with a note, when it has not converged by
    then; chosen, it is solved on from there to the solver's tolerance."""
    fits, seen, stopped = [], {}, []
    budget = COMPARED_NFEV if options.max_nfev is None else options.max_nfev
    for d in designs:
        key = d.identifiability.identified
        if key in seen:
            continue
        if d is first.design or key == first.design.identifiability.identified:
            seen[key] = first
        else:
            seen[key] = fit(d, replace(options, on_outliers="flag", max_nfev=budget), holdout, folds, outliers=first,
                            start=warm_start(first, d), tol=COMPARED_TOL)
            if not seen[key].solution.success:
                stopped.append(f"the {len(key)}-parameter design did not converge within {budget} evaluations of "
                               "the residuals: left out of the model choice")
                continue
        fits.append(seen[key])
    if len(fits) == 1:
        return first, tuple(stopped)
    mask = first.steady()
    pm = first.design.problem.point_mask
    loss = {id(f): f.held_out.observation_loss(pm) for f in fits}
    best = min(fits, key=lambda f: float(loss[id(f)][mask].mean()))
    for f in fits:
        excess, se = paired_excess(loss[id(f)], loss[id(best)], mask)
        if excess <= se:
            break
    count = {id(g): len(g.design.identifiability.identified) for g in fits}
    rms = {id(g): float(np.sqrt(np.nanmean(g.held_out.observation_norms(pm)[mask] ** 2))) for g in fits}
    said = "; ".join(f"{count[id(g)]} parameters: {rms[id(g)] * 1e3:.4g} mm" for g in fits)
    note = (f"model choice by cross-validated error (RMS held out): {said}; kept the {count[id(f)]} parameters, "
            "the simplest within one standard error of the best")
    if f is not first:
        f = fit(f.design, replace(options, on_outliers="flag"), holdout, folds, outliers=first, start=f.solution.p)
    if f.design.weak_kept:
        f = replace(f, design=replace(f.design, kept_in_use=True))
    return f, (note, *stopped)


# -- after the fit -------------------------------------------------------------------------------

def registered_nominal(design: Design) -> tuple[np.ndarray, np.ndarray | None, tuple[str, ...]]:
    """The parameter vector errors "before" are taken at: the nominal geometry, with the base and
    marker parameters being identified fitted to the data first (a raw base guess says nothing
    about the robot), where that fit took its last Jacobian (``Solution.jacobian_at``: None when
    nothing was fitted or at the vector itself), and what that noted. For a fit of the base and
    markers alone that is the calibration itself: the robot's kinematics are unchanged."""
    lay = parameter_layout(design.start)
    free = design.identifiability.identified
    placed = tuple(n for n in free if lay[n].family in ("base", "markers"))
    if not placed:
        return design.p0, None, ()
    sol = solve(design.problem.over(placed), design.p0, tol=REGISTRATION_TOL)
    if len(placed) == len(free):
        return sol.p, sol.jacobian_at, (
            "only the base and markers are identified: a registration; errors before calibration are those of the "
            "same registration, the robot's kinematics are unchanged",)
    return sol.p, sol.jacobian_at, ("errors before calibration are those of the nominal geometry with its base and "
                                    f"markers fitted to the data ({', '.join(placed)})",)


def placed_parameters(design: Design) -> tuple[str, ...]:
    """The identified base and marker parameters: a registration, not the robot's kinematics."""
    lay = parameter_layout(design.start)
    return tuple(n for n in design.identifiability.identified if lay[n].family in ("base", "markers"))


def placed_on(problem: Problem) -> Problem:
    """``problem`` over the base and the markers its points measure: what a registration on them fits."""
    lay = parameter_layout(problem.model)
    measured = set(problem.points.data.marker_names) if problem.points is not None else set()
    return problem.over(tuple(n for n in lay.names if lay[n].family == "base" or (lay[n].role == "marker" and
                                                                                  lay[n].owner in measured)))


def registration_determined(problem: Problem) -> bool:
    """Whether a registration on ``problem``'s points (``placed_on``) leaves some of their equations
    unabsorbed (``registration_freedom``). Else the registration fits every error, whatever the model."""
    taken, rows = registration_freedom(problem)
    return taken < rows


def registration_freedom(problem: Problem) -> tuple[int, int]:
    """(equations a registration on ``problem``'s points takes up, their number): the rank of its
    Jacobian (a point marker's turn moves nothing, so the rank, not the count of parameters), from
    its R factor (a large validation set's chunk by chunk)."""
    reg = placed_on(problem)
    return int(np.linalg.matrix_rank(reg.reduced_jacobian(reg.start_vector()))), reg.n_rows


def registered(problem: Problem, vectors: list[np.ndarray]) -> list[np.ndarray]:
    """``vectors`` with the base and the markers ``problem``'s points measure refitted on them:
    another set-up's frame, the same for every model judged there."""
    reg = placed_on(problem)
    return [solve(reg, v, tol=REGISTRATION_TOL).p for v in vectors]


def rehomed_on(problem: Problem, p: np.ndarray) -> tuple[str, float, str, np.ndarray] | None:
    """The joint whose readings, off by one constant on ``problem``'s points with the base and the
    markers they measure registered too, fit them best from the robot vector ``p``: (its name, the
    offset of its readings from its position (rad, or m), "angle" or "length", the fitted vector).
    Only joints that drive one frame alone are tried; None when there is none."""
    reg = placed_on(problem)
    model = problem.model
    C = np.asarray(model.coupling_matrix, dtype=float)
    variables = joint_variable_names(model)
    best = None
    for j, name in enumerate(model.joint_names):
        frames = np.nonzero(C[:, j])[0]
        if len(frames) != 1 or C[frames[0], j] != 1.0 or np.count_nonzero(C[frames[0]]) != 1:
            continue
        f, var = model.frames[frames[0]], variables[frames[0]]
        try:
            sol = solve(reg.over(reg.free_names + (var,)), p, tol=REGISTRATION_TOL)
        except (DegenerateDataError, np.linalg.LinAlgError, ValueError):     # this joint explains nothing here
            continue
        ssr = float(sol.residuals @ sol.residuals)
        if np.isfinite(ssr) and (best is None or ssr < best[0]):
            i = parameter_layout(model).by_name[var].index
            quantity = "length" if f.joint == "prismatic" else "angle"
            best = (ssr, name, float(p[i] - sol.p[i]), quantity, sol.p)
    return None if best is None else best[1:]


def vector_of(model: RobotModel, problem: Problem) -> np.ndarray:
    """``model``'s values as a full vector of ``problem`` (its nuisance at the start)."""
    return problem.start_vector(parameter_vector(model))
