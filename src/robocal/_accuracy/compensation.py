"""Compensation: joint commands that put the real (identified) robot where the nominal one was asked to go."""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from .._base.arguments import (
    FLAG,
    NON_NEGATIVE,
    POSITIVE,
    accepts,
    both,
    is_a,
    items,
    marker_of,
    optional,
    readings_of,
    rows_for,
    same_robot_as,
    shaped,
    whole,
)
from .._base.errors import InputError
from .._base.threads import one_blas_thread
from .._model.kinematics import evaluate, layout, transmission_slope
from .._model.measurements import approach_sides
from .._model.parameters import joint_variable_names, parameter_layout, parameter_vector
from .._model.robot import RobotModel

log = logging.getLogger(__name__)


@accepts(model=is_a(RobotModel), q=readings_of(), approach=optional(rows_for("q", lambda args: args["model"].n_joints)))
def joint_jacobian(model: RobotModel, q, approach=None) -> np.ndarray:
    """d(marker pose)/d(joint readings): (N, n_markers, 6, n_joints) in W (rows dx, dy, dz, rotation).

    Parameters
    ----------
    {model, q}
    approach : array_like, shape (n_poses, n_joints), optional
        Direction (+1 or -1) of each joint's last move, for a model with backlash (None: from the
        row order of ``q``, as ``evaluate``).

    Returns
    -------
    numpy.ndarray, shape (n_poses, n_markers, 6, n_joints)
        Derivatives of the marker poses in W by the joint readings.
    """
    lay = parameter_layout(model)
    cols = [lay[n].index for n in joint_variable_names(model)]
    ev = evaluate(model, q, jacobian=True, columns=cols, approach=approach)
    moving = np.array([f.joint != "fixed" for f in model.frames])
    # per frame variable; a transmission error turns the arm's variable d q_eff / d q per reading's turn
    qf = np.atleast_2d(q) @ model.coupling_matrix.T
    slope = transmission_slope(model, layout(model), parameter_vector(model), qf)
    Jf = np.where(moving, ev.jacobian, 0.0) * slope[:, None, None, :]
    return Jf @ model.coupling_matrix


@dataclass(frozen=True)
class Compensation:
    """``q`` (N, n_joints) corrected readings; ``residual`` (N,) remaining position error (m) and
    ``residual_rot`` (N,) orientation error (rad, 0 where orientation was not matched) of the
    corrected poses against the targets; ``within_limits`` (N,) whether the corrected readings
    respect the joint limits; ``oriented`` (N,) whether each target's orientation was matched;
    ``stuck`` (N,) whether the solver no longer approached the target when it stopped (its step
    vanished, or its error fell by less than ``STALL_DROP`` over its last ``STALL_WINDOW`` steps);
    ``outside`` (N, n_joints) which corrected readings lie beyond the ranges the calibration measured
    (``compensate``'s ``ranges``; False throughout without them): there the model is extrapolated."""

    q: np.ndarray
    residual: np.ndarray
    residual_rot: np.ndarray
    within_limits: np.ndarray
    oriented: np.ndarray
    stuck: np.ndarray
    outside: np.ndarray

    def reached(self, tol: float = 1e-6, tol_rot: float = 1e-6) -> np.ndarray:
        """(N,) whether each target was reached within ``tol`` (m) and ``tol_rot`` (rad)."""
        return (self.residual <= tol) & (self.residual_rot <= tol_rot)

    def out_of_reach(self, tol: float = 1e-6, tol_rot: float = 1e-6) -> np.ndarray:
        """(N,) whether each target is not reached and out of reach: the solver no longer approached
        it (``stuck``), or approached it only beyond a joint limit. A target neither reached nor out
        of reach is one the solver was still approaching when it stopped (from a starting guess far
        from it, say): not converged, it may be reachable."""
        return ~self.reached(tol, tol_rot) & (self.stuck | ~self.within_limits)


def registered(model: RobotModel, on: RobotModel) -> RobotModel:
    """``model`` placed on the base of ``on`` (the same ``X_WB``).

    A model's base is where the instrument saw the robot stand: the nominal model's is a guess, the
    calibrated model's the registration its campaign measured (with whatever of the first joint's
    placement no campaign tells apart from it). Neither is a property of the robot that a target
    written in the robot's base frame should feel, so a compensation compares the two models on
    one base (docs/method.md, "Compensation").
    """
    return model.replace(base_position=on.base_position, base_rotation=on.base_rotation)


