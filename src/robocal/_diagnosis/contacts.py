"""Diagnosis of calibrations from contacts: why a fit of joint-only recordings (sockets, planes,
ball bars, known distances) is bad, tested against the recordings themselves (docs/diagnosis.md,
"Calibrations from contacts").

The conventions of ``_diagnosis``: the original fit is redone with the linear loss from the
calibrated model over the parameters it identified (the reference); each hypothesis changes the
contacts the way one mistake would have and refits from the nominal model (tracker points fitted
beside the contacts stay in every refit); its score is the base-10 logarithm of the factor by which
the refit divides the residual variance (the weighted sum of squares over its degrees of freedom:
the robot's free parameters, the socket points and planes, and the hypothesis' own freedom counted),
plus ``PLAUSIBLE_BONUS`` when the refit turns implausible changes into plausible ones. Discrete
choices (which joint, which unit, which pair) are screened by the nominal robot's misfit on the
changed contacts (the socket points and planes at their best for it, one kinematics pass) and only
the best ``REFITS`` of each are refitted.

Every residual is in its row's stated standard deviations; a finding's ``rms_before``/``rms_after``
(and the diagnosis' ``rms``) are the RMS of the contact errors in metres (a socket's per axis,
a plane's, a bar's or a distance's along it). Large campaigns are diagnosed on at most ``MAX_ROWS``
contact rows, spread evenly within each group (whole ball-bar pairs), and ``MAX_POSES`` tracker
poses: a refit then costs a fixed amount whatever the campaign's size.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from itertools import combinations
from typing import cast

import numpy as np

from .._base.arguments import accepts, both, is_a, measured_on, noise_of, optional, unobserved
from .._base.errors import DegenerateDataError, InputError, excerpt
from .._base.linalg import r_factor, solve_upper
from .._base.options import INSTRUMENT_NOISE
from .._base.threads import one_blas_thread
from .._identification.checks import outlier_bar
from .._identification.contact_blocks import ContactRows
from .._identification.estimates import ParameterEstimate
from .._identification.problem import Problem
from .._identification.registration import rigid_base as register_base
from .._identification.result import Diagnosis, Finding
from .._identification.solve import solve
from .._model.contacts import Contacts, KnownDistance
from .._model.measurements import Measurements, Noise
from .._model.parameters import needs_compliance, parameter_layout, parameter_names, parameter_vector
from .._model.robot import RobotModel
from .joints import ANGLE_FACTORS, reading_columns
from .measured import ranked
from .reference import MAX_POSES, NAMED_FACTOR, SURVIVE_FACTOR, as_noise, count_implausible

# a refit that turns implausible changes into plausible ones names its cause at a factor this many
# times (log10) smaller: a possible cause, never a decisive one (a flip the model absorbs with a
# mirrored joint fits as well, and only the changes tell)
PLAUSIBLE_BONUS = 1.0
# a refit leaving a residual variance below NOISE_FACTOR**-2 of the stated deviations' has collapsed
NOISE_FACTOR = 5.0

# diagnose at most this many contact rows (spread evenly within each group, ball bars by whole pairs)
MAX_ROWS = 2000
# a group keeps at least this many rows when a large campaign is thinned
MIN_GROUP = 3
# the solver's budget per refit
MAX_NFEV = 30
# the candidates of each discrete choice (joint, unit, pair) refitted, best screened first
REFITS = 2
# a seating is taken for another socket's when it lies this share or less of its distance from its
# own socket's point from that socket's point
NEAR_SHARE = 0.5
# at most this share of the seatings is relabelled (more is a misfit of another kind)
MOST_RELABELLED = 0.1
# a set-up split keeps at least this many of its placement's seatings on each side
MIN_SIDE = 3
# a joint's offset on one placement is screened only when at least this share of its columns' square
# norm is left once the fit's own columns (the placement's socket points among them) take theirs
ABSORBED_SHARE = 1e-6

NAMED = float(np.log10(NAMED_FACTOR))

_SOLVE_ERRORS = (DegenerateDataError, InputError, np.linalg.LinAlgError, ValueError)


@dataclass(frozen=True, eq=False)
class _Fit:
    """A fit of contacts (the reference, or a hypothesis' refit): its problem and solution, the
    weighted sum of squares over ``n_rows`` rows with ``n_free`` free parameters (robot and nuisance),
    the RMS of the residuals in stated deviations, of the contact errors in metres, and the number of
    implausible changes from the nominal model."""

    problem: Problem
    p: np.ndarray
    ssr: float
    n_rows: int
    n_free: int
    rms_sd: float
    rms: float
    implausible: int

    @property
    def variance(self) -> float:
        return max(self.ssr, 1e-300) / max(self.n_rows - self.n_free, 1)


@dataclass(frozen=True, eq=False)
class _Case:
    """What every hypothesis starts from: the nominal model, the identified parameters, the contacts
    and tracker data diagnosed, the noise, and the reference fit from the calibrated model."""

    model: RobotModel
    names: tuple[str, ...]
    contacts: Contacts
    data: Measurements | None
    noise: Noise
    compliance: bool
    fit: _Fit


# -- the shared machinery --------------------------------------------------------------------------

def _evenly(n: int, k: int) -> np.ndarray:
    """``k`` of ``n`` indices spread evenly (all of them when ``k >= n``).

    >>> _evenly(5, 3).tolist()
    [0, 2, 4]
    """
    return np.arange(n) if k >= n else np.unique(np.linspace(0, n - 1, max(k, 1)).round().astype(int))


def _thinned(contacts: Contacts, most: int = MAX_ROWS) -> Contacts:
    """``contacts`` with about ``most`` rows at most (itself when it has no more): each group keeps
    its share (at least ``MIN_GROUP`` rows) spread evenly along it, ball bars whole pairs spread
    evenly over the pairs."""
    if contacts.n_rows <= most:
        return contacts
    share = most / contacts.n_rows
    keep = []
    groups = contacts.groups()
    bars = [g for g in groups if g.kind == "bar"]
    for g in groups:
        if g.kind != "bar":
            keep.append(g.rows[_evenly(len(g.rows), max(MIN_GROUP, round(share * len(g.rows))))])
    keep += [bars[i].rows for i in _evenly(len(bars), round(share * len(bars)))] if bars else []
    return contacts.subset(np.sort(np.concatenate(keep)))


def _problem(model: RobotModel, contacts: Contacts, names: tuple[str, ...], compliance: bool,
             data: Measurements | None, noise: Noise, *, registered: bool = True) -> Problem:
    """The contact problem of ``model`` (its base registered on the tracker points when they fix it
    and ``registered``: a refit from the nominal model)."""
    if registered and data is not None and any(parameter_layout(model)[n].family == "base" for n in names):
        model = register_base(model, data)
    return Problem(model, names, data=data, contacts=contacts, compliance=compliance, noise=noise)


def _outcome(prob: Problem, p: np.ndarray, nominal: RobotModel, names) -> _Fit:
    r = prob.residuals(p)
    errors = [np.ravel(e) for kind, (e, _, _) in prob.observation_errors(p).items() if kind != "tracker"]
    e = np.concatenate(errors)
    ssr = float(r @ r)
    return _Fit(problem=prob, p=p, ssr=ssr, n_rows=len(r), n_free=len(prob.free_idx),
                rms_sd=float(np.sqrt(ssr / max(len(r), 1))), rms=float(np.sqrt(np.mean(e ** 2))) if e.size else 0.0,
                implausible=count_implausible(nominal, parameter_vector(nominal), p[:prob.n_robot], names))


@one_blas_thread
def _refit(case: _Case, contacts: Contacts) -> _Fit | None:
    """The fit of ``contacts`` (changed as a hypothesis says) from the nominal model, None when the
    changed contacts cannot be fitted, or fit better than they can be measured: a residual variance
    below ``NOISE_FACTOR``**-2 of the stated deviations' is a collapse (unknown planes fit exactly by
    points that fall on a line), not a cause."""
    try:
        prob = _problem(case.model, contacts, case.names, case.compliance, case.data, case.noise)
        sol = solve(prob, prob.start_vector(), max_nfev=MAX_NFEV)
    except _SOLVE_ERRORS:
        return None
    out = _outcome(prob, sol.p, case.model, case.names)
    return out if np.isfinite(out.ssr) and out.variance >= NOISE_FACTOR ** -2 else None


def _screen(case: _Case, contacts: Contacts) -> float:
    """The nominal robot's weighted misfit on ``contacts``, the socket points and planes at their
    best for it (one kinematics pass): cheap, to choose what to refit."""
    try:
        prob = Problem(case.model, (), contacts=contacts, compliance=case.compliance)
        r = prob.residuals(prob.start_vector())
    except _SOLVE_ERRORS:
        return np.inf
    s = float(r @ r)
    return s if np.isfinite(s) else np.inf


def _score(case: _Case, out: _Fit, freedom: float) -> float:
    """log10 of the factor by which a refit divides the residual variance, ``freedom`` more parameters
    counted, with ``PLAUSIBLE_BONUS`` when it makes the changes plausible (less when the reverse)."""
    fit = case.fit
    after = max(out.ssr, 1e-300) / max(out.n_rows - out.n_free - freedom, 1.0)
    score = float(np.log10(fit.variance / after))
    if fit.implausible and not out.implausible:
        score += PLAUSIBLE_BONUS
    elif out.implausible and not fit.implausible:
        score -= PLAUSIBLE_BONUS
    return score


def _mm(v: float) -> str:
    return f"{v * 1e3:.3g} mm"


def _found(case: _Case, out: _Fit, hypothesis: str, cause: str, how: str, freedom: float, items=(),
           fix: str = "") -> Finding:
    """A finding from a refit, its evidence the refit's residuals against the reference's."""
    fit = case.fit
    evidence = (f"refitted {how}: {out.rms_sd:.3g} against {fit.rms_sd:.3g} stated deviations RMS "
                f"({_mm(out.rms)} against {_mm(fit.rms)})")
    if fit.implausible and not out.implausible:
        evidence += f", and the {fit.implausible} implausible change(s) become plausible"
    score = _score(case, out, freedom)
    after = max(out.ssr, 1e-300) / max(out.n_rows - out.n_free - freedom, 1.0)
    # decisive when the refit alone divides the residual variance by the naming factor
    status = "fail" if fit.variance / after >= NAMED_FACTOR else "warn"
    return Finding(hypothesis, cause, evidence, score, tuple(items), fit.rms, out.rms, fix, status)


def _best_of(case: _Case, candidates: list, hypothesis: str, how: str) -> Finding | None:
    """The best finding among ``candidates`` (cause, items, changed contacts, fix): screened, the
    best ``REFITS`` refitted; each choice costs log2 of their number in freedom."""
    if not candidates:
        return None
    order = np.argsort([_screen(case, c[2]) for c in candidates], kind="stable")
    freedom = float(np.log2(len(candidates)))
    found = []
    for i in order[:REFITS]:
        cause, items, changed, fix = candidates[i]
        out = _refit(case, changed)
        if out is not None:
            found.append(_found(case, out, hypothesis, cause, how, freedom, items, fix))
    return max(found, key=lambda f: f.score, default=None)


# -- hypotheses: the joint readings ---------------------------------------------------------------

def _readings(contacts: Contacts, q: np.ndarray) -> Contacts:
    return replace(contacts, q=q)


def _scaled(contacts: Contacts, joints, factor: float) -> Contacts:
    q = contacts.q.copy()
    q[:, joints] *= factor
    return _readings(contacts, q)


def joint_sign(case: _Case) -> Finding | None:
    """A joint's readings with the wrong sign: each joint flipped, the best screened refitted."""
    names = case.model.joint_names
    return _best_of(case, [(f"joint {n}'s readings have the wrong sign", (n,), _scaled(case.contacts, [j], -1.0),
                            f"reverse the sign of joint {n}'s readings (or its direction in the model)")
                           for j, n in enumerate(names)], "joint sign", "with its sign flipped")


