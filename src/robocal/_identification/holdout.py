"""Accuracy in use: how well a model places the robot at poses it was not fitted on.

A calibration answers its user's question, "will this model place my robot better than what it
has now, and how well?", from poses the fit did not see: a validation set when one is given, else
k-fold cross-validation (docs/checks.md, "Accuracy in use"). Folds are contiguous blocks of the
campaign's order where consecutive poses are neighbours (a grid, a path), or its series when the
file names them: poses measured together share their drift and their corner of the workspace, so
holding out a block asks what use asks (a pose elsewhere, at another time), where random folds
would let a pose's neighbours vouch for it. Where consecutive poses are not neighbours (a random
plan), a block holds out no region and folds are drawn at random. Repeated configurations stay
in one fold.

Each fold's model is the full solution moved by one Gauss-Newton step on the other folds' rows
(the normal equations less the fold's: a solve of the size of the parameters), then evaluated
exactly at the fold's poses. From a converged fit that step lands on the refitted minimum to
second order in the change, which is small; the tests hold it against refits.

The campaign's coverage says where that accuracy holds: the measured readings and points against
what the joint limits allow, and the parameters' uncertainty carried over the whole workspace.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import numpy as np
from scipy.linalg.lapack import dpocon, dpotrf, dpotrs

from .._base.arrays import column_extent, frozen, mean_and_error, point_spread, read_only, vector_norms
from .._model.configurations import sampling_box
from .._model.kinematics import CHUNK_POSES
from .._model.measurements import Measurements
from .contact_blocks import ContactRows
from .points import Points
from .problem import Problem

# folds of a cross-validation without a series column
DEFAULT_FOLDS = 5
# consecutive poses closer than this share of the typical distance between poses are neighbours: the
# campaign's order is spatial (a grid, a path) and folds are blocks of it; otherwise they are drawn
# at random (a block of a random plan holds out no region, only a stretch of time)
NEIGHBOURS = 0.5
FOLD_SEED = 20240602
# a series column with more series than this is grouped into this many folds (contiguous series)
MAX_FOLDS = 20
# eigenvalues of a fold's normal matrix (unit columns) below this share of the largest are left out:
# a fold that alone determined a direction leaves the others unable to (that direction keeps its value)
FOLD_RCOND = 1e-12
# a fold's normal matrix whose estimated reciprocal condition number (1-norm) is above this keeps every
# eigenvalue whatever the estimate's error: it is solved by Cholesky
WELL_CONDITIONED = 1e-8
# a joint whose limits allow a full turn or more is taken to be used over the campaign's range of it,
# widened by this share of that range on each side
USE_MARGIN = 0.1
# configurations drawn within the joint limits to describe the workspace (what the calibrated geometry
# does there, the spread of its points), and (at most) the poses the parameters' uncertainty is
# carried to, there and at the measured poses
WORKSPACE_POSES = 150
UNCERTAINTY_POSES = 100
WORKSPACE_SEED = 20240601


@dataclass(frozen=True)
class UseStats:
    """Statistics of ``n`` error norms in use (m for positions, rad for rotations).

    Attributes
    ----------
    n : int
        How many norms (points held out).
    mean : float or None
        Their mean; None when n = 0 (likewise below).
    rms : float or None
        Their root mean square.
    p95 : float or None
        Their 95th percentile.
    max : float or None
        The largest.
    """

    n: int
    mean: float | None
    rms: float | None
    p95: float | None
    max: float | None


def use_stats(norms) -> UseStats:
    """The statistics of error norms; NaN entries (not measured) are left out.

    >>> use_stats([3.0, 4.0]).rms
    3.5355339059327378
    """
    v = np.asarray(norms, dtype=float).ravel()
    finite = np.isfinite(v)
    if not finite.all():                  # no copy where every point was measured
        v = v[finite]
    if v.size == 0:
        return UseStats(0, None, None, None, None)
    return UseStats(int(v.size), float(v.mean()), float(np.sqrt(np.mean(v * v))), percentile_95(v), float(v.max()))


def percentile_95(v: np.ndarray) -> float:
    """``np.percentile(v, 95)`` (linear interpolation) bit for bit, from one partition of the 1-D
    ``v`` (numpy's function takes eight times as long on a thousand values): the values on either
    side of rank 0.95 (n - 1), interpolated as numpy does (from the nearer one).

    >>> percentile_95(np.arange(21.0))
    19.0
    """
    n = v.size
    at = (n - 1) * 0.95
    lo = int(at)
    hi = min(lo + 1, n - 1)
    part = np.partition(v, [lo, hi] if hi > lo else lo)
    a, b = float(part[lo]), float(part[hi])
    t = at - lo
    return b - (b - a) * (1 - t) if t >= 0.5 else a + (b - a) * t


def fold_labels(data: Measurements, folds: int = DEFAULT_FOLDS) -> tuple[np.ndarray, int, str]:
    """The fold of each pose, the number of folds and how they were made.

    With a ``series`` column (``data.extra["series"]``) of two or more series, each series is a fold
    (more than ``MAX_FOLDS`` are grouped in order); else ``folds`` contiguous blocks of the poses'
    order. A configuration repeated exactly goes to the fold of its first occurrence.
    """
    n = data.n_poses
    series = data.extra.get("series")
    if series is not None and len(set(np.asarray(series).tolist())) >= 2:
        names, first = np.unique(np.asarray(series), return_index=True)
        order = np.argsort(np.argsort(first))             # series numbered by first appearance
        labels = order[np.unique(np.asarray(series), return_inverse=True)[1]]
        k = len(names)
        if k > MAX_FOLDS:
            labels, k = labels * MAX_FOLDS // k, MAX_FOLDS
        return labels.astype(int), int(k), f"{k} folds by series"
    k = int(min(max(folds, 2), n))
    shuffled = np.random.default_rng(FOLD_SEED).permutation(n)
    if ordered(data.q, shuffled):
        labels, how = np.arange(n) * k // n, f"{k} folds of consecutive poses"
    else:
        labels, how = shuffled % k, f"{k} folds drawn at random"
    earliest = first_equal_rows(data.q)     # a configuration repeated exactly goes with its first
    return (labels if earliest is None else labels[earliest]).astype(int), k, how


def first_equal_rows(q: np.ndarray) -> np.ndarray | None:
    """For each row of ``q``, the index of the first row equal to it; None when every row is
    distinct. Rows with distinct projections on a fixed direction are distinct: only when two
    projections tie are the rows compared whole (+ 0.0 makes -0.0 and 0.0 alike)."""
    rows = np.ascontiguousarray(q + 0.0)
    h = np.sort(rows @ (1.0 / np.sqrt(np.arange(2.0, rows.shape[1] + 2.0))))
    if np.all(h[1:] != h[:-1]):
        return None
    _, first, inverse = np.unique(rows, axis=0, return_index=True, return_inverse=True)
    return first[np.ravel(inverse)]


def ordered(q: np.ndarray, shuffled: np.ndarray | None = None) -> bool:
    """Whether consecutive poses are neighbours (a grid, a path): the median step between them, in
    each joint's spread, is below ``NEIGHBOURS`` of the median distance between poses taken at random
    (each against the pose ``shuffled`` puts in its place; default the permutation of ``FOLD_SEED``)."""
    q = np.asarray(q, dtype=float)
    if len(q) < 4:
        return True
    x = np.ascontiguousarray(q.T)                   # (n_joints, n): numpy reduces long rows fast
    spread = x.std(axis=1)
    x /= np.where(spread > 0, spread, 1.0)[:, None]
    if shuffled is None:
        shuffled = np.random.default_rng(FOLD_SEED).permutation(x.shape[1])
    step, other = np.diff(x, axis=1), x - x[:, shuffled]
    return bool(np.median(np.sqrt(np.sum(step * step, axis=0))) < NEIGHBOURS * np.median(
        np.sqrt(np.sum(other * other, axis=0))))


def _sub_problem(problem: Points, index: np.ndarray) -> Points:
    """The measured points of the poses ``index`` of ``problem``'s data, over the same free parameters
    (each model held out is evaluated once: no positions kept)."""
    data = problem.data.with_approach() if problem.backlash else problem.data
    return Points(problem.model, data.subset(index), free_names(problem), compliance=problem.compliance,
                  noise=problem.noise, kept_positions=0)


def free_names(problem: Points) -> tuple[str, ...]:
    """The names of ``problem``'s free parameters (they decide, e.g., whether joints rest in their
    lost motion)."""
    return tuple(problem.lay.names[i] for i in problem.free_idx)


def point_loss(problem: Points, p: np.ndarray, errors: np.ndarray | None = None) -> np.ndarray:
    """(n_poses, n_markers) each measured point's sum of squared weighted residuals at ``p``.
    ``errors``: ``problem.errors(p)`` when at hand; for point data the residuals are then those
    errors weighted (the same numbers, without evaluating the campaign again)."""
    n, m = problem.data.mask.shape
    if errors is not None and not problem.use_rot:
        # each point's three weighted residuals squared and added in row order, as the sum by rows below
        out = np.zeros((n, m))
        for j, (s, w) in enumerate(zip(problem.sel, problem.w)):
            e = errors[:, j] if len(s) == n else errors[s, j]
            r = e * w[:, None]
            out[s, j] = r[:, 0] * r[:, 0] + r[:, 1] * r[:, 1] + r[:, 2] * r[:, 2]
        return out
    r = problem.residuals(p)
    poses, markers = problem.row_points()
    return np.bincount(poses * m + markers, weights=r * r, minlength=n * m).reshape(n, m)


@dataclass(frozen=True, eq=False)
class HeldOut:
    """One model's errors at observations it was not fitted on. Measured points: ``positions``
    (n_poses, n_markers, 3) predicted minus measured, m (NaN where not measured); ``rotations``
    likewise in rad or None; ``loss`` (n_poses, n_markers) each point's sum of squared weighted
    residuals (the fit's own weighting: what the fit minimises, so models compare on it); no poses
    without points. Contacts: ``contact_errors`` (n_contact_observations, 3) each observation's error
    with its own unknowns from its own rows (``ContactRows.own_errors``; NaN where not predicted) and
    ``contact_loss`` the same squared in stated deviations, or None without contacts."""

    positions: np.ndarray
    rotations: np.ndarray | None
    loss: np.ndarray
    contact_errors: np.ndarray | None = None
    contact_loss: np.ndarray | None = None

    @property
    def norms(self) -> np.ndarray:
        return vector_norms(self.positions)

    @property
    def rotation_norms(self) -> np.ndarray | None:
        return None if self.rotations is None else vector_norms(self.rotations)

    def observation_loss(self, mask: np.ndarray) -> np.ndarray:
        """(n_observations,) the loss of each observation of the problem whose measured points are
        ``mask`` (n_poses, n_markers): points in mask order, then contacts."""
        parts = [self.loss[mask]] + ([] if self.contact_loss is None else [self.contact_loss])
        return np.concatenate(parts)

    def observation_norms(self, mask: np.ndarray) -> np.ndarray:
        """(n_observations,) each observation's error norm (m), as ``observation_loss`` orders them."""
        parts = [self.norms[mask]] + ([] if self.contact_errors is None else
                                      [np.sqrt(np.nansum(self.contact_errors ** 2, axis=1))])
        return np.concatenate(parts)


def evaluated(problem: Points, p: np.ndarray) -> HeldOut:
    """The errors of the vector ``p`` at every pose of ``problem`` (none of them fitted with it)."""
    errors = problem.errors(p)
    return HeldOut(errors, problem.rotation_errors(p), point_loss(problem, p, errors))


def _moved_held_out(problem: Problem, pts: Points, p: np.ndarray, steps: list[np.ndarray], holdout: Holdout
                    ) -> HeldOut | None:
    """The measured points' held-out errors (``cross_validate``) when every fold's model differs from
    ``p`` in the base and markers only (a registration refitted): each is the campaign's evaluation
    at ``p`` moved rigidly (``Points.moved_positions``), what a pass per fold finds to rounding. None
    where that does not hold (a step of the chain, compliance, lost motion, orientations)."""
    if pts.use_rot:
        return None
    n = problem.n_robot
    moved = np.repeat(p[None], holdout.point_folds, axis=0)
    moved[:, problem.free_idx] += steps[:holdout.point_folds]
    predicted = pts.moved_positions(p[:n], moved[:, :n], cast(np.ndarray, holdout.pose_labels))
    if predicted is None:
        return None
    errors = pts.errors_of(predicted)
    return HeldOut(errors, None, point_loss(pts, p[:n], errors))


def _fold_passes(problem: Problem, pts: Points, p: np.ndarray, steps: list[np.ndarray], holdout: Holdout
                 ) -> HeldOut | None:
    """The measured points' held-out errors (``cross_validate``) from a pass of each fold's model at
    that fold's readings alone (``CHUNK_POSES`` at a time), their errors and loss then taken over the
    campaign at once: the figures of a problem made per fold, without making one. None with
    orientations (their errors are the problem's to make)."""
    if pts.use_rot:
        return None
    n, labels = problem.n_robot, cast(np.ndarray, holdout.pose_labels)
    order = np.argsort(labels, kind="stable") if np.any(labels[1:] < labels[:-1]) else None
    bounds = np.searchsorted(labels if order is None else labels[order], np.arange(holdout.point_folds + 1))
    positions = np.empty((pts.data.n_poses, len(pts.marker_idx), 3))
    for g in range(holdout.point_folds):
        pg = p.copy()
        pg[problem.free_idx] += steps[g]
        for lo in range(bounds[g], bounds[g + 1], CHUNK_POSES):
            part = slice(lo, min(lo + CHUNK_POSES, bounds[g + 1]))
            at = part if order is None else order[part]
            positions[at] = pts.positions_at(pg[:n], at)
    errors = pts.errors_of(positions)
    return HeldOut(errors, None, point_loss(pts, p[:n], errors))


def contact_held_out(rows: ContactRows, p_robot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each contact observation's error with its own unknowns from its own rows at ``p_robot``
    (n_obs, 3), and its loss in stated deviations (n_obs,)."""
    e = rows.own_errors(p_robot)
    return e, np.nansum(e ** 2, axis=1) / rows.sigma() ** 2


@dataclass(frozen=True, eq=False)
class Holdout:
    """How a problem's observations are held out: ``groups`` (n_observations,) the group of each
    (-1: never held out), ``k`` groups, ``description`` (how they were made, for messages),
    ``pose_labels`` (n_poses,) the fold of each pose of the measured points (None without),
    ``point_folds`` how many of the groups are folds of poses (the others are placements of the
    contacts, in ``placements`` order)."""

    groups: np.ndarray
    k: int
    description: str
    pose_labels: np.ndarray | None
    point_folds: int
    placements: tuple[str, ...] = ()

    @property
    def grouping(self) -> str:
        return self.description


def holdout_of(problem: Problem, folds: int = DEFAULT_FOLDS) -> Holdout:
    """The held-out groups of ``problem``'s observations: folds of the measured points' poses (their
    series, or ``folds`` blocks of consecutive poses, or folds drawn at random: ``fold_labels``) and,
    with two placements or more, each placement of the contacts."""
    obs = problem.observations()
    groups = np.full(len(obs), -1, dtype=int)
    labels, k_points, said = None, 0, []
    if problem.points is not None:
        d = problem.points.data
        labels, k_points, how = fold_labels(d, folds)
        groups[:obs.n_points] = labels[np.nonzero(d.mask)[0]]
        said.append(how)
    placements: tuple[str, ...] = ()
    if problem.contacts is not None and len(problem.contacts.contacts.placements()) > 1:
        placements = problem.contacts.contacts.placements()
        where = {name: k_points + i for i, name in enumerate(placements)}
        groups[obs.n_points:] = [where[p] for p in obs.placement[obs.n_points:]]
        said.append("each placement predicted by the others")
    return Holdout(groups, k_points + len(placements), "; ".join(said), labels, k_points, placements)


def fold_steps(problem: Problem, p: np.ndarray, holdout: Holdout, at: np.ndarray | None = None) -> list[np.ndarray]:
    """For each group, the Gauss-Newton step from ``p`` (a solution on every row) to the fit on the
    rows of the other groups: ``-(A - A_g)^+ (b - b_g)`` over the free parameters, ``A = J^T J``,
    ``b = J^T r`` (``A_g``, ``b_g`` the group's part), in unit-column scaling. ``at``: where the
    solver took its last Jacobian (within its tolerances of ``p``), taken instead of a new one. A
    group's own unknowns (a placement's socket points) have no row left: they keep their value."""
    k = holdout.k
    n_free = len(problem.free_idx)
    A, b = np.zeros((n_free, n_free)), np.zeros(n_free)
    Ag, bg = np.zeros((k, n_free, n_free)), np.zeros((k, n_free))
    for J, r, obs in problem.pieces(p, at):
        f = holdout.groups[obs]
        Jt, ro = np.asarray(J).T, r
        if np.any(f[1:] < f[:-1]):              # rows of a group together (folds of consecutive poses are)
            # a few labels: as 16-bit integers a stable sort is a radix sort (a fifth of the time)
            order = np.argsort(f.astype(np.int16) if k < 2 ** 15 else f, kind="stable")
            f, Jt, ro = f[order], Jt[:, order], r[order]
        bounds = np.searchsorted(f, np.arange(-1, k + 1))     # each group's rows, -1 first
        for g in range(-1, k):
            lo, hi = bounds[g + 1], bounds[g + 2]
            if hi == lo:
                continue
            part = Jt[:, lo:hi]
            gram, grad = part @ part.T, part @ ro[lo:hi]
            A += gram
            b += grad
            if g >= 0:
                Ag[g] += gram
                bg[g] += grad
    col = np.sqrt(np.diag(A))
    col[col == 0] = 1.0
    scale = np.outer(col, col)
    return [-_kept_solve((A - Ag[g]) / scale, (b - bg[g]) / col) / col for g in range(k)]


def _kept_solve(M: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``M^+ v`` over the eigenvalues of the symmetric ``M`` above ``FOLD_RCOND`` of the largest. Where
    ``M`` is positive definite and its estimated reciprocal condition number is above
    ``WELL_CONDITIONED``, every eigenvalue is kept: a Cholesky solve gives that (a twentieth of an
    eigendecomposition's work at a hundred parameters)."""
    c, info = dpotrf(M, lower=0)
    if info == 0:
        rcond, info = dpocon(c, float(np.abs(M).sum(axis=0).max()))
        if info == 0 and rcond > WELL_CONDITIONED:
            return dpotrs(c, v, lower=0)[0]
    w, V = np.linalg.eigh(0.5 * (M + M.T))
    keep = w > FOLD_RCOND * max(float(w.max()), 0.0)
    return V[:, keep] @ ((V[:, keep].T @ v) / w[keep])


class FoldProblems:
    """The problems on each group's observations of a campaign, made once for one calibration and
    taken over the free parameters of each model it compares (``points``, ``contacts``). Held by the
    calibration call that made it, and gone with it."""

    def __init__(self, holdout: Holdout):
        self.holdout = holdout
        self._made: dict = {}

    def points(self, problem: Points) -> list:
        """(poses, problem over ``problem``'s free parameters) of each fold of poses that has poses."""
        labels, k = cast(np.ndarray, self.holdout.pose_labels), self.holdout.point_folds
        key = (id(problem.data), problem.compliance, problem.backlash)
        if key not in self._made:
            self._made[key] = (problem.data, [(idx, _sub_problem(problem, idx)) for idx in
                                              (np.nonzero(labels == g)[0] for g in range(k)) if len(idx)])
        return [(idx, sub.over(free_names(problem))) for idx, sub in self._made[key][1]]

    def contacts(self, rows: ContactRows) -> list:
        """(group, observations, the rows of the group's placement) of each placement held out."""
        key = (id(rows.contacts), rows.compliance, rows.backlash)
        if key not in self._made:
            h, out = self.holdout, []
            obs_placement = np.array(rows.obs_placement, dtype=object)
            for i, name in enumerate(h.placements):
                index = np.nonzero(obs_placement == name)[0]
                sub = rows.contacts.subset(np.array([p == name for p in rows.contacts.placement]))
                part = ContactRows(rows.model, sub, compliance=rows.compliance, backlash=rows.backlash)
                if len(part.obs_kind) != len(index):      # the same observations, in the same order
                    raise AssertionError("a placement's observations differ from the campaign's")
                out.append((h.point_folds + i, index, part))
            self._made[key] = (rows.contacts, out)
        return self._made[key][1]


def cross_validate(problem: Problem, p: np.ndarray, holdout: Holdout, *, on: Problem | None = None,
                   folds: FoldProblems | None = None, at: np.ndarray | None = None) -> HeldOut:
    """Each observation's errors under the model fitted on the other groups (``fold_steps``); ``on``:
    the problem whose observations are predicted (default ``problem``; e.g. the whole campaign when
    ``problem`` has observations set aside); ``folds``: the group problems to reuse; ``at``: where
    the solver took its last Jacobian (``Solution.jacobian_at``)."""
    steps = fold_steps(problem, p, holdout, at)
    target = problem if on is None else on
    folds = FoldProblems(holdout) if folds is None else folds
    pos: np.ndarray | None = None
    rot: np.ndarray | None = None
    loss = np.zeros((0, 0))
    moved = None if target.points is None else (_moved_held_out(problem, target.points, p, steps, holdout)
                                                 or _fold_passes(problem, target.points, p, steps, holdout))
    if moved is not None:
        pos, rot, loss = moved.positions, None, moved.loss
    elif target.points is not None:
        pts = target.points
        data = pts.data
        pos = np.full(data.positions.shape, np.nan)
        rot = np.full(data.positions.shape, np.nan) if data.has_orientation else None
        loss = np.zeros(data.mask.shape)
        for index, sub in folds.points(pts):
            pg = p.copy()
            pg[problem.free_idx] += steps[int(cast(np.ndarray, holdout.pose_labels)[index[0]])]
            out = evaluated(sub, pg[:problem.n_robot])
            pos[index], loss[index] = out.positions, out.loss
            if rot is not None and out.rotations is not None:
                rot[index] = out.rotations
    c_err = c_loss = None
    if target.contacts is not None:
        n_obs = len(target.contacts.obs_kind)
        c_err, c_loss = np.full((n_obs, 3), np.nan), np.full(n_obs, np.nan)
        for g, index, part in folds.contacts(target.contacts):
            pg = p.copy()
            pg[problem.free_idx] += steps[g]
            c_err[index], c_loss[index] = contact_held_out(part, pg[:problem.n_robot])
    if pos is None:
        pos, loss = np.zeros((0, 0, 3)), np.zeros((0, 0))
    return HeldOut(pos, rot, loss, c_err, c_loss)


def paired_excess(simple: np.ndarray, complex_: np.ndarray, mask: np.ndarray) -> tuple[float, float]:
    """How much more the simpler model loses over the points ``mask`` than the other, per point, and
    the standard error of that mean (the two are compared on the same points, so their difference
    is measured far more precisely than either; infinite below two points, which establish nothing)."""
    return mean_and_error((simple - complex_)[mask])


@dataclass(frozen=True)
class JointOffset:
    """The joint whose readings, off by one constant on a validation set (base and tool registered
    on it too), explain its errors best: ``offset`` the reading less the joint's position (rad, or
    m for a prismatic joint), ``errors`` the calibrated model's errors once it is taken off, scaled
    as ``registered_after`` with one more equation taken up (m)."""

    joint: str
    offset: float
    quantity: str
    errors: UseStats


# the method of an accuracy in use taken on a validation set once base and tool are registered on it
REGISTERED_ON_IT = "validation, base and tool registered on it"


@dataclass(frozen=True, eq=False)
class AccuracyInUse:
    """The accuracy a calibration predicts in use, before and after it, from poses not fitted.

    Every figure is the robot's: the instrument's noise is taken out (``without_instrument``),
    except in ``measured_after`` and ``measured_fit`` (what overfitting is judged on: the same
    noise in both).

    Attributes
    ----------
    method : str
        "validation" (a held-out set), "validation, base and tool registered on it",
        "cross-validation" or "held-out placements".
    folds : int or None
        The folds of the cross-validation; None with a held-out set.
    grouping : str
        How the held-out groups were made (consecutive poses, the file's series, placements).
    position_before : UseStats
        The held-out position error norms of the nominal model (its base and tool registered on
        the fitted poses, as the calibration's), m.
    position_after : UseStats
        The same of the calibrated model, m.
    rotation_before : UseStats or None
        The held-out rotation error angles of the nominal model, rad; None for point data.
    rotation_after : UseStats or None
        The same of the calibrated model, rad; None for point data.
    fit_after : UseStats
        The calibrated model on the fitted poses themselves, m.
    errors_before : numpy.ndarray
        (n_points,) the held-out position error norms of the nominal model, m (read-only).
    errors_after : numpy.ndarray
        (n_points,) those of the calibrated model, m (read-only).
    registration_only : bool
        Only base and markers were identified: the robot's kinematics are the nominal ones.
    measured_after : UseStats or None
        The held-out errors after calibration as the instrument saw them, m.
    measured_fit : UseStats or None
        The fitted errors after calibration as the instrument saw them, m.
    measured_points : UseStats or None
        The held-out measured points alone after calibration as the instrument saw them, m:
        ``measured_after`` without the seatings held out beside them (what a verification with
        measured points is held against).
    noise : float
        The instrument's noise taken out of each measured point's figure, as an RMS error norm
        (the square root of three times its per-axis variance), m; 0 when none was.
    registered_after : UseStats or None
        With a validation set not registered: the calibrated model's errors on it once base and
        tool are registered on it, scaled by sqrt(m / (m - r)) for the r of its m equations the
        registration takes up, m (what tells another set-up from overfitting).
    cross_validated : UseStats or None
        With a validation set: the fitted campaign's own held-out errors as measured, m (what
        tells other poses from overfitting).
    rehomed : JointOffset or None
        With a validation set not registered whose errors are ``OVERFIT_RATIO`` times the fitted
        ones or more: the one joint whose readings, off by a constant there, explain them best (a
        joint homed otherwise between the campaigns).
    spacing_before : numpy.ndarray or None
        With contacts: (n,) the absolute errors of the known distances between held-out sockets'
        mean centres of the nominal model, m (read-only): the scale in use.
    spacing_after : numpy.ndarray or None
        The same of the calibrated model, m (read-only).
    """

    method: str
    folds: int | None
    grouping: str
    position_before: UseStats
    position_after: UseStats
    rotation_before: UseStats | None
    rotation_after: UseStats | None
    fit_after: UseStats
    errors_before: np.ndarray
    errors_after: np.ndarray
    registration_only: bool = False
    measured_after: UseStats | None = None
    measured_fit: UseStats | None = None
    measured_points: UseStats | None = None
    noise: float = 0.0
    registered_after: UseStats | None = None
    cross_validated: UseStats | None = None
    rehomed: JointOffset | None = None
    spacing_before: np.ndarray | None = None
    spacing_after: np.ndarray | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "errors_before", frozen(self.errors_before))
        object.__setattr__(self, "errors_after", frozen(self.errors_after))
        for name in ("spacing_before", "spacing_after"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, frozen(getattr(self, name)))

    @property
    def standard_error(self) -> float:
        """The standard error of the mean error after calibration (m); infinite for one point, which
        has none (nothing is established from it)."""
        return mean_and_error(self.errors_after)[1]

    @property
    def improvement(self) -> tuple[float, float]:
        """The mean error before minus after (m) and its standard error (paired over the points;
        infinite for one point)."""
        return mean_and_error(self.errors_before - self.errors_after)


def without_instrument(norms: np.ndarray, variance: float) -> np.ndarray:
    """Error norms of 3D vectors with an instrument's share taken out: scaled so that their mean
    square loses three times its per-axis ``variance`` (what the robot's placement errors would
    show without the instrument between; none left when the instrument explains it all)."""
    v = np.asarray(norms, dtype=float)
    if variance <= 0:
        return v
    square = v * v
    ms = float(np.sum(square)) / max(square.size, 1)     # np.nanmean's figure where every norm is finite
    if not np.isfinite(ms):
        ms = float(np.nanmean(square)) if np.isfinite(v).any() else 0.0
    if ms <= 0:
        return v
    return v * np.sqrt(max(1.0 - 3.0 * variance / ms, 0.0))


def within_noise(figure: float | None, noise: float | None) -> str | None:
    """'within the instrument's noise of 0.03464 mm RMS' when the robot's ``figure`` (m) is nothing
    once the instrument's ``noise`` (``AccuracyInUse.noise``; None: not known) is taken out: the
    errors measured were within it, and a bare 0 would read as a perfect robot. None otherwise
    (with no noise taken out, a figure of 0 is what was measured).

    >>> within_noise(0.0, 3.4641e-05), within_noise(2e-05, 3.4641e-05)
    ("within the instrument's noise of 0.03464 mm RMS", None)
    """
    if figure is None or figure > 0 or (noise is not None and not noise > 0):
        return None
    return "within the instrument's noise" + ("" if noise is None else f" of {noise * 1e3:.4g} mm RMS")


def accuracy_in_use(method: str, folds: int | None, grouping: str, before: HeldOut, after: HeldOut,
                    fit_after: np.ndarray, *, registration_only: bool = False, noise: tuple[float, float] = (0.0, 0.0),
                    seatings: np.ndarray | None = None, fit_seatings: np.ndarray | None = None,
                    spacings: np.ndarray | None = None) -> AccuracyInUse:
    """The record of held-out errors before and after (``HeldOut``); ``fit_after`` the error norms
    on the fitted points (and seatings); ``registration_only``: only base and markers were identified
    (the robot's kinematics are the nominal ones, before as after). ``noise``: the instrument's
    per-axis variance of positions (m^2) and rotations (rad^2), taken out of every measured point's
    figure (``without_instrument``): the accuracy in use is the robot's. ``seatings``
    (n_contact_observations,): the contact observations whose held-out errors are positions of the
    robot (seatings: their distance from their socket's mean centre), judged beside the points;
    ``fit_seatings`` the fitted seatings' distances; ``spacings`` (n_contact_observations,) the
    known distances, whose held-out errors are kept beside (``spacing_before``, ``spacing_after``)."""
    raw_after = after.norms.ravel()
    eb, ea = without_instrument(before.norms.ravel(), noise[0]), without_instrument(raw_after, noise[0])
    fit_raw = np.asarray(fit_after, dtype=float)
    fitted = without_instrument(fit_raw, noise[0])
    if fit_seatings is not None:
        fit_raw, fitted = np.r_[fit_raw, fit_seatings], np.r_[fitted, fit_seatings]
    if seatings is not None and after.contact_errors is not None and before.contact_errors is not None:
        cb, ca = (np.linalg.norm(np.nan_to_num(cast(np.ndarray, e.contact_errors)[seatings]), axis=1)
                  for e in (before, after))
        held = np.isfinite(after.contact_errors[seatings, 0])
        eb, ea = np.r_[eb, cb[held]], np.r_[ea, ca[held]]
        raw_after = np.r_[raw_after, ca[held]]
    both = np.isfinite(eb) & np.isfinite(ea)
    rb, ra = before.rotation_norms, after.rotation_norms
    rb = None if rb is None else without_instrument(rb, noise[1])
    ra = None if ra is None else without_instrument(ra, noise[1])
    sb = sa = None
    eb_c, ea_c = before.contact_errors, after.contact_errors
    if spacings is not None and spacings.any() and ea_c is not None and eb_c is not None:
        held = spacings & np.isfinite(ea_c[:, 0])
        sb, sa = read_only(np.abs(eb_c[held, 0])), read_only(np.abs(ea_c[held, 0]))
    return AccuracyInUse(method=method, folds=folds, grouping=grouping, position_before=use_stats(eb[both]),
                         position_after=use_stats(ea[both]), rotation_before=None if rb is None else use_stats(rb),
                         rotation_after=None if ra is None else use_stats(ra), fit_after=use_stats(fitted),
                         errors_before=eb[both], errors_after=ea[both], registration_only=registration_only,
                         measured_after=use_stats(raw_after), measured_fit=use_stats(fit_raw),
                         measured_points=use_stats(after.norms), noise=float(np.sqrt(3.0 * max(noise[0], 0.0))),
                         spacing_before=sb, spacing_after=sa)


@dataclass(frozen=True, eq=False)
class Coverage:
    """Where the calibration was measured, against where the robot can go.

    Attributes
    ----------
    joint_span : numpy.ndarray
        (n_joints,) the measured span of each reading over its allowed span (limits; an unbounded
        revolute joint one turn), read-only.
    joint_ranges : tuple of (float, float)
        (lo, hi) of each joint's measured readings, SI (rad, m).
    box : tuple of two (float, float, float)
        ((xmin, ymin, zmin), (xmax, ymax, zmax)) of the measured points, m, in W.
    spread_ratio : float
        The RMS spread of the measured points over that of the robot's points at random
        configurations within the limits.
    uncertainty_measured : float
        The RMS position uncertainty (m, one standard deviation as a norm) the parameters'
        covariance gives at the measured poses.
    uncertainty_workspace : float
        The same at those random configurations.
    joint_names : tuple of str
        The joints, in the order of ``joint_span``.
    use_from_campaign : tuple of bool
        Per joint, whether its range of use is the campaign's widened (``use_box``: limits of a full
        turn or more), so that its ``joint_span`` says nothing of the campaign.
    """

    joint_span: np.ndarray
    joint_ranges: tuple[tuple[float, float], ...]
    box: tuple[tuple[float, float, float], tuple[float, float, float]]
    spread_ratio: float
    uncertainty_measured: float
    uncertainty_workspace: float
    joint_names: tuple[str, ...] = ()
    use_from_campaign: tuple[bool, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "joint_span", frozen(self.joint_span))

    @property
    def extrapolation(self) -> float:
        """How much larger the parameters' uncertainty is over the workspace than where measured."""
        if self.uncertainty_measured <= 0:
            return 1.0
        return self.uncertainty_workspace / self.uncertainty_measured


def _uncertainty(design: Points, p: np.ndarray, covariance: np.ndarray, n: int | None = None) -> float:
    """RMS over the readings of ``design`` (``design_like``; its first ``n``) of the position
    uncertainty (norm of one standard deviation) of every marker the data measure, from the free
    parameters' covariance."""
    blocks = design.pose_blocks(p)[:n]             # (n, rows, n_free), unweighted
    k = blocks.shape[-1]
    rows = blocks.reshape(len(blocks), -1, 3 if not design.use_rot else 6, k)[:, :, :3].reshape(-1, k)
    # one matrix product (a three-operand einsum here took 50 times as long at 150 parameters)
    var = np.einsum("ij,ij->i", rows @ covariance, rows).reshape(len(blocks), -1, 3).sum(axis=2)
    return float(np.sqrt(np.mean(np.maximum(var, 0.0))))


def design_like(problem: Points, q: np.ndarray) -> Points:
    """A problem at readings ``q`` with the markers, free parameters and model of ``problem``."""
    data = problem.data
    n, m = len(q), len(data.marker_names)
    fake = Measurements(q=q, positions=np.zeros((n, m, 3)), marker_names=data.marker_names,
                        joint_names=data.joint_names,
                        extra={"approach": np.ones((n, q.shape[1]))} if problem.backlash else {})
    return Points(problem.model, fake, free_names(problem), compliance=problem.compliance, chunked=False)


def use_box(model, q: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper readings of the configurations the robot reaches in use: its joint limits
    (``sampling_box``), except for a revolute joint whose limits allow a full turn or more (a DH
    table's nominal +-360 deg says nothing of its use): there the campaign's range of that joint
    (``q``, readings of the campaign), widened by ``USE_MARGIN`` of it on each side."""
    lo, hi = sampling_box(model)
    if q is None or not len(q):
        return lo, hi
    nominal = full_turn(model)
    # readings beyond the limits (which a check fails) count at the limit they passed
    qlo, qhi = (np.clip(v, model.lower_limits, model.upper_limits) for v in column_extent(q))
    margin = USE_MARGIN * (qhi - qlo)
    lo = np.where(nominal, np.maximum(qlo - margin, model.lower_limits), lo)
    hi = np.where(nominal, np.minimum(qhi + margin, model.upper_limits), hi)
    return lo, hi


def full_turn(model) -> np.ndarray:
    """(n_joints,) bool: revolute joints whose limits allow a full turn or more, whose range of use
    ``use_box`` takes from the campaign."""
    angle = np.zeros(model.n_joints, dtype=bool)
    for f in model.frames:
        for j, _ in f.coupling:
            angle[j] |= f.joint == "revolute"
    return angle & ~(model.upper_limits - model.lower_limits < 2 * np.pi - 1e-9)


def workspace_readings(model, n: int = WORKSPACE_POSES, q: np.ndarray | None = None) -> np.ndarray:
    """``n`` configurations drawn (with a fixed seed) within the box of use (``use_box``; the joint
    limits without ``q``), (n, n_joints)."""
    lo, hi = use_box(model, q)
    return np.random.default_rng(WORKSPACE_SEED).uniform(lo, hi, size=(n, model.n_joints))


def coverage(problem: Points, p: np.ndarray, covariance: np.ndarray, predicted_workspace: np.ndarray, *,
             factor: np.ndarray | None = None, workspace: Points | None = None) -> Coverage:
    """The campaign of ``problem`` against the workspace (``Coverage``); ``predicted_workspace``
    (n, n_markers, 3) the markers at random configurations (``workspace_readings``); ``factor``: an
    R factor of the problem's (unweighted) Jacobian at ``p``, when at hand: the uncertainty at the
    measured poses is then its mean over all of them, trace(C R^T R) / n, without a Jacobian more;
    ``workspace``: the problem at those configurations (``design_like``), when at hand: the
    uncertainty there is carried to its first ``UNCERTAINTY_POSES`` (the same readings drawn)."""
    data = problem.data
    q = data.q
    lo, hi = use_box(problem.model, q)
    allowed = np.where(np.isfinite(hi - lo), hi - lo, 2 * np.pi)
    qlo, qhi = column_extent(q)
    span = (qhi - qlo) / np.where(allowed > 0, allowed, 1.0)
    measured = data.positions[data.mask]
    low, high = column_extent(measured.reshape(-1, 3))
    box = cast("tuple[tuple[float, float, float], tuple[float, float, float]]",   # (x, y, z) each
               (tuple(float(v) for v in low), tuple(float(v) for v in high)))
    ws = point_spread(predicted_workspace)
    ratio = point_spread(measured) / ws if ws > 0 else 1.0
    # the uncertainty at (at most 300 of) the measured poses and at the workspace's configurations
    if factor is not None and not problem.weighted:
        at_measured = float(np.sqrt(max(np.trace(covariance @ (factor.T @ factor)), 0.0)
                                    / max(int(data.mask.sum()), 1)))
    else:
        pick = np.linspace(0, data.n_poses - 1, min(data.n_poses, UNCERTAINTY_POSES)).astype(int)
        at_measured = _uncertainty(design_like(problem, q[pick]), p, covariance)
    if workspace is None:
        workspace = design_like(problem, workspace_readings(problem.model, UNCERTAINTY_POSES, q))
    at_workspace = _uncertainty(workspace, p, covariance, UNCERTAINTY_POSES)
    return Coverage(joint_span=np.minimum(span, 1.0), joint_ranges=tuple((float(a), float(b)) for a, b in
                                                                       zip(qlo, qhi)),
                    box=box, spread_ratio=float(ratio), uncertainty_measured=at_measured,
                    uncertainty_workspace=at_workspace, joint_names=tuple(data.joint_names),
                    use_from_campaign=tuple(bool(v) for v in full_turn(problem.model)))