def on_robot_base(model: RobotModel) -> RobotModel:
    """``model`` with its base at the identity: W is the robot's own base frame."""
    return model.replace(base_position=(0.0, 0.0, 0.0), base_rotation=tuple(map(tuple, np.eye(3))))


def _targets(model, nominal, q0, positions, rotations, marker, orientation, approach):
    """Target positions and rotations in W (N, 3), (N, 3, 3) and which rows match orientation."""
    target = evaluate(nominal, q0, orientations=True, approach=approach)
    Pt = target.positions[:, marker].copy()
    Rt = target.rotations[:, marker].copy()
    if orientation is None:
        orientation = model.n_joints >= 6
    oriented = np.full(len(q0), bool(orientation))
    if positions is not None:
        given = np.all(np.isfinite(positions), axis=1)
        Pt[given] = positions[given]
        oriented[given] = False
        if rotations is not None:
            rot_given = given & np.all(np.isfinite(rotations), axis=(1, 2))
            Rt[rot_given] = rotations[rot_given]
            oriented[rot_given] = True
    return Pt, Rt, oriented


@dataclass(frozen=True)
class _Goal:
    """What the solver is asked, per pose: the marker's position ``P`` (N, 3) and rotation ``R``
    (N, 3, 3) in W, whether the rotation counts (``oriented`` (N,)), and the direction of each
    joint's last move (``approach`` (N, n_joints)), which holds while the readings change: a joint
    with backlash rests on the side its command is approached from, not on one the solver's
    iterates would give."""

    marker: int
    P: np.ndarray
    R: np.ndarray
    oriented: np.ndarray
    approach: np.ndarray

    def rows(self, k) -> _Goal:
        return _Goal(self.marker, self.P[k], self.R[k], self.oriented[k], self.approach[k])

    def errors(self, model, q, p) -> tuple[np.ndarray, np.ndarray]:
        """Position (N, 3) and rotation-vector (N, 3) errors of the marker at readings ``q``, the
        latter zero where the rotation does not count."""
        ev = evaluate(model, q, p, orientations=True, approach=self.approach)
        e_pos = ev.positions[:, self.marker] - self.P
        e_rot = Rotation.from_matrix(ev.rotations[:, self.marker] @ np.swapaxes(self.R, -1, -2)).as_rotvec()
        e_rot[~self.oriented] = 0.0
        return e_pos, e_rot

    def step(self, model, q, e, damping) -> tuple[np.ndarray, np.ndarray]:
        """The damped least-squares step (N, n_joints) that removes the errors ``e`` (N, 6) to first
        order, and the errors (N, 6) it leaves to first order."""
        J = joint_jacobian(model, q, self.approach)[:, self.marker].copy()
        J[~self.oriented, 3:] = 0.0          # position-only rows: the rotation rows ask nothing
        # damped least squares per pose: near a singularity (wrist aligned) an exact step would
        # swing the joints by radians for a micrometre; damping and a step bound keep it local
        JT = np.swapaxes(J, 1, 2)
        A = JT @ J + damping ** 2 * np.eye(J.shape[2])
        # pinv, not solve: where the damping is lost in round-off (joints that move the marker alike,
        # far from it) A is singular and solve raised LinAlgError for every pose
        step = (np.linalg.pinv(A, hermitian=True) @ np.einsum("nji,ni->nj", JT, e)[..., None])[..., 0]
        return step, e - np.einsum("nij,nj->ni", J, step)


def _damped_newton(model, q0, goal: _Goal, *, iterations, tol, damping, max_step):
    """Readings that put the marker on ``goal``'s poses, from ``q0``, and whether each pose stalled:
    damped least-squares steps per pose, each pose left alone once within ``tol`` (m, rad) or once
    its step vanishes (a local minimum). A pose stalled where its step vanished or its error fell by
    less than ``STALL_DROP`` over its last ``STALL_WINDOW`` steps: the solver settled at (or about)
    the nearest pose it finds, out of reach; one that did neither was still approaching its target."""
    q = np.array(q0, dtype=float)
    p = parameter_vector(model)
    active = np.arange(len(q))
    sizes = np.full((iterations, len(q)), np.nan)       # each pose's error, step by step
    vanished = np.zeros(len(q), dtype=bool)
    for it in range(iterations):
        sub = goal.rows(active)
        e_pos, e_rot = sub.errors(model, q[active], p)
        log.info("compensation step %d: largest position error %.3g m", it,
                 np.max(np.linalg.norm(e_pos, axis=1), initial=0.0))
        left = (np.linalg.norm(e_pos, axis=1) >= tol) | (np.abs(e_rot).max(axis=1) >= tol)
        active, e = active[left], np.concatenate([e_pos, e_rot], axis=1)[left]
        if not len(active):
            break
        sizes[it, active] = np.linalg.norm(e, axis=1)
        step = sub.rows(left).step(model, q[active], e, damping)[0]
        big = np.abs(step).max(axis=1, keepdims=True)
        q[active] -= step * np.minimum(1.0, max_step / np.maximum(big, 1e-300))
        vanished[active[big[:, 0] <= 1e-15]] = True
        active = active[big[:, 0] > 1e-15]
    return q, vanished | _stalled(sizes)


