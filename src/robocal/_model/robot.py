"""The robot model: an immutable description in SI units.

Conventions (see docs/conventions.md):

* ``W`` is the measurement frame (laser tracker, theodolites, CMM), ``B`` the robot's frame 0.
* Frame ``j`` is placed relative to its parent frame ``p`` by the modified Denavit-Hartenberg
  transform of Khalil and Kleinfinger extended with Hayati's beta::

      X_pj = Rot(z, gamma) Trans(z, b) Rot(y, beta) Rot(x, alpha) Trans(x, d) Rot(z, theta) Trans(z, r)

  For a serial chain gamma = b = 0 and the parent is the predecessor; gamma and b place a frame that
  hangs off a frame other than its predecessor (kinematic trees).
* The joint variable adds to theta (revolute) or r (prismatic); theta and r themselves are the
  constant offsets, so their error is the encoder-offset error.
* Compliance: theta, alpha and beta deflect by ``K * M`` with ``M`` the gravity moment about the
  parameter's own rotation axis (docs/conventions.md).
* Backlash (docs/conventions.md): a joint's arm rests ``backlash_theta`` (revolute) or ``backlash_r``
  (prismatic), half its lost motion, to one side of its reading: q_eff = q + b s, with the side s
  set per pose by the model's ``backlash_side`` (the gravity load or the approach direction).
* Transmission (docs/conventions.md): the joint variable the arm reaches is
  q_eff = q (1 + gear_scale) + a_k cos(k q) + b_k sin(k q) + the same in the motor angle n q, with
  n the frame's stated ``reduction`` ratio (0: not stated, no motor terms).
* The base pose ``X_WB`` and a marker's orientation carry small rotation corrections rx, ry, rz that
  are zero in any stored model: identification composes them into the stored rotation.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass, field, fields, replace
from typing import Any

import numpy as np

from .._base.arguments import (
    FLAG,
    MAPPING,
    POSITIVE,
    SEQUENCE,
    TEXT,
    accepts,
    each_a,
    in_range,
    is_a,
    one_of,
    optional,
    shaped,
    whole,
)
from .._base.errors import InputError
from .._base.options import BACKLASH_SIDES, MAX_FRAMES, MAX_MARKERS
from .._base.spatial import rot4, rot_matrix, trans4, vector3

JOINT_TYPES = ("revolute", "prismatic", "fixed")
DEFAULT_PARALLEL_TOL = np.deg2rad(1.0)
# the transmission terms of a frame, in the order of the parameter layout (docs/conventions.md)
TRANSMISSION_KINDS = ("gear_scale", "gear_cos1", "gear_sin1", "gear_cos2", "gear_sin2",
                      "motor_cos1", "motor_sin1", "motor_cos2", "motor_sin2")


@dataclass(frozen=True)
class Frame:
    """One frame of the modified-DH description, fixed to one link.

    Lengths in metres, angles in radians, mass in kg, compliance in rad/(N m) (the moment of a
    prismatic frame's theta axis is a torque too, so the unit is the same for every frame).
    ``coupling`` gives the joint variable as ``sum(coef * reading[index])``; for an ordinary joint
    it is ``((own_index, 1.0),)`` and for a fixed frame it is empty.
    ``backlash_theta`` (rad) and ``backlash_r`` (m): half the joint's lost motion, on the revolute and
    the prismatic joint variable. ``backlash_friction`` and ``backlash_width`` (N m on a revolute
    frame, N on a prismatic one) shape the gravity-sided side ``tanh((L - a F) / w)``: F the load the
    transmission's friction holds (0: gravity alone decides), w the width of the smooth transition.
    Transmission errors (docs/conventions.md): ``gear_scale`` the gear ratio's relative error, and
    harmonics of the joint angle (``gear_cos1`` ... ``gear_sin2``, rad) and, where the frame states its
    ``reduction`` ratio (motor turns per joint turn; 0: not stated), of the motor angle
    (``motor_cos1`` ... ``motor_sin2``, rad). Harmonics belong to revolute joints only.
    """

    name: str
    joint: str = "revolute"
    parent: int = -1
    gamma: float = 0.0
    b: float = 0.0
    beta: float = 0.0
    alpha: float = 0.0
    d: float = 0.0
    theta: float = 0.0
    r: float = 0.0
    has_beta: bool = False
    coupling: tuple[tuple[int, float], ...] = ()
    mass: float = 0.0
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)
    k_theta: float = 0.0
    k_alpha: float = 0.0
    k_beta: float = 0.0
    backlash_theta: float = 0.0
    backlash_r: float = 0.0
    backlash_friction: float = 0.0
    backlash_width: float = 1.0
    gear_scale: float = 0.0
    gear_cos1: float = 0.0
    gear_sin1: float = 0.0
    gear_cos2: float = 0.0
    gear_sin2: float = 0.0
    motor_cos1: float = 0.0
    motor_sin1: float = 0.0
    motor_cos2: float = 0.0
    motor_sin2: float = 0.0
    reduction: float = 0.0


@dataclass(frozen=True)
class Marker:
    """A measured point (or a measured full frame) fixed to one robot frame.

    ``position`` is the point in that frame, metres. ``rotation`` (3x3, row-major nested tuple)
    orients the marker's own frame in that frame; it matters only for 6D measurements.
    ``rotation_known`` False: the orientation is not known (it starts at identity and a calibration
    gives its change no tolerance).
    """

    name: str
    frame: int
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotation: tuple[tuple[float, ...], ...] = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    rotation_known: bool = True


@dataclass(frozen=True)
class Payload:
    """A mass carried at a frame (normally the last), centre of mass in that frame."""

    mass: float = 0.0
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)
    frame: int = -1


@dataclass(frozen=True)
class RobotModel:
    """A robot: frames, joints, markers, base pose and mass properties, all SI.

    ``frames`` are ordered so that a parent always precedes its children. ``joint_names`` name
    the measured joint readings (the columns of a measurement file); ``joint_limits`` is
    ``((lower, upper), ...)`` per reading. ``base_position``/``base_rotation`` give ``X_WB``.
    ``tolerances``: ``(family, quantity, value)`` triples, how far calibration may plausibly move
    a family's parameters (SI; None for no bound), over the defaults of docs/checks.md.
    ``payload`` is the payload a measurement file's ``payload_kg`` column varies; ``other_payloads``
    are fixed masses on other frames (a second arm's tool). ``notes``: what the reader decided on the
    user's behalf (a re-orthonormalised matrix), for the summary.
    ``backlash_side``: where a joint rests in its lost motion, pose by pose: ``"gravity"`` on the
    side its gravity load L pushes it to, ``s = tanh((L - a F) / w)`` (frame's friction F and
    width w; a the approach direction, which matters only where F > 0), or ``"approach"`` behind
    its last move, ``s = -a`` (docs/conventions.md).
    """

    name: str
    frames: tuple[Frame, ...]
    joint_names: tuple[str, ...]
    joint_limits: tuple[tuple[float, float], ...]
    markers: tuple[Marker, ...]
    base_position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    base_rotation: tuple[tuple[float, ...], ...] = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    gravity: tuple[float, float, float] = (0.0, 0.0, -9.81)
    payload: Payload = field(default_factory=Payload)
    description: str = ""
    tolerances: tuple[tuple[str, str, float | None], ...] = ()
    backlash_side: str = "gravity"
    other_payloads: tuple[Payload, ...] = ()
    notes: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        _validate(self)

    # -- convenient views -------------------------------------------------------------------
    @property
    def n_frames(self) -> int:
        return len(self.frames)

    @property
    def n_joints(self) -> int:
        return len(self.joint_names)

    @property
    def frame_names(self) -> tuple[str, ...]:
        return tuple(f.name for f in self.frames)

    @property
    def marker_names(self) -> tuple[str, ...]:
        return tuple(m.name for m in self.markers)

    @property
    def X_WB(self) -> np.ndarray:
        """Base pose as a 4x4 homogeneous matrix (measurement frame W <- robot frame 0)."""
        X = np.eye(4)
        X[:3, :3] = np.asarray(self.base_rotation, dtype=float)
        X[:3, 3] = self.base_position
        return X

    @property
    def coupling_matrix(self) -> np.ndarray:
        """``(n_frames, n_joints)``: frame joint variables = C @ readings."""
        C = np.zeros((self.n_frames, self.n_joints))
        for i, f in enumerate(self.frames):
            for j, coef in f.coupling:
                C[i, j] += coef
        return C

    @property
    def lower_limits(self) -> np.ndarray:
        return np.array([lo for lo, _ in self.joint_limits], dtype=float)

    @property
    def upper_limits(self) -> np.ndarray:
        return np.array([hi for _, hi in self.joint_limits], dtype=float)

    @property
    def reading_quantities(self) -> tuple[str, ...]:
        """Per joint reading, "length" when it drives a prismatic frame, else "angle" (its unit's kind)."""
        out: list[str | None] = [None] * self.n_joints
        for f in self.frames:  # the first frame a reading drives says its kind
            for k, _ in f.coupling:
                if 0 <= k < self.n_joints and out[k] is None:
                    out[k] = "length" if f.joint == "prismatic" else "angle"
        return tuple(k or "angle" for k in out)

    @property
    def payloads(self) -> tuple[Payload, ...]:
        return (self.payload,) + self.other_payloads

    @property
    def has_masses(self) -> bool:
        return any(f.mass > 0 for f in self.frames) or any(p.mass > 0 for p in self.payloads)

    @property
    def has_compliance(self) -> bool:
        return any(f.k_theta or f.k_alpha or f.k_beta for f in self.frames)

    @property
    def has_backlash(self) -> bool:
        return any(f.backlash_theta or f.backlash_r for f in self.frames)

    @property
    def has_transmission(self) -> bool:
        return any(getattr(f, k) for f in self.frames for k in TRANSMISSION_KINDS)

    def replace(self, **changes) -> RobotModel:
        if changes.keys() <= {"description"}:       # words alone: the structure checked already stays
            out = copy.copy(self)
            object.__setattr__(out, "description", changes.get("description", self.description))
            return out
        return replace(self, **changes)

    def derived(self, key: Hashable, make: Callable[[], Any]) -> Any:
        """What ``make()`` gives, made once for this model object and kept with it under ``key``.

        For what the engine derives from the model's structure (its parameter layout, its step
        layout): the values kept are immutable (records with read-only arrays), so whatever a
        caller does with one cannot change a later result; they live and die with the model, and
        an equal model made elsewhere makes its own. Not part of the model's value: equality,
        hashing, copies and pickles ignore them.
        """
        kept = self.__dict__.setdefault("_derived", {})
        if key not in kept:
            kept.setdefault(key, make())
        return kept[key]

    def __getstate__(self) -> dict:
        return {k: v for k, v in self.__dict__.items() if k != "_derived"}


# every number a frame holds (geometry, mass, compliance) must be finite
_FRAME_NUMBERS = tuple(f.name for f in fields(Frame) if f.type == "float")


def _rows_rule(value, name: str, args) -> None:
    """``serial_model``'s rows: one dict per frame of Frame's keys (coupling aside), numbers finite."""
    SEQUENCE(value, name, args)
    allowed = {f.name for f in fields(Frame)} - {"coupling"}
    for i, row in enumerate(value):
        where = f"{name}[{i}]"
        MAPPING(row, where, args)
        unknown = sorted(str(k) for k in row if k not in allowed)
        if unknown:
            raise InputError(f"unknown key {unknown[0]!r}; a row holds {', '.join(sorted(allowed))}", where=where)
        for k in _FRAME_NUMBERS:
            if k in row:
                in_range()(row[k], f"{where}.{k}", args)
        if "joint" in row:
            one_of(JOINT_TYPES)(row["joint"], f"{where}.joint", args)
        if "parent" in row:
            whole(-1, i - 1)(row["parent"], f"{where}.parent", args)
        if "name" in row:
            TEXT(row["name"], f"{where}.name", args)
        if "com" in row:
            shaped(3)(row["com"], f"{where}.com", args)
        if "has_beta" in row:
            FLAG(row["has_beta"], f"{where}.has_beta", args)


def _markers_rule(value, name: str, args) -> None:
    """``serial_model``'s markers: (name, (x, y, z)) pairs on the last frame."""
    SEQUENCE(value, name, args)
    for i, item in enumerate(value):
        if isinstance(item, str) or not hasattr(item, "__len__") or len(item) != 2:
            raise InputError("must be a (name, (x, y, z)) pair", where=f"{name}[{i}]")
        TEXT(item[0], f"{name}[{i}]", args)
        shaped(3)(item[1], f"{name}[{i}]", args)


def _validate(model: RobotModel) -> None:
    _check_sizes(model)
    _refuse_repeats([f.name for f in model.frames], "frame", "frames")
    _refuse_repeats(model.joint_names, "joint", "joints")
    _check_joint_limits(model)
    for i, f in enumerate(model.frames):
        _check_frame(f, i, len(model.joint_names))
    if model.backlash_side not in BACKLASH_SIDES:
        raise InputError(f"backlash side must be one of {', '.join(BACKLASH_SIDES)}, got {model.backlash_side!r}",
                         where="backlash.side")
    _check_payloads(model)
    _check_markers(model)
    _check_rotation(model.base_rotation, "base.rotation")


def _check_sizes(model: RobotModel) -> None:
    """At least one frame; no more frames or markers than a model holds."""
    if len(model.frames) == 0:
        raise InputError("a model needs at least one frame", where="frames")
    for what, n, top in (("frames", len(model.frames), MAX_FRAMES), ("markers", len(model.markers), MAX_MARKERS)):
        if n > top:
            raise InputError(f"{n:,} {what}; a robocal model holds up to {top} (docs/formats.md)", where=what)


def _refuse_repeats(names: Sequence[str], what: str, where: str) -> None:
    """An InputError naming the first of ``names`` given twice (``what``: frame, joint, marker)."""
    if len(set(names)) != len(names):
        dup = next(n for n in names if names.count(n) > 1)
        raise InputError(f"{what} name {dup!r} is used twice", where=where)


def _check_joint_limits(model: RobotModel) -> None:
    if len(model.joint_limits) != len(model.joint_names):
        raise InputError("one (lower, upper) limit pair is needed per joint", where="joint_limits")
    for j, (lo, hi) in enumerate(model.joint_limits):
        if not (lo <= hi):
            raise InputError(f"lower limit {lo} exceeds upper limit {hi}", where=f"joints[{j}].limits")
        if lo == hi and math.isfinite(lo):    # a joint of no range can be neither moved nor calibrated
            raise InputError(f"lower and upper limit are both {lo}: a joint that cannot move",
                             where=f"joints[{j}].limits")


def _check_frame(f: Frame, i: int, n_joints: int) -> None:
    """Frame ``i``: its joint type, parent, joint readings and numbers."""
    where = f"frames[{i}] ({f.name})"
    if f.joint not in JOINT_TYPES:
        raise InputError(f"joint type must be one of {', '.join(JOINT_TYPES)}, got {f.joint!r}", where=where)
    if not (-1 <= f.parent < i):
        raise InputError("a frame's parent must come before it (or be the base, -1)", where=where)
    if f.joint == "fixed" and f.coupling:
        raise InputError("a fixed frame has no joint variable", where=where)
    if f.joint != "fixed" and not f.coupling:
        raise InputError("a moving frame needs a joint reading (coupling)", where=where)
    for j, _ in f.coupling:
        if not (0 <= j < n_joints):
            raise InputError(f"coupling refers to joint {j}, which does not exist", where=where)
    if f.mass < 0 or not math.isfinite(f.mass):
        raise InputError(f"mass must be a non-negative number, got {f.mass}", where=where)
    for k in _FRAME_NUMBERS:
        if not math.isfinite(getattr(f, k)):
            raise InputError(f"{k} is not a finite number", where=where)
    if not (f.backlash_width > 0 and f.backlash_friction >= 0):
        raise InputError("backlash_width must be positive and backlash_friction non-negative", where=where)
    _check_transmission(f, where)


def _check_transmission(f: Frame, where: str) -> None:
    """A frame's transmission terms: harmonics on a revolute joint, motor terms with a stated ratio."""
    if f.reduction < 0:
        raise InputError(f"reduction (motor turns per joint turn) must be positive, or 0 for not stated, "
                         f"got {f.reduction}", where=where)
    held = [k for k in TRANSMISSION_KINDS if getattr(f, k)]
    if f.joint == "fixed" and (held or f.reduction):
        raise InputError("a fixed frame has no transmission", where=where)
    if f.joint == "prismatic" and any(k != "gear_scale" for k in held):
        raise InputError("harmonics of the joint angle belong to revolute joints; a prismatic joint carries "
                         "gear_scale only", where=where)
    if not f.reduction and any(k.startswith("motor_") for k in held):
        raise InputError("motor harmonics need the joint's reduction ratio (reduction)", where=where)


def _check_payloads(model: RobotModel) -> None:
    for n, pl in enumerate(model.payloads):
        where = "payload" if not model.other_payloads else f"payload[{n}]"
        if pl.mass < 0 or not np.isfinite(pl.mass):
            raise InputError(f"payload mass must be non-negative, got {pl.mass}", where=where)
        if not (-1 <= pl.frame < len(model.frames)):
            raise InputError("payload frame does not exist", where=where)


def _check_markers(model: RobotModel) -> None:
    """At least one marker, each named once, on a frame of the model, with a proper rotation."""
    _refuse_repeats([m.name for m in model.markers], "marker", "markers")
    if not model.markers:
        raise InputError("a model needs at least one marker (tool point)", where="markers")
    for i, m in enumerate(model.markers):
        if not (0 <= m.frame < len(model.frames)):
            raise InputError(f"marker {m.name!r} is attached to a frame that does not exist", where=f"markers[{i}]")
        _check_rotation(m.rotation, f"markers[{i}].rotation")


def _check_rotation(R, where: str) -> None:
    R = np.asarray(R, dtype=float)
    if R.shape != (3, 3) or not np.all(np.isfinite(R)):
        raise InputError("expected a 3x3 rotation", where=where)
    if np.abs(R @ R.T - np.eye(3)).max() > 1e-6 or np.linalg.det(R) < 0:
        raise InputError("not a proper rotation matrix", where=where)


@accepts(frame=is_a(Frame), q=in_range())
def mdh_transform(frame: Frame, q: float = 0.0) -> np.ndarray:
    """``X_pj``, the 4x4 placement of one frame in its parent at joint variable ``q`` (rad or m).

    The reference form of the engine's transform (docs/method.md section 1)::

        X_pj = Rot(z, gamma) Trans(z, b) Rot(y, beta) Rot(x, alpha) Trans(x, d) Rot(z, theta) Trans(z, r)

    with ``q`` added to theta (revolute) or r (prismatic); compliance is not applied.

    Parameters
    ----------
    {frame}
    q : float
        The joint variable, rad or m.

    Returns
    -------
    numpy.ndarray, shape (4, 4)
        The frame's transform from its parent, ``X_pj``.

    With gamma = b = beta = 0 it is the usual modified-DH matrix: a frame turned by theta = 90 deg
    about z, then lifted by r = 0.2 m, after alpha = 90 deg and d = 0.5 m:

    >>> X = mdh_transform(Frame("j2", alpha=np.pi / 2, d=0.5, r=0.2), q=np.pi / 2)
    >>> X.round(12) + 0.0
    array([[ 0. , -1. ,  0. ,  0.5],
           [ 0. ,  0. , -1. , -0.2],
           [ 1. ,  0. ,  0. ,  0. ],
           [ 0. ,  0. ,  0. ,  1. ]])
    """
    th = frame.theta + (q if frame.joint == "revolute" else 0.0)
    r = frame.r + (q if frame.joint == "prismatic" else 0.0)
    return (rot4(2, frame.gamma) @ trans4(2, frame.b) @ rot4(1, frame.beta) @ rot4(0, frame.alpha)
            @ trans4(0, frame.d) @ rot4(2, th) @ trans4(2, r))


@accepts(X=shaped(4, 4))
def placement_parameters(X) -> dict[str, float]:
    """gamma, b, beta, alpha, d, theta, r whose ``mdh_transform`` (at q = 0) is the placement ``X``
    (4x4, a proper rotation): the inverse of ``mdh_transform`` for fixed frames given as transforms.

    Seven numbers for six degrees of freedom, so one is chosen: either beta = 0 (Khalil-Kleinfinger:
    z of the frame placed by gamma and alpha, the offset split along z, x and the new z), or r = 0
    (gamma turns x towards the offset, beta and alpha tilt z, theta turns about it). The first
    divides by sin(alpha), the second by cos(beta); the better conditioned is taken, so nearly
    parallel axes never give huge offsets.

    Parameters
    ----------
    {X}

    Returns
    -------
    dict
        The placement's parameters by kind (``d``, ``r``, ``theta``, ``alpha``, ``beta``, ``gamma``,
        ``b``), SI.

    >>> X = mdh_transform(Frame("m", joint="fixed", gamma=0.3, b=0.1, alpha=-np.pi / 2, d=0.5, theta=0.2, r=0.05))
    >>> bool(np.abs(mdh_transform(Frame("m", joint="fixed", **placement_parameters(X))) - X).max() < 1e-12)
    True
    """
    X = np.asarray(X, dtype=float)
    R, p = X[:3, :3], X[:3, 3]
    z = R[:, 2]
    s_alpha = math.hypot(z[0], z[1])
    h = math.hypot(p[0], p[1])
    # r = 0 form: gamma points x at the offset's horizontal part
    gamma = math.atan2(p[1], p[0]) if h > 1e-15 else 0.0
    beta, alpha, theta = _yxz_angles(rot_matrix(2, -gamma) @ R)
    c_beta = abs(math.cos(beta)) if h > 1e-15 else 1.0
    if c_beta >= s_alpha:
        d = h / math.cos(beta) if h > 1e-15 else 0.0
        return dict(gamma=gamma, b=p[2] + d * math.sin(beta), beta=beta, alpha=alpha, d=d, theta=theta, r=0.0)
    # beta = 0 form: z of the frame is Rz(gamma) (0, -sin alpha, cos alpha)
    alpha = math.atan2(s_alpha, z[2])
    gamma = math.atan2(z[0], -z[1])
    M = rot_matrix(0, -alpha) @ rot_matrix(2, -gamma) @ R
    theta = math.atan2(M[1, 0], M[0, 0])
    q = rot_matrix(2, -gamma) @ p
    r = -q[1] / s_alpha
    return dict(gamma=gamma, b=q[2] - r * math.cos(alpha), beta=0.0, alpha=alpha, d=q[0], theta=theta, r=r)


# the default mass model's linear density when no total mass is given: masses are then relative,
# and identified compliances relative compliances (docs/conventions.md)
DEFAULT_LINK_DENSITY = 10.0   # kg per metre of link
RELATIVE_MASSES = "no total mass given: compliances are relative"  # said in the notes of such a model


@accepts(model=is_a(RobotModel), total_mass=optional(POSITIVE))
def default_masses(model: RobotModel, total_mass: float | None = None) -> RobotModel:
    """``model`` with link masses assumed from its geometry, for compliance without CAD masses.

    Each frame's link is the set of segments from its origin to its children's origins and to the
    markers it carries (at zero joint variables); its mass is proportional to their total length
    (a uniform linear density), its centre of mass their length-weighted midpoint. The masses sum
    to ``total_mass`` (kg, the arm's catalogue mass without payloads) when given, else to
    ``DEFAULT_LINK_DENSITY`` kg per metre. Payloads are kept. Identified compliances absorb any
    common scale error of the masses, and are exact when the true masses are in these proportions;
    the summary says which masses were assumed.

    Parameters
    ----------
    model : RobotModel
        The robot model.
    {total_mass}

    Returns
    -------
    RobotModel
        A copy of ``model`` with link masses and centres of mass.

    >>> m = default_masses(serial_model("rr", [dict(), dict(d=0.5)], markers=[("tool", (0.3, 0, 0))]), 8.0)
    >>> [round(f.mass, 3) for f in m.frames], m.frames[1].com
    ([5.0, 3.0], (0.15, 0.0, 0.0))
    """
    lengths: list[float] = []
    centres: list[tuple[float, float, float]] = []
    for i in range(len(model.frames)):
        ends = [mdh_transform(g)[:3, 3] for g in model.frames if g.parent == i]
        ends += [np.asarray(mk.position, dtype=float) for mk in model.markers if mk.frame == i]
        seg = np.array([np.linalg.norm(e) for e in ends]) if ends else np.zeros(0)
        lengths.append(float(seg.sum()))
        centres.append(vector3(sum(s * e / 2 for s, e in zip(seg, ends)) / seg.sum())
                       if seg.sum() > 0 else (0.0, 0.0, 0.0))
    total_length = sum(lengths)
    if total_length <= 0:
        raise InputError("the model has no link of non-zero length to spread masses over", where="masses")
    if total_mass is not None and not (np.isfinite(total_mass) and total_mass > 0):
        raise InputError(f"the total mass must be a positive number of kg, got {total_mass}", where="total mass")
    scale = (total_mass / total_length) if total_mass is not None else DEFAULT_LINK_DENSITY
    frames = tuple(replace(f, mass=scale * L, com=c) for f, L, c in zip(model.frames, lengths, centres))
    said = (f"total {total_mass:g} kg" if total_mass is not None else
            f"{DEFAULT_LINK_DENSITY:g} kg per metre, {RELATIVE_MASSES}")
    listed = ", ".join(f"{f.name} {f.mass:.3g} kg" for f in frames if f.mass > 0)
    note = f"masses assumed from the geometry ({said}): {listed}"
    return model.replace(frames=frames, notes=model.notes + (note,))


def _yxz_angles(M: np.ndarray) -> tuple[float, float, float]:
    """(beta, alpha, theta) with M = Rot(y, beta) Rot(x, alpha) Rot(z, theta); beta first, the rest
    from Rot(y, -beta) M, so the rebuilt matrix is exact to rounding even at alpha = +-90 deg."""
    beta = math.atan2(M[0, 2], M[2, 2]) if math.hypot(M[0, 2], M[2, 2]) > 1e-300 else 0.0
    N = rot_matrix(1, -beta) @ M
    return beta, math.atan2(-N[1, 2], N[2, 2]), math.atan2(-N[0, 1], N[0, 0])


@accepts(frames=each_a(Frame), tol=in_range(0.0, math.pi / 2, low_open=True))
def parallel_beta_frames(frames: Sequence[Frame], tol: float = DEFAULT_PARALLEL_TOL) -> tuple[bool, ...]:
    """Which frames carry Hayati's beta: z of the parent and z of the frame parallel within ``tol``.

    In modified DH, z(j) is tilted from z(parent) by alpha_j about x (and beta_j about y, gamma
    does not tilt z), so the axes are parallel when the tilt angle is 0 or pi.

    Parameters
    ----------
    {frames}
    tol : float
        Angle below which consecutive axes count as parallel, rad.

    Returns
    -------
    tuple of bool
        Whether each frame takes Hayati's beta.
    """
    out = []
    for f in frames:
        c = np.cos(f.alpha) * np.cos(f.beta)  # z_parent . z_j
        tilt = np.arccos(np.clip(abs(c), -1.0, 1.0))
        out.append(bool(tilt <= tol and f.joint != "fixed"))
    return tuple(out)


@accepts(name=TEXT, rows=_rows_rule, markers=_markers_rule, joint_limits=optional(shaped(None, 2)),
         base_position=shaped(3), base_rotation=optional(shaped(3, 3)),
         beta_tol=in_range(0.0, math.pi / 2, low_open=True), gravity=shaped(3), payload=optional(is_a(Payload)),
         description=TEXT)
def serial_model(
    name: str,
    rows: Sequence[dict],
    *,
    markers: Sequence[tuple[str, Sequence[float]]] = (("tool", (0.0, 0.0, 0.0)),),
    joint_limits: Sequence[tuple[float, float]] | None = None,
    base_position=(0.0, 0.0, 0.0),
    base_rotation=None,
    beta_tol: float = DEFAULT_PARALLEL_TOL,
    gravity=(0.0, 0.0, -9.81),
    payload: Payload | None = None,
    description: str = "",
) -> RobotModel:
    """Build a serial chain from modified-DH rows (dicts with joint, alpha, d, theta, r, ...; SI).

    Each moving frame gets its own joint reading named after the frame; markers attach to the last
    frame; beta is carried where consecutive axes are parallel within ``beta_tol`` unless a row
    says ``has_beta`` explicitly.

    Parameters
    ----------
    name : str
        The robot's name.
    rows : sequence of dict
        One row per frame: ``Frame``'s fields by name (``joint``, ``alpha``, ``d``, ``theta``, ``r``,
        ``mass``, ``com``, ...), SI; couplings follow the row order.
    markers : sequence of (str, (float, float, float))
        Markers on the last frame, SI.
    {joint_limits, base_position, base_rotation, beta_tol, gravity, payload, description}

    Returns
    -------
    RobotModel
        The model.

    >>> m = serial_model("rr", [dict(joint="revolute"), dict(joint="revolute", d=0.5)],
    ...                  markers=[("tool", (0.3, 0, 0))])
    >>> m.joint_names, [f.has_beta for f in m.frames]
    (('j1', 'j2'), [True, True])
    """
    frames = []
    joint_names: list[str] = []
    for i, row in enumerate(rows):
        row = dict(row)
        fname = row.pop("name", f"j{i + 1}")
        joint = row.pop("joint", "revolute")
        coupling: tuple = ()
        if joint != "fixed":
            coupling = ((len(joint_names), 1.0),)
            joint_names.append(fname)
        row.setdefault("parent", i - 1)
        explicit_beta = row.pop("has_beta", None)
        f = Frame(name=fname, joint=joint, coupling=coupling, **row)
        if explicit_beta is None:
            explicit_beta = parallel_beta_frames([f], beta_tol)[0]
        frames.append(replace(f, has_beta=bool(explicit_beta)))
    if joint_limits is None:
        joint_limits = [(-np.pi, np.pi) if frames[i].joint == "revolute" else (0.0, 1.0)
                        for i in range(len(frames)) if frames[i].joint != "fixed"]
    R = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)) if base_rotation is None else \
        tuple(tuple(float(v) for v in row) for row in np.asarray(base_rotation, dtype=float))
    last = len(frames) - 1
    return RobotModel(
        name=name,
        frames=tuple(frames),
        joint_names=tuple(joint_names),
        joint_limits=tuple((float(lo), float(hi)) for lo, hi in joint_limits),
        markers=tuple(Marker(n, last, vector3(p)) for n, p in markers),
        base_position=vector3(base_position),
        base_rotation=R,
        gravity=vector3(gravity),
        payload=payload if payload is not None else Payload(frame=last),
        description=description,
    )
