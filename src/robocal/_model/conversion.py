"""Robots written other ways, turned into our modified DH with Hayati's beta: classic DH tables,
and joint axes as lines in space (what a URDF chain gives); and the MDH table of a model.

Every conversion returns a :class:`RobotModel` whose forward kinematics equals the source's: the
same marker pose in W for the same joint readings, to rounding (tests check 1e-12 m). The MDH
parameters themselves are a choice, written down here:

* Frame j (one per moving joint) has z along the joint axis, pointing the way the source's positive
  joint motion turns (right-hand rule) or slides, so the readings are the source's joint values.
* x_j runs along the common normal of axis j and axis j+1 and O_j is its foot on axis j (Khalil and
  Kleinfinger). Where the two axes are parallel within ``DEFAULT_PARALLEL_TOL`` the normal is taken
  through the foot of the previous normal, so r_j = 0, and a residual tilt of the next axis goes
  into Hayati's beta (exact, and well conditioned where the true common normal runs off to
  infinity). The last frame continues the previous x (theta = r = 0 at zero readings).
* Whatever is left at the ends goes to the base pose ``X_WB`` and to the markers.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from .._base.arguments import POSITIVE_OR_INF, SEQUENCE, TEXT, UNIT_SYSTEM, accepts, is_a, optional, shaped
from .._base.errors import InputError
from .._base.spatial import inverse4, matrix_tuple, pose4, rot4, rot_matrix, trans4, unit_vector, vector3
from .._base.units import parse_units, unit_factors
from .parameters import KIND_QUANTITY
from .robot import DEFAULT_PARALLEL_TOL, Frame, Marker, RobotModel, mdh_transform, parallel_beta_frames

# the columns of an MDH table, beta to r first as the paper lists them
MDH_TABLE_KINDS = ("beta", "alpha", "d", "theta", "r", "gamma", "b")

def _perpendicular(z: np.ndarray, hint: np.ndarray | None) -> np.ndarray:
    """A unit vector normal to ``z``: ``hint`` made normal when it can be, else the best world axis."""
    if hint is not None:
        h = hint - (hint @ z) * z
        if np.linalg.norm(h) > 1e-9:
            return unit_vector(h)
    e = np.eye(3)[int(np.argmin(np.abs(z)))]
    return unit_vector(e - (e @ z) * z)


def marker_placements(markers, where: str) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """Normalise ``[(name, xyz), (name, xyz, R3x3), ...]`` to arrays; names must be strings."""
    out = []
    for i, m in enumerate(markers):
        if len(m) not in (2, 3) or not isinstance(m[0], str):
            raise InputError("a marker is (name, xyz) or (name, xyz, 3x3 rotation)", where=f"{where}[{i}]")
        p = np.asarray(m[1], dtype=float)
        R = np.asarray(m[2], dtype=float) if len(m) == 3 else np.eye(3)
        if p.shape != (3,) or R.shape != (3, 3) or not (np.all(np.isfinite(p)) and np.all(np.isfinite(R))):
            raise InputError("marker position must be 3 numbers and rotation 3x3", where=f"{where}[{i}]")
        out.append((m[0], p, R))
    return out


def _dh_row(row, i: int) -> tuple[str | None, float, float, float, float, str]:
    where = f"rows[{i}]"
    if isinstance(row, dict):
        unknown = set(row) - {"name", "theta", "d", "a", "alpha", "joint"}
        if unknown:
            raise InputError(f"unknown keys {sorted(unknown)}; expected theta, d, a, alpha, joint, name",
                             where=where)
        name = row.get("name")
        vals = [row.get(k, 0.0) for k in ("theta", "d", "a", "alpha")]
        joint = row.get("joint", "revolute")
    else:
        row = tuple(row)
        if len(row) not in (4, 5):
            raise InputError("a DH row is (theta, d, a, alpha[, joint])", where=where)
        name, vals, joint = None, list(row[:4]), (row[4] if len(row) == 5 else "revolute")
    if joint not in ("revolute", "prismatic"):
        raise InputError(f"joint type must be revolute or prismatic, got {joint!r}", where=where)
    try:
        th, d, a, al = (float(v) for v in vals)
    except (TypeError, ValueError):
        raise InputError("theta, d, a, alpha must be numbers", where=where) from None
    if not all(map(math.isfinite, (th, d, a, al))):
        raise InputError("theta, d, a, alpha must be finite", where=where)
    return name, th, d, a, al, joint


@accepts(rows=SEQUENCE, name=TEXT, markers=SEQUENCE, base=optional(shaped(4, 4)), joint_limits=optional(shaped(None,
                                                                                                               2)))
def from_standard_dh(rows: Sequence, *, name: str, markers: Sequence = (("tool", (0.0, 0.0, 0.0)),),
                     base=None, joint_limits: Sequence[tuple[float, float]] | None = None) -> RobotModel:
    """A model from classic (distal) DH rows, as Universal Robots publish them.

    ``rows``: one per joint, a dict ``{theta, d, a, alpha, joint, name}`` or a tuple
    ``(theta, d, a, alpha[, joint])``; SI; theta (revolute) or d (prismatic) is the offset the
    joint value adds to. The source chain is ``T_0n = prod_i Rot(z,theta_i) Trans(z,d_i)
    Trans(x,a_i) Rot(x,alpha_i)``.
    ``markers``: ``(name, xyz)`` or ``(name, xyz, R)`` given in the source's last frame n (the
    flange). ``base``: ``X_W0`` (4x4) placing the DH frame 0 in W; identity when None.
    ``joint_limits``: ``(lower, upper)`` per row, default +-pi (revolute) or (0, 1) m (prismatic).

    Mapping (exact, because Trans(x,a) and Rot(x,alpha) commute): MDH frame i takes theta_i, r = d_i
    and, from the previous row, alpha = alpha_{i-1}, d = a_{i-1}; frame 1 starts at frame 0 with
    alpha = d = 0, so the base needs nothing; a_n and alpha_n of the last row go into every marker.
    Beta is carried where ``parallel_beta_frames`` says the axes are parallel.

    Parameters
    ----------
    rows : sequence of dict
        One row per joint: ``joint`` (revolute or prismatic) and the classic DH values ``d``, ``theta``,
        ``a``, ``alpha`` (SI).
    {name}
    markers : sequence
        Markers as ``(name, (x, y, z))`` or ``(name, (x, y, z), R)`` in the last frame, SI.
    {base, joint_limits}

    Returns
    -------
    RobotModel
        The model in modified DH, with the same forward kinematics.

    >>> m = from_standard_dh([(0, 0.1, 0.5, 0), (0, 0, 0.4, 0)], name="rr")
    >>> [(f.alpha, f.d, f.r) for f in m.frames], m.markers[0].position
    ([(0.0, 0.0, 0.1), (0.0, 0.5, 0.0)], (0.4, 0.0, 0.0))
    """
    parsed = [_dh_row(r, i) for i, r in enumerate(rows)]
    if not parsed:
        raise InputError("at least one DH row is needed", where="rows")
    frames = []
    names = []
    prev_a = prev_alpha = 0.0
    for i, (fname, th, d, a, al, joint) in enumerate(parsed):
        fname = fname or f"j{i + 1}"
        frames.append(Frame(name=fname, joint=joint, parent=i - 1, alpha=prev_alpha, d=prev_a,
                            theta=th, r=d, coupling=((i, 1.0),)))
        names.append(fname)
        prev_a, prev_alpha = a, al
    flags = parallel_beta_frames(frames)
    frames = [replace(f, has_beta=b) for f, b in zip(frames, flags)]
    # the last row's Trans(x, a_n) Rot(x, alpha_n) sits between MDH frame n and the source's frame n
    X_tail = trans4(0, prev_a) @ rot4(0, prev_alpha)
    mk = []
    for mname, p, R in marker_placements(markers, "markers"):
        X = X_tail @ pose4(R, p)
        mk.append(Marker(mname, len(frames) - 1, vector3(X[:3, 3]), matrix_tuple(X[:3, :3])))
    if joint_limits is None:
        joint_limits = [(-math.pi, math.pi) if f.joint == "revolute" else (0.0, 1.0) for f in frames]
    if len(joint_limits) != len(frames):
        raise InputError(f"{len(frames)} (lower, upper) pairs needed, got {len(joint_limits)}",
                         where="joint_limits")
    X_W0 = np.eye(4) if base is None else np.asarray(base, dtype=float)
    if X_W0.shape != (4, 4):
        raise InputError("base must be a 4x4 homogeneous matrix X_W0", where="base")
    return RobotModel(
        name=name, frames=tuple(frames), joint_names=tuple(names),
        joint_limits=tuple((float(lo), float(hi)) for lo, hi in joint_limits),
        markers=tuple(mk), base_position=vector3(X_W0[:3, 3]),
        base_rotation=matrix_tuple(X_W0[:3, :3]),
        description="imported from classic DH",
    )


def _decompose(T: np.ndarray, use_beta: bool) -> dict:
    """MDH parameters of a relative pose built by :func:`line_frames` (gamma = b = 0).

    ``T = Rot(y,beta) Rot(x,alpha) Trans(x,d) Rot(z,theta) Trans(z,r)``; beta is kept within
    +-pi/2 (alpha takes the half-turn of antiparallel axes) and forced to 0 unless ``use_beta``.
    """
    z = T[:3, 2]
    if use_beta:
        s = 1.0 if z[2] >= 0 else -1.0
        beta = math.atan2(s * z[0], s * z[2])
    else:
        beta = 0.0
    cb, sb = math.cos(beta), math.sin(beta)
    alpha = math.atan2(-z[1], z[0] * sb + z[2] * cb)
    Rp = rot_matrix(1, beta) @ rot_matrix(0, alpha)
    M = Rp.T @ T[:3, :3]
    theta = math.atan2(M[1, 0], M[0, 0])
    t = T[:3, 3]
    out = dict(beta=beta, alpha=alpha, d=float(t @ Rp[:, 0]), theta=theta, r=float(t @ Rp[:, 2]))
    # rounding noise (1e-17) reads as a parameter in tables; below 1e-15 it moves nothing measurable
    return {k: (0.0 if abs(v) < 1e-15 else v) for k, v in out.items()}


def line_frames(points: np.ndarray, axes: np.ndarray, tol: float) -> tuple[np.ndarray, list[np.ndarray]]:
    """Base pose ``X_0B`` and MDH frames ``X_0j`` (4x4 each) for joint lines in source frame 0.

    ``points`` (n, 3) a point on each line, ``axes`` (n, 3) unit directions, both in the source's
    root frame. The base has z on axis 1 through the root origin's projection, rotated from the
    root by the smallest rotation, so a first axis along the root z gives X_0B = identity.
    """
    n = len(axes)
    z1 = axes[0]
    # smallest rotation taking e_z to z1 (a half-turn about x when z1 = -e_z)
    c = float(z1[2])
    w = np.cross([0.0, 0.0, 1.0], z1)
    if np.linalg.norm(w) < 1e-12:
        RB = np.eye(3) if c > 0 else rot_matrix(0, math.pi)
    else:
        k = unit_vector(w)
        K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
        ang = math.atan2(np.linalg.norm(w), c)
        RB = np.eye(3) + math.sin(ang) * K + (1 - math.cos(ang)) * K @ K
        RB[:, 2] = z1  # exact z, so frame 1 needs no alpha/beta
    foot = points[0] + (-points[0] @ z1) * z1      # root origin projected on axis 1
    X_0B = pose4(RB, foot)
    frames = []
    x_prev = RB[:, 0]
    for j in range(n):
        zj = axes[j]
        if j + 1 == n:
            origin, x = foot, _perpendicular(zj, x_prev)
        else:
            zn, pn = axes[j + 1], points[j + 1]
            cr = np.cross(zj, zn)
            if np.linalg.norm(cr) <= math.sin(tol):
                # parallel: normal through the previous foot (r_j = 0), towards the nearest point of
                # the next axis; a slight tilt of that axis goes to beta of frame j+1
                origin = foot
                near = pn + ((origin - pn) @ zn) * zn
                x = _perpendicular(zj, near - origin) if np.linalg.norm(near - origin) > 1e-12 else \
                    _perpendicular(zj, x_prev)
                foot = near
            else:
                # common normal: the feet origin = pj + s zj and near = pn + u zn, in closed form over
                # |zj x zn|^2 (a 2x2 solve was singular in round-off for a tilt of ~1e-9 rad)
                pj = points[j]
                s = np.cross(pn - pj, zn) @ cr / (cr @ cr)
                u = np.cross(pn - pj, zj) @ cr / (cr @ cr)
                origin, near = pj + s * zj, pn + u * zn
                x = unit_vector(cr)
                if (near - origin) @ x < -1e-12:
                    x = -x  # keep d >= 0 where the axes do not meet
                foot = near
        x = unit_vector(x - (x @ zj) * zj)
        frames.append(pose4(np.column_stack([x, np.cross(zj, x), zj]), origin))
        x_prev = x
    return X_0B, frames


def frames_from_lines(names, joints, couplings, X_0B, X_0F) -> list[Frame]:
    """Serial MDH frames from the base pose and frame poses found by :func:`line_frames`."""
    out = []
    prev = X_0B
    prev_z = X_0B[:3, 2]
    for i, X in enumerate(X_0F):
        par = abs(float(prev_z @ X[:3, 2])) >= math.cos(DEFAULT_PARALLEL_TOL)
        p = _decompose(inverse4(prev) @ X, use_beta=par)
        out.append(Frame(name=names[i], joint=joints[i], parent=i - 1, coupling=couplings[i], **p))
        prev, prev_z = X, X[:3, 2]
    flags = parallel_beta_frames(out)
    return [replace(f, has_beta=b) for f, b in zip(out, flags)]



@accepts(model=is_a(RobotModel), units=UNIT_SYSTEM)
def mdh_table(model: RobotModel, *, units: str = "m-rad") -> list[dict]:
    """The MDH table, one dict per frame, units in the keys (``alpha_rad``, ``d_m``, ...).

    Keys in order: frame, parent (frame name or ``"base"``), joint (revolute/prismatic/fixed),
    reading (the joint reading(s) driving it, e.g. ``"j3"`` or ``"0.5*j3"``; empty when fixed),
    has_beta, then beta, alpha, d, theta, r, gamma, b with unit suffixes. theta (revolute) and r
    (prismatic) are the offsets at zero reading. ``units``: one of ``m-rad``, ``mm-deg``, ``m-deg``,
    ``mm-rad``.

    Parameters
    ----------
    {model, units}

    Returns
    -------
    list of dict
        One row per frame: name, joint, parent and its modified-DH values in ``units``.

    >>> from robocal.kinematics import serial_model
    >>> mdh_table(serial_model("r", [dict(d=0.5)]), units="mm-deg")[0]["d_mm"]
    500.0
    """
    names = dict(zip(("length", "angle"), parse_units(units, where="units")))
    factors = unit_factors(units)
    rows = []
    for f in model.frames:
        reading = " + ".join(model.joint_names[k] if c == 1.0 else f"{c!r}*{model.joint_names[k]}"
                             for k, c in f.coupling)
        row = {"frame": f.name, "parent": "base" if f.parent < 0 else model.frames[f.parent].name,
               "joint": f.joint, "reading": reading, "has_beta": f.has_beta}
        for kind in MDH_TABLE_KINDS:
            quantity = KIND_QUANTITY[kind]
            row[f"{kind}_{names[quantity]}"] = float(getattr(f, kind)) / factors[quantity]
        rows.append(row)
    return rows


@dataclass(frozen=True)
class StandardDH:
    """A serial model in classic (distal) DH, SI: ``rows`` one dict per joint (name, joint, theta,
    d, a, alpha), ``X_W0`` the pose of DH frame 0 in W, ``markers`` (name, X_nM) in the last DH
    frame, and ``offsets`` the frames whose common normal runs off (name, offset in m) where
    consecutive axes are nearly but not exactly parallel."""

    rows: tuple[dict, ...]
    X_W0: np.ndarray
    markers: tuple[tuple[str, np.ndarray], ...]
    offsets: tuple[tuple[str, float], ...]


def _serial_frames(model: RobotModel, what: str) -> None:
    for i, f in enumerate(model.frames):
        if f.parent != i - 1 or f.joint == "fixed" or f.coupling != ((i, 1.0),):
            raise InputError(f"{what} needs a serial chain with one reading per frame, in order; frame "
                             f"{f.name!r} is not", where=f"frames[{i}]")


def frame_poses(model: RobotModel) -> list[np.ndarray]:
    """``X_Wj`` (4x4) of every frame at zero readings."""
    out: list[np.ndarray] = []
    for f in model.frames:
        parent = model.X_WB if f.parent < 0 else out[f.parent]
        out.append(parent @ mdh_transform(f))
    return out


@accepts(model=is_a(RobotModel), max_offset=optional(POSITIVE_OR_INF))
def to_standard_dh(model: RobotModel, *, max_offset: float | None = None) -> StandardDH:
    """Classic DH of a serial model, with the same forward kinematics (exact up to a tilt below
    1e-12 rad between axes taken as parallel).

    Classic DH places each frame on the common normal of consecutive joint axes, frame 0 on axis 1
    level with the model's base: the rows are the robot's own, ``X_W0`` alone holds its base. Where
    the axes are nearly parallel (what Hayati's beta exists for) that normal runs off: the table needs
    offsets of hundreds of metres that cancel to give a metre-sized robot, and rounding them
    ruins the model. Offsets beyond ``max_offset`` (default ten times the robot's extent, and at
    least 10 m) raise an InputError naming the frames; ``max_offset=inf`` accepts them (the
    returned ``offsets`` list those beyond the default).

    Parameters
    ----------
    model : RobotModel
        A serial model with one reading per frame.
    {max_offset}

    Returns
    -------
    StandardDH
        The classic DH table with the base and tool placements.
    """
    _serial_frames(model, "classic DH")
    # the table is the robot's own, found in its base frame: where the instrument stood moves the base row only
    X = frame_poses(model.replace(base_position=(0.0, 0.0, 0.0), base_rotation=tuple(map(tuple, np.eye(3)))))
    pts = np.array([x[:3, 3] for x in X])
    X_0B, lines = line_frames(pts, np.array([x[:3, 2] for x in X]), 1e-12)
    rel = [_decompose(inverse4(prev) @ cur, use_beta=False) for prev, cur in zip([X_0B] + lines[:-1], lines)]
    rows = []
    for i, f in enumerate(model.frames):
        nxt = rel[i + 1] if i + 1 < len(rel) else dict(d=0.0, alpha=0.0)
        # classic row i: this frame's theta and r, the next frame's d and alpha (from_standard_dh, reversed)
        rows.append(dict(name=f.name, joint=f.joint, theta=rel[i]["theta"], d=rel[i]["r"], a=nxt["d"],
                         alpha=nxt["alpha"]))
    X_W0 = model.X_WB @ X_0B @ rot4(0, rel[0]["alpha"]) @ trans4(0, rel[0]["d"])
    extent = max(1.0, float(np.max(np.linalg.norm(pts, axis=1))))
    size = [(r["name"], max(abs(r["d"]), abs(r["a"]))) for r in rows]
    offsets = tuple((n, v) for n, v in size if v > 10.0 * extent)
    too_far = [(n, v) for n, v in size if v > (10.0 * extent if max_offset is None else max_offset)]
    if too_far:
        where = ", ".join(f"{n} ({v:.3g} m)" for n, v in too_far)
        raise InputError(f"classic DH is ill-conditioned here: nearly parallel axes put the common normal far "
                         f"away, offsets {where}; use modified DH (mdh-csv) or URDF", where="frames")
    markers = []
    for mk in model.markers:
        if mk.frame != len(model.frames) - 1:
            raise InputError(f"classic DH places markers on the last frame; {mk.name!r} is on "
                             f"{model.frames[mk.frame].name!r}", where="markers")
        markers.append((mk.name, inverse4(lines[-1]) @ X[-1] @ pose4(np.asarray(mk.rotation), mk.position)))
    return StandardDH(rows=tuple(rows), X_W0=X_W0, markers=tuple(markers), offsets=offsets)