# a pose whose error fell by less than this share over its last STALL_WINDOW steps has stalled
STALL_DROP, STALL_WINDOW = 0.01, 10


def _stalled(sizes) -> np.ndarray:
    """(N,) whether each pose's error (``sizes`` (iterations, N), NaN where it took no step) fell by
    less than ``STALL_DROP`` over its last ``STALL_WINDOW`` steps."""
    taken = np.isfinite(sizes)
    last = len(sizes) - 1 - np.argmax(taken[::-1], axis=0)
    cols = np.arange(sizes.shape[1])
    earlier = sizes[np.maximum(last - STALL_WINDOW, 0), cols]
    return taken.any(axis=0) & (last >= STALL_WINDOW) & (sizes[last, cols] > (1.0 - STALL_DROP) * earlier)


# a reading this far (rad, m) beyond a calibrated range is still within it: the range as a file
# holds it, to 15 digits, and a command at the campaign's own extreme are not extrapolations
RANGE_SLACK = 1e-9


def ranges_for(model: str):
    """The rule of a ``ranges`` argument: per joint of the model passed as ``model`` a [lowest,
    highest] reading, NaN where not known."""
    def rule(value, name, args):
        if np.any(np.diff(items(value, name, (2,), args[model].n_joints, finite=False), axis=1) < 0):
            raise InputError("must hold per joint a [lowest, highest] reading, lowest first", where=name)
    return rule


def _outside(q, ranges) -> np.ndarray:
    """(N, n_joints) which readings ``q`` lie beyond ``ranges`` (n_joints, 2; None: none)."""
    if ranges is None:
        return np.zeros(q.shape, dtype=bool)
    r = np.asarray(ranges, dtype=float)
    with np.errstate(invalid="ignore"):         # NaN: a joint whose range is not known
        return (q < r[:, 0] - RANGE_SLACK) | (q > r[:, 1] + RANGE_SLACK)


@accepts(model=is_a(RobotModel), targets_q=readings_of(), nominal=optional(is_a(RobotModel)),
         positions=optional(shaped(None, 3, finite=False)), rotations=optional(shaped(None, 3, 3, finite=False)),
         marker=marker_of(), orientation=optional(FLAG), iterations=whole(1, 10_000), tol=POSITIVE,
         damping=NON_NEGATIVE, max_step=POSITIVE,
         approach=optional(rows_for("targets_q", lambda args: args["model"].n_joints)),
         ranges=optional(ranges_for("model")))