def unit_factor(case: _Case) -> Finding | None:
    """Angle readings in degrees read as radians or the reverse (``ANGLE_FACTORS``): every angle
    joint alone and all together, the best screened refitted."""
    angles = [j for j, k in enumerate(case.model.reading_quantities) if k == "angle"]
    groups = ([angles] if len(angles) > 1 else []) + [[j] for j in angles]
    cands = []
    for f, why in ANGLE_FACTORS.items():
        for g in groups:
            joints = tuple(case.model.joint_names[j] for j in g)
            cands.append((f"joint readings of {', '.join(joints)}: {why}", joints, _scaled(case.contacts, g, 1.0 / f),
                          "declare the unit of those columns (e.g. j1_deg) and calibrate again"))
    return _best_of(case, cands, "unit factor", "in that unit")


def joints_swapped(case: _Case) -> Finding | None:
    """Two joint columns of the same kind swapped: every pair, the best screened refitted."""
    kinds = case.model.reading_quantities
    cands = []
    for a, b in combinations(range(case.model.n_joints), 2):
        if kinds[a] != kinds[b]:
            continue
        q = case.contacts.q.copy()
        q[:, [a, b]] = q[:, [b, a]]
        na, nb = case.model.joint_names[a], case.model.joint_names[b]
        cands.append((f"the columns of joints {na} and {nb} are swapped", (na, nb), _readings(case.contacts, q),
                      f"swap the columns of joints {na} and {nb}"))
    return _best_of(case, cands, "joints swapped", "with them swapped back")


