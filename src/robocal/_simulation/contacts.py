"""Simulated joint-only campaigns: sockets on plates, plane contacts and ball bars.

A true robot is driven (numerical inverse kinematics from random starts, so every pose reaches the
target in its own way) to put its marker on a socket, a plane or a bar's end; the recorded readings
carry encoder noise and the contact its own seating scatter. The stated deviation of each row is
the seating scatter combined with what the encoder noise moves the marker by at that pose.
Every random function takes an explicit seed or ``numpy.random.Generator``.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from .._base.arguments import (
    FLAG,
    MAPPING,
    NON_NEGATIVE,
    POSITIVE,
    SEED,
    accepts,
    in_range,
    is_a,
    marker_of,
    shaped,
    whole,
)
from .._base.errors import InputError
from .._base.spatial import vector3
from .._model.configurations import random_configurations, sampling_box
from .._model.contacts import Contacts, KnownDistance, KnownPlane
from .._model.kinematics import evaluate
from .._model.parameters import parameter_layout
from .._model.robot import RobotModel

# a 3-socket plate (m, in the plate's frame): spacings of 200, 150 and 250 mm
PLATE = {"A": (0.0, 0.0, 0.0), "B": (0.2, 0.0, 0.0), "C": (0.0, 0.15, 0.0)}
# where plates and planes are put: a box in front of a 7-joint arm of about 0.8 m reach (m, in W)
WORK_BOX = ((0.45, -0.35, 0.05), (0.65, 0.35, 0.45))


def _joint_jacobian(model: RobotModel, q: np.ndarray, marker: int) -> tuple[np.ndarray, np.ndarray]:
    """The marker's positions (N, 3) and d(position)/d(readings) (N, 3, n_joints): the columns of
    the moving parameters (theta of a revolute frame, r of a prismatic one) through the coupling."""
    lay = parameter_layout(model)
    moving = [lay[f"{f.name}.{'theta' if f.joint == 'revolute' else 'r'}"].index for f in model.frames]
    ev = evaluate(model, q, jacobian=True, columns=moving)
    return ev.positions[:, marker], ev.jacobian[:, marker, :3] @ model.coupling_matrix


@accepts(model=is_a(RobotModel), targets=shaped(None, 3), marker=marker_of(), rng=SEED, tol=POSITIVE,
         max_rounds=whole(1, 1000))
def reach(model: RobotModel, targets, *, marker: int = 0, rng=None, tol: float = 1e-10, max_rounds: int = 40):
    """Readings (N, n_joints) within the joint limits that put ``marker`` on each of ``targets`` (N, 3),
    each from its own random start (damped least squares). Targets no start reaches raise InputError
    (out of the robot's reach, e.g. a plate placed where the arm cannot seat).

    Parameters
    ----------
    model : RobotModel
        The robot.
    {targets, marker, rng}
    tol : float
        Position tolerance of a reached target, m.
    {max_rounds}

    Returns
    -------
    numpy.ndarray, shape (n, n_joints)
        Joint readings within the limits that reach the targets.
    """
    rng = np.random.default_rng(rng)
    targets = np.atleast_2d(np.asarray(targets, dtype=float))
    lo, hi = sampling_box(model)
    out = np.full((len(targets), model.n_joints), np.nan)
    todo = np.arange(len(targets))
    for _ in range(max_rounds):
        q = random_configurations(model, len(todo), rng)
        for it in range(40):
            P, J = _joint_jacobian(model, q, marker)
            e = targets[todo] - P
            if it > 10 and np.all(np.linalg.norm(e, axis=1) < tol):
                break
            JJt = J @ J.transpose(0, 2, 1) + (1e-6 if it < 20 else 0.0) * np.eye(3)
            # pinv, not solve: at a singular pose (a stretched arm, a joint that moves nothing) the step
            # is the least-squares one instead of a LinAlgError
            step = (J.transpose(0, 2, 1) @ np.linalg.pinv(JJt, hermitian=True) @ e[..., None])[..., 0]
            q = np.clip(q + np.nan_to_num(step, nan=0.0, posinf=0.0, neginf=0.0), lo, hi)
        err = np.linalg.norm(targets[todo] - evaluate(model, q).positions[:, marker], axis=1)
        ok = err < tol
        out[todo[ok]] = q[ok]
        todo = todo[~ok]
        if not len(todo):
            return out
    x, y, z = targets[todo[0]]
    raise InputError(f"{len(todo)} of {len(targets)} target(s) out of the robot's reach within its joint limits, "
                     f"e.g. ({x:.4g}, {y:.4g}, {z:.4g}) m in W", where="targets")


def _recorded(model, q, marker, rng, joint_noise, seat_noise):
    """Readings with encoder noise and the stated deviation of each row (m): the seating scatter and
    what the encoder noise moves the marker by (per axis, on average over the axes)."""
    J = _joint_jacobian(model, q, marker)[1]
    moved = joint_noise * np.sqrt(np.sum(J ** 2, axis=(1, 2)) / 3.0)
    return q + rng.normal(0.0, joint_noise, q.shape), np.hypot(seat_noise, moved)


@accepts(n=whole(1, 1000), rng=SEED, box=shaped(2, 3), tilt_deg=in_range(0.0, 90.0))
def plate_placements(n: int, rng=None, box=WORK_BOX, tilt_deg: float = 20.0):
    """``n`` plate poses (origin (3,), rotation (3, 3)) in ``box``: turned freely about z, tilted up
    to ``tilt_deg``.

    Parameters
    ----------
    n : int
        Number of placements.
    {rng, box, tilt_deg}

    Returns
    -------
    list of numpy.ndarray
        The plate poses in W, (4, 4) each.
    """
    rng = np.random.default_rng(rng)
    out = []
    for _ in range(n):
        origin = rng.uniform(box[0], box[1])
        tilt = Rotation.from_rotvec(np.r_[rng.normal(size=2), 0.0] / np.sqrt(2) * np.deg2rad(tilt_deg) * rng.uniform())
        out.append((origin, (tilt * Rotation.from_euler("z", rng.uniform(-np.pi, np.pi))).as_matrix()))
    return out


@accepts(true=is_a(RobotModel), placements=whole(1, 1000), poses_per_socket=whole(1, 10_000), plate=MAPPING,
         joint_noise=NON_NEGATIVE, seat_noise=NON_NEGATIVE, distance_sigma=POSITIVE, marker=marker_of("true"),
         known_distances=FLAG, rng=SEED)
def socket_campaign(true: RobotModel, *, placements: int = 3, poses_per_socket: int = 25, plate=PLATE,
                    joint_noise: float = 2e-5, seat_noise: float = 5e-6, distance_sigma: float = 2e-6,
                    marker: int = 0, known_distances: bool = True, rng=None) -> Contacts:
    """The true robot's ball seated ``poses_per_socket`` times in each socket of ``plate`` (name ->
    position in the plate, m) at ``placements`` random placements; ``known_distances`` states every
    spacing of the plate (with ``distance_sigma``).

    Parameters
    ----------
    {true, placements, poses_per_socket, plate, joint_noise, seat_noise, distance_sigma}
    marker : int
        Index of the probing marker in the model.
    {known_distances, rng}

    Returns
    -------
    Contacts
        The simulated recordings.
    """
    rng = np.random.default_rng(rng)
    names = tuple(plate)
    local = np.array([plate[s] for s in names])
    local = local - local.mean(axis=0)           # the plate's centre where the placement puts it
    rows_q, target, placement, sig = [], [], [], []
    for k, (origin, R) in enumerate(plate_placements(placements, rng)):
        pts = origin + local @ R.T
        goal = np.repeat(pts, poses_per_socket, axis=0)
        seat = goal + rng.normal(0.0, seat_noise, goal.shape)
        q = reach(true, seat, marker=marker, rng=rng)
        qn, s = _recorded(true, q, marker, rng, joint_noise, seat_noise)
        rows_q.append(qn)
        sig.append(s)
        target += [n for n in names for _ in range(poses_per_socket)]
        placement += [f"P{k + 1}"] * len(goal)
    distances = tuple(KnownDistance(a, b, float(np.linalg.norm(local[i] - local[j])), distance_sigma)
                      for i, a in enumerate(names) for j, b in enumerate(names) if i < j) if known_distances else ()
    q = np.vstack(rows_q)
    return Contacts(q=q, marker=(true.marker_names[marker],) * len(q), kind=("socket",) * len(q), target=tuple(target),
                    placement=tuple(placement), sigma=np.concatenate(sig), distances=distances,
                    joint_names=true.joint_names, source="simulated")


@accepts(true=is_a(RobotModel), planes=whole(1, 1000), poses_per_plane=whole(1, 10_000), joint_noise=NON_NEGATIVE,
         seat_noise=NON_NEGATIVE, extent=POSITIVE, marker=marker_of("true"), known=FLAG, rng=SEED)
def plane_campaign(true: RobotModel, *, planes: int = 4, poses_per_plane: int = 30, joint_noise: float = 2e-5,
                   seat_noise: float = 5e-6, extent: float = 0.15, marker: int = 0, known: bool = False,
                   rng=None) -> Contacts:
    """The true robot's marker on ``planes`` random planes (tilted up to 45 deg), ``poses_per_plane``
    points each within ``extent`` (m) of the plane's centre; ``known`` states the planes.

    Parameters
    ----------
    {true, planes, poses_per_plane, joint_noise, seat_noise, extent}
    marker : int
        Index of the probing marker in the model.
    known : bool
        Whether the planes are known (position and normal).
    {rng}

    Returns
    -------
    Contacts
        The simulated recordings.
    """
    rng = np.random.default_rng(rng)
    rows_q, target, sig, known_planes = [], [], [], []
    for k, (origin, R) in enumerate(plate_placements(planes, rng, tilt_deg=45.0)):
        local = np.c_[rng.uniform(-extent, extent, (poses_per_plane, 2)), np.zeros(poses_per_plane)]
        pts = origin + local @ R.T + np.outer(rng.normal(0.0, seat_noise, poses_per_plane), R[:, 2])
        q = reach(true, pts, marker=marker, rng=rng)
        qn, s = _recorded(true, q, marker, rng, joint_noise, seat_noise)
        rows_q.append(qn)
        sig.append(s)
        target += [f"plane{k + 1}"] * poses_per_plane
        known_planes.append(KnownPlane(f"plane{k + 1}", vector3(R[:, 2]), float(R[:, 2] @ origin)))
    q = np.vstack(rows_q)
    return Contacts(q=q, marker=(true.marker_names[marker],) * len(q), kind=("plane",) * len(q), target=tuple(target),
                    placement=("",) * len(q), sigma=np.concatenate(sig), planes=tuple(known_planes) if known else (),
                    joint_names=true.joint_names, source="simulated")


@accepts(true=is_a(RobotModel), pairs=whole(1, 100_000), length=POSITIVE, length_sigma=POSITIVE,
         joint_noise=NON_NEGATIVE, seat_noise=NON_NEGATIVE, marker=marker_of("true"), rng=SEED)
def bar_campaign(true: RobotModel, *, pairs: int = 60, length: float = 0.2, length_sigma: float = 2e-6,
                 joint_noise: float = 2e-5, seat_noise: float = 5e-6, marker: int = 0, rng=None) -> Contacts:
    """``pairs`` ball-bar measurements: the marker at two poses ``length`` (m) apart, ends in the work box.

    Parameters
    ----------
    {true, pairs, length, length_sigma, joint_noise, seat_noise}
    marker : int
        Index of the probing marker in the model.
    {rng}

    Returns
    -------
    Contacts
        The simulated recordings.
    """
    rng = np.random.default_rng(rng)
    lo, hi = np.asarray(WORK_BOX[0]), np.asarray(WORK_BOX[1])
    a, b = np.zeros((0, 3)), np.zeros((0, 3))
    while len(a) < pairs:    # both ends in the work box
        a1 = rng.uniform(lo, hi, (pairs, 3))
        u = rng.normal(size=(pairs, 3))
        b1 = a1 + length * u / np.linalg.norm(u, axis=1, keepdims=True)
        inside = np.all((b1 >= lo) & (b1 <= hi), axis=1)
        a, b = np.vstack([a, a1[inside]])[:pairs], np.vstack([b, b1[inside]])[:pairs]
    ends = np.empty((2 * pairs, 3))
    ends[0::2], ends[1::2] = a, b
    q = reach(true, ends + rng.normal(0.0, seat_noise, ends.shape), marker=marker, rng=rng)
    qn, s = _recorded(true, q, marker, rng, joint_noise, seat_noise)
    n = len(q)
    return Contacts(q=qn, marker=(true.marker_names[marker],) * n, kind=("bar",) * n, target=("bar",) * n,
                    placement=tuple(f"pair{i // 2 + 1}" for i in range(n)), sigma=s,
                    bars={"bar": (length, length_sigma)}, joint_names=true.joint_names, source="simulated")