@one_blas_thread
def compensate(model: RobotModel, targets_q, *, nominal: RobotModel | None = None, positions=None,
               rotations=None, marker: int = 0, orientation: bool | None = None, iterations: int = 50,
               tol: float = 1e-10, damping: float = 1e-6, max_step: float = 0.05, approach=None,
               ranges=None) -> Compensation:
    """Readings q' at which ``model`` reaches the pose ``nominal`` reaches at ``targets_q``, both
    on ``model``'s base.

    This is what a controller holding the nominal model needs to send to the identified robot. The
    nominal model is placed on ``model``'s base (``registered``): its own base, a guess of where the
    instrument stood, never moves a target.
    With six or more joints the full pose of ``marker`` is matched (``orientation`` default True),
    otherwise its position only (least-norm correction). ``positions`` (N, 3) and ``rotations``
    (N, 3, 3), W: Cartesian targets instead, where a row is finite; ``targets_q`` is then the
    starting guess (e.g. the nominal controller's inverse kinematics), and orientation is matched
    where a rotation is given. A joint with backlash rests on the side ``approach`` gives for its
    command, the targets visited in row order by default (as ``evaluate``, from ``targets_q``):
    held while solving, so that each command's side is that of the move to it. Damped
    least-squares steps (``damping`` in the Jacobian's units, each step at most ``max_step`` rad or
    m per joint), batched over poses. ``residual`` tells how well each target was reached, and
    ``out_of_reach`` why one was not: out of reach, or near a singularity where the exact pose would
    need a large joint motion, the damped steps settle short of it (``stuck``); from a starting
    guess far from it, they may still be approaching it when ``iterations`` run out.

    Parameters
    ----------
    model : RobotModel
        The calibrated model.
    {targets_q}
    nominal : RobotModel, optional
        The model the controller computes with (default: ``model``); its base is not used.
    {positions, rotations, marker}
    orientation : bool, optional
        Whether to match orientations too (None: when ``rotations`` are given).
    {iterations}
    tol : float
        Position tolerance of a reached target, m.
    {damping, max_step}
    approach : array_like, shape (N, n_joints), optional
        Direction (+1 or -1) of each joint's move to each command (None: the targets visited in row
        order, the first approached from the last; ``robocal.sim.approach_sides`` of ``targets_q``).
    ranges : array_like, shape (n_joints, 2), optional
        Each joint's lowest and highest reading where the model was calibrated (SI, NaN where not
        known: ``robocal.io.read_calibration(path)["joint_ranges"]``); the corrected readings beyond
        them are marked in ``outside``.

    Returns
    -------
    Compensation
        Corrected joint commands, with what each reaches.
    """
    q0 = np.atleast_2d(np.asarray(targets_q, dtype=float))
    approach = approach_sides(q0) if approach is None else np.asarray(approach, dtype=float).reshape(q0.shape)
    nominal = model if nominal is None else registered(nominal, model)
    Pt, Rt, oriented = _targets(model, nominal, q0,
                                None if positions is None else np.asarray(positions, dtype=float).reshape(-1, 3),
                                None if rotations is None else np.asarray(rotations, dtype=float).reshape(-1, 3, 3),
                                marker, orientation, approach)
    goal = _Goal(marker, Pt, Rt, oriented, approach)
    q, stuck = _damped_newton(model, q0, goal, iterations=iterations, tol=tol, damping=damping, max_step=max_step)
    e_pos, e_rot = goal.errors(model, q, parameter_vector(model))
    inside = np.all((q >= model.lower_limits) & (q <= model.upper_limits), axis=1)
    return Compensation(q=q, residual=np.linalg.norm(e_pos, axis=1), residual_rot=np.linalg.norm(e_rot, axis=1),
                        within_limits=inside, oriented=oriented, stuck=stuck, outside=_outside(q, ranges))




# -- Cartesian targets: the nominal controller's inverse kinematics ------------------------------------

# the posture bits of a six-axis arm (docs/formats.md, "Robot programs"): ABB's cfx is
# 4 shoulder + 2 elbow + wrist, KUKA's Status bits 0, 1 and 2 are the same three
POSTURE = ("shoulder_back", "elbow_back", "wrist_negative")
# seeds of the inverse kinematics: this many configurations sampled over the joint limits, and
# at most this many tried per target (nearest pose first)
N_SEEDS, SEED_TRIES = 4096, 6
HALTON_PRIMES = (2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37, 41, 43, 47, 53)
MAX_SEEDED_JOINTS = len(HALTON_PRIMES)


@accepts(model=is_a(RobotModel), marker=marker_of())
def arm_chain(model: RobotModel, marker: int = 0) -> tuple[int, ...]:
    """Indices of the moving frames from the base to ``marker``'s frame, base first.

    Parameters
    ----------
    {model, marker}

    Returns
    -------
    tuple of int
        Frame indices, base first.
    """
    chain, i = [], model.markers[marker].frame
    while i >= 0:
        if model.frames[i].joint != "fixed":
            chain.append(i)
        i = model.frames[i].parent
    return tuple(reversed(chain))


def _six_axes(value, name, args):
    """A model with six moving frames on the chain to the marker (checked after ``marker``)."""
    is_a(RobotModel)(value, name, args)
    marker_of(name)(args.get("marker", 0), "marker", args)
    n = len(arm_chain(value, args.get("marker", 0)))
    if n < 6:
        raise InputError(f"must have six moving frames on the chain to the marker, got {n}", where=name)