@one_blas_thread
def joint_rehomed(case: _Case) -> Finding | None:
    """One joint's readings off by a constant on one placement (rehomed, or its encoder slipped,
    between placements): every placement and joint screened at once by one Gauss-Newton step on
    the reference fit's residuals (what its own parameters cannot take up), the best refitted with
    that placement's readings corrected. A joint whose offset the placement's free socket points
    take up whole (a turn about the vertical first axis) is not tested."""
    c, fit = case.contacts, case.fit
    placements = c.placements()
    if len(placements) < 2:
        return None
    prob = fit.problem
    obs = prob.observations()
    rows_of = np.asarray(obs.placement, dtype=object)[prob.row_observations()]
    Jq = reading_columns(prob, fit.p)
    Z = np.hstack([Jq * (rows_of == p)[:, None] for p in placements])
    J, r = prob.jacobian(fit.p), prob.residuals(fit.p)
    R = r_factor(J)
    Zs = Z - J @ solve_upper(R, solve_upper(R, J.T @ Z, transposed=True))
    if not np.all(np.isfinite(Zs)):       # the fit's own columns dependent: nothing to screen against
        return None
    norm, whole = np.sum(Zs ** 2, axis=0), np.sum(Z ** 2, axis=0)
    b = Zs.T @ r
    usable = norm > ABSORBED_SHARE * np.maximum(whole, 1e-300)
    gains = np.where(usable, b ** 2 / np.maximum(norm, 1e-300), 0.0)
    k = int(np.argmax(gains))
    if gains[k] <= 0.0:
        return None
    freedom = 1.0 + float(np.log2(max(int(usable.sum()), 2)))
    after = max(fit.ssr - gains[k], 1e-300) / max(fit.n_rows - fit.n_free - freedom, 1.0)
    if fit.variance / after < SURVIVE_FACTOR:
        return None
    placement, j = placements[k // c.q.shape[1]], k % c.q.shape[1]
    shift = float(-b[k] / norm[k])
    q = c.q.copy()
    q[np.array([pl == placement for pl in c.placement], dtype=bool), j] += shift
    out = _refit(case, _readings(c, q))
    if out is None:
        return None
    name = case.model.joint_names[j]
    angle = case.model.reading_quantities[j] == "angle"
    off = f"{np.degrees(-shift):+.4g} deg" if angle else f"{-shift * 1e3:+.4g} mm"
    return _found(case, out, "joint rehomed", f"joint {name}'s readings on placement {placement or '-'} are {off} "
                  "off the joint's position (the joint rehomed, or its encoder slipped, between placements)",
                  "with them corrected", freedom, (name, placement),
                  f"home joint {name} and record placement {placement or '-'} again (or drop it)")


# -- hypotheses: the labels of the seatings ----------------------------------------------------------

def _relabelled(case: _Case) -> dict:
    """Row -> socket of the seatings that lie far from their socket's point at the reference fit
    (beyond the outlier bar, in robust units of their stated deviations) and near another socket's
    of the same placement (``NEAR_SHARE``)."""
    c, fit = case.contacts, case.fit
    sockets = cast(ContactRows, fit.problem.contacts).sockets
    if not sockets:
        return {}
    P, points = fit.problem.contact_positions(fit.p), fit.problem.socket_points(fit.p)
    own = np.empty(c.n_rows, dtype=int)
    for s, g in enumerate(sockets):
        own[g.rows] = s
    rows = np.concatenate([g.rows for g in sockets])
    z = (P[rows] - points[own[rows]]) / c.sigma[rows, None]
    robust = max(1.4826 * float(np.median(np.abs(z - np.median(z)))), 1.0)
    far = np.linalg.norm(z, axis=1) / robust > outlier_bar(len(rows))
    moves = {}
    for i in rows[far]:
        g = sockets[own[i]]
        others = [t for t, h in enumerate(sockets) if h.placement == g.placement and t != own[i]]
        if not others:
            continue
        d = np.linalg.norm(points[others] - P[i], axis=1)
        if d.min() < NEAR_SHARE * np.linalg.norm(points[own[i]] - P[i]):
            moves[int(i)] = sockets[others[int(np.argmin(d))]].target
    return moves if len(moves) <= MOST_RELABELLED * len(rows) else {}


def wrong_socket(case: _Case) -> Finding | None:
    """Seatings labelled with the wrong socket: those far from their socket and near another of the
    same placement at the reference fit, relabelled and refitted (each a choice of row and socket)."""
    moves = _relabelled(case)
    if not moves:
        return None
    c = case.contacts
    target = list(c.target)
    for i, t in moves.items():
        target[i] = t
    out = _refit(case, replace(c, target=tuple(target)))
    if out is None:
        return None
    items = tuple(c.labels[i] for i in moves)
    said = ", ".join(f"{c.labels[i]} ({c.placement[i] + '/' if c.placement[i] else ''}{c.target[i]}, "
                     f"seated in {t})" for i, t in list(moves.items())[:4]) + (" and more" if len(moves) > 4 else "")
    freedom = len(moves) * float(np.log2(max(c.n_rows, 2)))
    return _found(case, out, "wrong socket", f"{len(moves)} seating(s) labelled with the wrong socket: {said}",
                  "with them in the socket they lie in", freedom, items,
                  "check the socket of those seatings (their file or label) and calibrate again")


def _within(w: np.ndarray, X: np.ndarray) -> np.ndarray:
    """(n + 1,) the weighted sum of squares about their mean of the first k rows of ``X`` (n, 3),
    for every k (cumulative sums; 0 for no weight)."""
    cw = np.r_[0.0, np.cumsum(w)]
    cx = np.vstack([np.zeros(3), np.cumsum(w[:, None] * X, axis=0)])
    cxx = np.r_[0.0, np.cumsum(w * np.sum(X ** 2, axis=1))]
    return cxx - np.sum(cx ** 2, axis=1) / np.maximum(cw, 1e-300)


def _split_gains(contacts: Contacts, P: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """(len(rows) - 2 MIN_SIDE + 1,) how much the weighted sum of squares about the socket points
    falls, at the marker positions ``P`` (n_rows, 3), when the seatings ``rows`` (one placement's, in
    order) from each split on stand on a set-up of their own."""
    X = P[rows]
    w = 1.0 / contacts.sigma[rows] ** 2
    splits = np.arange(MIN_SIDE, len(rows) - MIN_SIDE + 1)
    gain = np.zeros(len(splits))
    for target in dict.fromkeys(contacts.target[i] for i in rows):
        m = np.array([contacts.target[i] == target for i in rows], dtype=float)
        before = _within(w * m, X)
        after = _within((w * m)[::-1], X[::-1])[::-1]
        gain += before[-1] - before[splits] - after[splits]
    return gain


def _best_split(contacts: Contacts, P: np.ndarray) -> tuple[tuple[str, int] | None, int]:
    """(placement, first moved row) of the split whose set-up of its own explains most at the marker
    positions ``P`` (None: no placement has seatings enough to split), and the splits tried."""
    best, tried, gain_best = None, 0, 0.0
    for placement in contacts.placements():
        rows = np.array([i for i in range(contacts.n_rows) if contacts.placement[i] == placement
                         and contacts.kind[i] == "socket"], dtype=int)
        if len(rows) < 2 * MIN_SIDE:
            continue
        gain = _split_gains(contacts, P, rows)
        tried += len(gain)
        k = int(np.argmax(gain))
        if gain[k] > gain_best:
            best, gain_best = (placement, int(rows[MIN_SIDE + k])), float(gain[k])
    return best, tried


def _moved_from(contacts: Contacts, placement: str, first: int) -> Contacts:
    """``contacts`` with the socket seatings of ``placement`` from row ``first`` on as a placement of their own."""
    new = f"{placement} from {contacts.labels[first]}"
    return replace(contacts, placement=tuple(new if (i >= first and p == placement and contacts.kind[i] == "socket")
                                             else p for i, p in enumerate(contacts.placement)))


def setup_moved(case: _Case) -> Finding | None:
    """A placement whose seatings from some row on stand on another set-up (the plate moved, or those
    seatings belong to another placement): every split of every placement's seatings screened at
    once by cumulative sums, at the reference fit's marker positions and at the nominal robot's (a
    mistake can drag the calibration far from the robot), the best of each refitted with the seatings
    from it on as a placement of their own."""
    c, fit = case.contacts, case.fit
    nominal = Problem(case.model, (), contacts=c, compliance=case.compliance)
    choices = [_best_split(c, P) for P in (fit.problem.contact_positions(fit.p),
                                           nominal.contact_positions(nominal.start_vector()))]
    tried = sum(n for _, n in choices)
    found = []
    for placement, first in dict.fromkeys(best for best, _ in choices if best is not None):
        out = _refit(case, _moved_from(c, placement, first))
        if out is None:
            continue
        label = c.labels[first]
        found.append(_found(case, out, "setup moved", f"from {label} on, placement {placement or '-'}'s seatings "
                            "lie on another set-up (the plate moved, or those seatings belong to another placement)",
                            "with them as a placement of their own", float(np.log2(max(tried, 2))),
                            (placement, label), f"check the placement of the seatings from {label} on (their folder "
                            "or label); if the plate moved, give them a placement of their own, or record that "
                            "placement again"))
    return max(found, key=lambda f: f.score, default=None)


# -- hypotheses: the stated distances ----------------------------------------------------------------

def _spacing(prob: Problem, p: np.ndarray, d: KnownDistance) -> float | None:
    """The mean distance of sockets ``d.a`` and ``d.b`` over the placements holding both, at ``p``."""
    rows = cast(ContactRows, prob.contacts)
    where = {(g.placement, g.target): s for s, g in enumerate(rows.sockets)}
    points = prob.socket_points(p)
    placements = dict.fromkeys(g.placement for g in rows.sockets)
    got = [float(np.linalg.norm(points[where[p_, d.a]] - points[where[p_, d.b]]))
           for p_ in placements if (p_, d.a) in where and (p_, d.b) in where]
    return float(np.mean(got)) if got else None


def spacing_stated(case: _Case) -> Finding | None:
    """A known distance stated wrongly: each refitted without it (with the others), or, when it is the
    only one, at the spacing the nominal robot measures (a wrong only spacing scales the robot: its
    changes become implausible)."""
    c = case.contacts
    if not c.distance_pairs():
        return None
    nominal = Problem(case.model, (), contacts=c, compliance=case.compliance)
    found = []
    for k, d in enumerate(c.distances):
        others = c.distances[:k] + c.distances[k + 1:]
        if replace(c, distances=others).distance_pairs():
            changed, how = replace(c, distances=others), "without it"
        else:
            length = _spacing(nominal, nominal.start_vector(), d)
            if length is None:
                continue
            changed = replace(c, distances=(KnownDistance(d.a, d.b, length, d.sigma),))
            how = f"at the nominal robot's {_mm(length)}"
        out = _refit(case, changed)
        if out is None:
            continue
        fitted = _spacing(out.problem, out.p, d)
        said = "" if fitted is None else f"; the refit puts them {_mm(fitted)} apart"
        found.append(_found(case, out, "spacing stated", f"the stated distance of sockets {d.a} and {d.b} "
                            f"({_mm(d.length)}) is wrong", how, float(np.log2(len(c.distances))), (f"{d.a}-{d.b}",),
                            f"check the stated spacing of sockets {d.a} and {d.b} ({_mm(d.length)} stated{said})"))
    return max(found, key=lambda f: f.score, default=None)


# -- the ranking -------------------------------------------------------------------------------------

CONTACT_HYPOTHESES = (joint_sign, unit_factor, joints_swapped, joint_rehomed, wrong_socket, setup_moved,
                      spacing_stated)


def _recorded_on(value, name, args):
    """Contacts of the model passed as ``model``: at least one, its joint count, its markers."""
    m = args["model"]
    if (lack := unobserved(value)) is not None:
        raise InputError(f"holds no {lack}", source=value.source or None, where=name)
    if value.q.shape[1] != m.n_joints:
        raise InputError(f"{value.q.shape[1]} joint columns for a model with {m.n_joints} joints", where=name)
    missing = [n for n in dict.fromkeys(value.marker) if n not in m.marker_names]
    if missing:
        raise InputError(f"marker(s) {', '.join(missing)} are not in the model (markers: "
                         f"{', '.join(m.marker_names)})", where=name)


def _calibration_of(value, name, args):
    """A calibration of the model passed as ``model``: a record with ``calibrated_model`` and
    ``nominal_model`` of its layout, and the ``parameters`` it identified (at least one)."""
    m = args["model"]
    models = (getattr(value, "calibrated_model", None), getattr(value, "nominal_model", None))
    estimates = getattr(value, "parameters", None)
    if not (all(isinstance(x, RobotModel) for x in models) and isinstance(estimates, tuple)
            and all(isinstance(e, ParameterEstimate) for e in estimates)):
        raise InputError(f"must be a calibration (with calibrated_model, nominal_model and parameters), got "
                         f"{excerpt(value) if isinstance(value, (str, int, float)) else type(value).__name__}",
                         where=name)
    own = parameter_names(m)
    if any(parameter_names(x) != own for x in models):
        raise InputError("must be a calibration of this model (its parameters differ)", where=name)
    if not estimates:
        raise InputError("identified no parameter: there is nothing to refit", where=name)
    bad = next((e.name for e in estimates if e.name not in set(own)), None)
    if bad is not None:
        raise InputError(f"identified {bad!r}, not a parameter of the model", where=name)


@one_blas_thread
def _reference(model: RobotModel, contacts: Contacts, result, data: Measurements | None, noise: Noise) -> _Case:
    """The original fit redone with the linear loss from the calibrated model, on the rows diagnosed."""
    names = tuple(p.name for p in result.parameters)
    work = _thinned(contacts)
    if data is not None and data.n_poses > MAX_POSES:
        data = data.subset(_evenly(data.n_poses, MAX_POSES))
    compliance = needs_compliance(result.calibrated_model, names)
    prob = _problem(result.calibrated_model, work, names, compliance, data, noise, registered=False)
    sol = solve(prob, prob.start_vector(), max_nfev=MAX_NFEV)
    return _Case(model, names, work, data, noise, compliance, _outcome(prob, sol.p, model, names))


@accepts(model=is_a(RobotModel), contacts=both(is_a(Contacts), _recorded_on), result=_calibration_of,
         data=optional(both(is_a(Measurements), measured_on())), noise=noise_of(Noise, INSTRUMENT_NOISE))
def diagnose_contacts(model: RobotModel, contacts: Contacts, result, *, data: Measurements | None = None,
                      noise=None) -> Diagnosis:
    """Test specific explanations of a calibration from contacts' misfit against the contacts, and
    rank them (docs/diagnosis.md, "Calibrations from contacts").

    Parameters
    ----------
    model : RobotModel
        The nominal model the calibration started from.
    contacts : Contacts
        The contacts it fitted, in their campaign order.
    result : CalibrationResult
        The calibration of ``model`` on ``contacts`` (and ``data``): its identified ``parameters``
        are refitted, from its ``calibrated_model`` for the reference and from ``model`` for each
        hypothesis.
    data : Measurements, optional
        Tracker measurements fitted beside the contacts (kept in every refit).
    noise : Noise, str or None
        The noise of the tracker measurements (a ``Noise`` or an instrument class); default a laser
        tracker's.

    Returns
    -------
    Diagnosis
        The findings, most likely first (others only when close to it; none when nothing tested
        explains the misfit), the hypotheses tested and a one-line summary; RMS figures are those of
        the contact errors in metres.
    """
    case = _reference(model, contacts, result, data, as_noise(noise))
    found = [f for f in (h(case) for h in CONTACT_HYPOTHESES) if f is not None and f.score >= NAMED]
    return ranked(found, tuple(h.__name__.replace("_", " ") for h in CONTACT_HYPOTHESES), case.fit.rms,
                  f"{case.fit.rms_sd:.3g} stated deviations RMS, {_mm(case.fit.rms)}")