@accepts(model=_six_axes, q=readings_of(), marker=marker_of())
def posture(model: RobotModel, q, *, marker: int = 0) -> np.ndarray:
    """(N, 3) posture bits of a six-axis arm at readings ``q`` (N, n_joints), columns ``POSTURE``.

    With frames 1 to 6 the first six moving frames on the chain to ``marker`` (origin O_i on
    joint i's axis z_i, MDH) and the wrist centre c = O_5: ``shoulder_back`` when c lies behind
    axis 1, ``(c - O_1) . x_1 < 0``; ``elbow_back`` when c lies on the negative side of the lower
    arm, ``((O_3 - O_2) x (c - O_2)) . z_2 < 0`` (the elbow singularity is where the two agree in
    line); ``wrist_negative`` when joint 5's reading is negative. A bit whose test is within
    ``POSTURE_TOL`` of zero (``posture_margins``) is on its boundary: either value describes it.

    Parameters
    ----------
    model : RobotModel
        A model with at least six moving frames on the chain to ``marker``.
    q : array_like
        (N, n_joints) joint readings, SI.
    marker : int
        The marker whose chain defines frames 1 to 6.

    Returns
    -------
    numpy.ndarray
        (N, 3) booleans.
    """
    return posture_margins(model, q, marker=marker) < 0


# a posture test (a ratio of lengths, or joint 5's reading in rad) this close to zero is on its
# boundary: round-off, not a configuration (a cylindrical arm's shoulder and elbow tests are 1e-16)
POSTURE_TOL = 1e-9


def posture_margins(model: RobotModel, q, *, marker: int = 0) -> np.ndarray:
    """(N, 3) signed tests of the posture bits (``posture``), each scaled to no unit: the shoulder's
    by |c - O_1|, the elbow's by |O_3 - O_2| |c - O_2|; joint 5's reading (rad)."""
    chain = arm_chain(model, marker)
    if len(chain) < 6:
        raise ValueError(f"a posture needs six moving frames to the marker, the model has {len(chain)}")
    q = np.atleast_2d(np.asarray(q, dtype=float))
    X = evaluate(model, q, frames=True).frames
    f1, f2, f3, _, f5, _ = chain[:6]
    origin, wc = X[:, :, :3, 3], X[:, f5, :3, 3]
    arm, lower = wc - origin[:, f1], origin[:, f3] - origin[:, f2]
    reach = wc - origin[:, f2]
    tiny = np.finfo(float).tiny
    shoulder = np.einsum("ni,ni->n", arm, X[:, f1, :3, 0]) / np.maximum(np.linalg.norm(arm, axis=1), tiny)
    elbow = np.einsum("ni,ni->n", np.cross(lower, reach), X[:, f2, :3, 2]) / np.maximum(
        np.linalg.norm(lower, axis=1) * np.linalg.norm(reach, axis=1), tiny)
    j5 = model.frames[f5].coupling[0][0] if model.frames[f5].coupling else 4
    return np.stack([shoulder, elbow, q[:, j5]], axis=1)


def distinct_postures(model: RobotModel, marker: int = 0) -> np.ndarray:
    """(3,) whether each posture bit (``POSTURE``) tells two configurations of ``model`` apart: its
    test takes both signs beyond ``POSTURE_TOL`` over the joint ranges (a cylindrical arm has one
    shoulder and one elbow configuration only)."""
    m = _seed_table(model, marker)[2]
    return _distinct(m)


def _distinct(margins) -> np.ndarray:
    return np.any(margins > POSTURE_TOL, axis=0) & np.any(margins < -POSTURE_TOL, axis=0)


def posture_fits(margins, want, distinct) -> np.ndarray:
    """(N,) whether postures with ``margins`` (N, 3) are the ones ``want`` (N, 3: 0, 1, -1 free) asks
    for: a bit that is free, on its boundary, or that tells no configurations apart (``distinct``)
    always fits."""
    free = (want < 0) | ~np.asarray(distinct)[None] | (np.abs(margins) <= POSTURE_TOL)
    return np.all(free | ((margins < 0) == (want > 0)), axis=1)


def configuration_fits(model: RobotModel, q, want, turn_from, *, marker: int = 0) -> np.ndarray:
    """(N,) whether readings ``q`` (N, n_joints) are the solution the nominal inverse kinematics gives
    in the configuration asked for: the posture ``want`` (N, 3) (``posture_fits``, on ``model``'s
    distinct postures) and each revolute reading inside its turn ``[turn_from, turn_from + 2 pi)``
    where finite (as in ``inverse_kinematics``)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    fits = posture_fits(posture_margins(model, q, marker=marker), np.asarray(want), distinct_postures(model, marker))
    return fits & np.all(np.abs(_turned(model, q, np.asarray(turn_from, dtype=float)) - q) < 1e-9, axis=1)


def _seed_table(model: RobotModel, marker: int):
    """Configurations spread over the joint limits (a Halton sequence, the same every call; a
    revolute joint's range cut to one turn) and the pose features and postures they give."""
    lo, hi = model.lower_limits.copy(), model.upper_limits.copy()
    angle = np.array([k == "angle" for k in model.reading_quantities])
    wide = angle & (hi - lo > 2 * np.pi)
    mid = 0.5 * (lo + hi)
    lo[wide], hi[wide] = mid[wide] - np.pi, mid[wide] + np.pi
    q = lo + (hi - lo) * _halton(N_SEEDS, model.n_joints)
    ev = evaluate(model, q, orientations=True)
    return q, _features(ev.positions[:, marker], ev.rotations[:, marker]), posture_margins(model, q, marker=marker)


def _halton(n: int, d: int) -> np.ndarray:
    """(n, d) points of the Halton sequence in [0, 1) (radical inverses in the first d primes), from the second on."""
    primes = HALTON_PRIMES[:d]
    if len(primes) < d:
        raise ValueError(f"seeds for up to {len(primes)} joints, not {d}")
    k = np.arange(1, n + 1)
    out = np.zeros((n, d))
    for j, b in enumerate(primes):
        i, f = k.copy(), 1.0
        while np.any(i):
            f /= b
            out[:, j] += f * (i % b)
            i //= b
    return out


def _features(P, R):
    """Pose features for nearest-pose lookups: metres, and the rotation's entries a quarter metre each."""
    return np.concatenate([P, 0.25 * R.reshape(len(R), 9)], axis=1)


def _turned(model: RobotModel, q, turn_from):
    """``q`` with each revolute reading moved by whole turns into [turn_from, turn_from + 2 pi) where
    ``turn_from`` is finite."""
    if turn_from is None:
        return q
    angle = np.array([k == "angle" for k in model.reading_quantities])
    use = np.isfinite(turn_from) & angle
    start = np.where(use, turn_from, 0.0)
    return np.where(use, start + np.mod(q - start, 2 * np.pi), q)


@dataclass(frozen=True)
class InverseKinematics:
    """``q`` (N, n_joints) readings; ``solved`` (N,) whether the pose was reached (within the
    tolerances) in the posture asked for; ``within_limits`` (N,) whether ``q`` respects the joint
    limits. Where no seed solved a target, ``q`` is the last attempt."""

    q: np.ndarray
    solved: np.ndarray
    within_limits: np.ndarray


def _seed_order(table_f, table_margins, features, want, k: int) -> np.ndarray:
    """(N, k) indices of the table's configurations nearest each target's pose among those of the
    posture ``want`` (N, 3) (0/1, -1 where a bit is free)."""
    from scipy.spatial import cKDTree

    order = np.zeros((len(features), k), dtype=int)
    for pattern in np.unique(want, axis=0):
        rows = np.all(want == pattern, axis=1)
        fits = posture_fits(table_margins, pattern[None], np.ones(3, dtype=bool))
        pool = np.flatnonzero(fits) if fits.any() else np.arange(len(table_f))
        kk = min(k, len(pool))
        _, idx = cKDTree(table_f[pool]).query(features[rows], k=kk)
        idx = np.asarray(idx).reshape(int(rows.sum()), kk)
        idx[idx >= len(pool)] = 0    # a target too far for any finite distance: any seed, it will not solve
        order[rows] = pool[np.concatenate([idx, np.repeat(idx[:, -1:], k - kk, axis=1)], axis=1)]
    return order


def _points(value, name, _):
    """Positions (n, 3), finite; one may be given as (3,)."""
    items(value, name, (3,))


def _rotations(value, name, args):
    """Rotation matrices, one per position: (n, 3, 3), finite; one may be given as (3, 3)."""
    items(value, name, (3, 3), len(np.atleast_2d(np.asarray(args["positions"], dtype=float))))


def _bits(value, name, args):
    """Posture bits per pose (n, 3): 0, 1, or -1 where free."""
    rows_for("positions", lambda _: 3)(value, name, args)
    if not np.all(np.isin(np.asarray(value, dtype=float), (-1, 0, 1))):
        raise InputError("must hold posture bits 0 or 1, -1 where free", where=name)


def _joints(args) -> int:
    return next(iter(args.values())).n_joints        # of the model, the first argument


def _seeded(value, name, args):
    """A six-axis arm (``_six_axes``) with at most as many joints as the seeds' Halton sequence has primes."""
    _six_axes(value, name, args)
    if value.n_joints > MAX_SEEDED_JOINTS:
        raise InputError(f"must have at most {MAX_SEEDED_JOINTS} joints for the inverse kinematics, got "
                         f"{value.n_joints}", where=name)


_TARGETS = dict(positions=_points, rotations=_rotations, want=optional(_bits),
                turn_from=optional(rows_for("positions", _joints, finite=False)),
                hints=optional(rows_for("positions", _joints, finite=False)))


@accepts(model=_seeded, **_TARGETS, tol=POSITIVE, iterations=whole(1, 10_000))
@one_blas_thread
def inverse_kinematics(model: RobotModel, positions, rotations, *, marker: int = 0, want=None, turn_from=None,
                       hints=None, tol: float = 1e-10, iterations: int = 100) -> InverseKinematics:
    """Readings at which ``model`` puts ``marker`` on the poses (``positions`` (N, 3), ``rotations``
    (N, 3, 3), W), in a chosen configuration: the numerical inverse kinematics of a controller that
    holds ``model``.

    ``want`` (N, 3): the posture bits (``POSTURE``) asked for, 0 or 1, -1 where a bit is free.
    ``turn_from`` (N, n_joints): each revolute reading is taken in ``[turn_from, turn_from + 2 pi)``
    where finite (a turn or quadrant of the program's configuration data). ``hints`` (N, n_joints):
    first starting guesses where finite (e.g. the controller's current joints). Then damped Newton
    steps from the configurations nearest the pose among ``N_SEEDS`` spread over the limits and of
    the posture asked for, nearest first, until a solution has the posture and respects the limits
    (``SEED_TRIES`` at most); a solution beyond the limits is kept when no other is found.

    Parameters
    ----------
    model : RobotModel
        The model the controller holds.
    positions : array_like, shape (N, 3)
        Positions of ``marker`` to reach, W, m.
    rotations : array_like, shape (N, 3, 3)
        Orientations of ``marker`` to reach, W.
    marker : int
        The marker (tool point) placed on the poses.
    want : array_like, shape (N, 3), optional
        Posture bits asked for (None: free).
    turn_from : array_like, shape (N, n_joints), optional
        Start of each revolute reading's turn, NaN where free (None: all free).
    hints : array_like, shape (N, n_joints), optional
        First starting guesses, NaN where none (None: none).
    tol : float
        Position (m) and rotation (rad) residual at which a pose counts as reached (within 10 tol).
    iterations : int
        Damped Newton steps per seed at most.

    Returns
    -------
    InverseKinematics
        The readings, whether each pose was reached and whether they respect the joint limits.
    """
    P = np.asarray(positions, dtype=float).reshape(-1, 3)
    R = np.asarray(rotations, dtype=float).reshape(-1, 3, 3)
    n = len(P)
    want = np.full((n, 3), -1) if want is None else np.asarray(want, dtype=int).reshape(n, 3)
    turn_from = np.full((n, model.n_joints), np.nan) if turn_from is None else np.asarray(turn_from, dtype=float)
    table_q, table_f, table_margins = _seed_table(model, marker)
    distinct = _distinct(table_margins)
    want = np.where(distinct[None], want, -1)      # a bit that tells no configurations apart asks nothing
    seeds = [table_q[i] for i in _seed_order(table_f, table_margins, _features(P, R), want, SEED_TRIES).T]
    if hints is not None:                       # first the hint, then the table's seeds one round later
        hinted = np.all(np.isfinite(np.asarray(hints, dtype=float)), axis=1, keepdims=True)
        seeds = [np.where(hinted, hints, seeds[0])] + [np.where(hinted, seeds[k], seeds[min(k + 1, len(seeds) - 1)])
                                                      for k in range(len(seeds))]
    q = np.full((n, model.n_joints), np.nan)
    state = np.zeros(n, dtype=int)              # 0 nothing yet, 1 solved beyond the limits, 2 solved
    # a target farther than twice the reach seen over the joint ranges is out of reach: not solved for
    # (Newton's steps on it would overflow), its seed kept as the attempt
    reach = np.max(np.linalg.norm(table_f[:, :3], axis=1))
    far = ~np.all(np.abs(P) <= 2.0 * reach + 1.0, axis=1)
    q[far] = seeds[0][far]
    state[far] = 2
    p = parameter_vector(model)
    # the controller's model: a joint with backlash on one side throughout, so that a target's
    # solution never depends on which others are solved with it
    goal = _Goal(marker, P, R, np.ones(n, dtype=bool), np.ones((n, model.n_joints)))
    for seed in seeds:
        todo = np.flatnonzero(state < 2)
        if not len(todo):
            break
        qk = _damped_newton(model, seed[todo], goal.rows(todo), iterations=iterations, tol=tol, damping=1e-6,
                            max_step=0.3)[0]
        qk = _turned(model, qk, turn_from[todo])
        e_pos, e_rot = goal.rows(todo).errors(model, qk, p)
        good = (np.linalg.norm(e_pos, axis=1) <= 10 * tol) & (np.linalg.norm(e_rot, axis=1) <= 10 * tol)
        good &= posture_fits(posture_margins(model, qk, marker=marker), want[todo], distinct)
        inside = np.all((qk >= model.lower_limits) & (qk <= model.upper_limits), axis=1)
        level = np.where(good, np.where(inside, 2, 1), 0)
        better = (level > state[todo]) | np.isnan(q[todo, 0])
        q[todo[better]] = qk[better]
        state[todo] = np.maximum(state[todo], level)
    inside = np.all((q >= model.lower_limits) & (q <= model.upper_limits), axis=1)
    return InverseKinematics(q=q, solved=(state > 0) & ~far, within_limits=inside)


@dataclass(frozen=True)
class PoseCompensation:
    """Cartesian targets compensated: ``q_nominal`` (N, n_joints) the readings the nominal
    controller's inverse kinematics gives for each target; ``q`` (N, n_joints) the readings that put
    the calibrated robot on the target; ``positions`` (N, 3) and ``rotations`` (N, 3, 3), W, the pose
    the nominal model reaches at ``q``: the target to give the controller. ``solved`` (N,) whether the
    nominal inverse kinematics found the target in its configuration; ``compensation`` the
    calibrated robot's residuals and joint limits at ``q``."""

    q_nominal: np.ndarray
    q: np.ndarray
    positions: np.ndarray
    rotations: np.ndarray
    solved: np.ndarray
    compensation: Compensation


@accepts(nominal=_seeded, calibrated=both(is_a(RobotModel), same_robot_as("nominal")), **_TARGETS,
         ranges=optional(ranges_for("nominal")))
def compensate_poses(nominal: RobotModel, calibrated: RobotModel, positions, rotations, *, marker: int = 0,
                     want=None, turn_from=None, hints=None, ranges=None) -> PoseCompensation:
    """Targets for a controller holding ``nominal`` so that the calibrated robot reaches the poses
    (``positions`` (N, 3), ``rotations`` (N, 3, 3), W) the nominal model gives them, both models on
    ``calibrated``'s base (``registered``: the nominal base, a guess of where the instrument stood,
    never moves a target; with both bases at the identity, W is the robot's base frame).

    The nominal inverse kinematics (``inverse_kinematics``, in the configuration ``want`` and
    ``turn_from`` ask for) gives the readings the controller would command; ``compensate`` gives
    the readings ``q`` at which ``calibrated`` reaches the intended pose; the nominal model's pose
    at ``q`` is the target to send, so that the controller's own inverse kinematics yields ``q``.

    Parameters
    ----------
    nominal : RobotModel
        The model the controller holds (a six-axis arm).
    calibrated : RobotModel
        The calibrated model (the nominal's joints and markers).
    positions : array_like, shape (N, 3)
        Intended positions of ``marker`` in W (``calibrated``'s), m.
    rotations : array_like, shape (N, 3, 3)
        Intended orientations of ``marker`` in W (``calibrated``'s).
    marker : int
        The marker (tool point) placed on the targets.
    want : array_like, shape (N, 3), optional
        As in ``inverse_kinematics``.
    turn_from : array_like, shape (N, n_joints), optional
        As in ``inverse_kinematics``.
    hints : array_like, shape (N, n_joints), optional
        As in ``inverse_kinematics``.
    ranges : array_like, shape (n_joints, 2), optional
        As in ``compensate``.

    Returns
    -------
    PoseCompensation
        Readings, targets to send and the calibrated robot's residuals.
    """
    P = np.asarray(positions, dtype=float).reshape(-1, 3)
    R = np.asarray(rotations, dtype=float).reshape(-1, 3, 3)
    nominal = registered(nominal, calibrated)
    ik = inverse_kinematics(nominal, P, R, marker=marker, want=want, turn_from=turn_from, hints=hints)
    start = np.where(ik.solved[:, None], ik.q, 0.0)
    comp = compensate(calibrated, start, nominal=nominal, positions=np.where(ik.solved[:, None], P, np.nan),
                      rotations=R, marker=marker, orientation=True, ranges=ranges)
    ev = evaluate(nominal, comp.q, orientations=True, approach=np.ones_like(comp.q))     # as its inverse kinematics
    return PoseCompensation(q_nominal=ik.q, q=comp.q, positions=ev.positions[:, marker],
                            rotations=ev.rotations[:, marker], solved=ik.solved, compensation=comp)
