"""Robots as users have them: classic DH tables and URDF in, URDF and MDH tables out.

Every importer returns a :class:`RobotModel` in our modified-DH convention (docs/conventions.md)
whose forward kinematics equals the source's: the same marker pose in W for the same joint
readings, to rounding (tests check 1e-12 m). The MDH parameters themselves are a choice, written
down here:

* Frame j (one per moving joint) has z along the joint axis, pointing the way the source's positive
  joint motion turns (right-hand rule) or slides, so the readings are the source's joint values.
* x_j runs along the common normal of axis j and axis j+1 and O_j is its foot on axis j (Khalil and
  Kleinfinger). Where the two axes are parallel within ``DEFAULT_PARALLEL_TOL`` the normal is taken
  through the foot of the previous normal, so r_j = 0, and a residual tilt of the next axis goes
  into Hayati's beta (exact, and well conditioned where the true common normal runs off to
  infinity). The last frame continues the previous x (theta = r = 0 at zero readings).
* Whatever is left at the ends goes to the base pose ``X_WB`` and to the markers.

Units: SI everywhere; ``write_mdh_csv`` converts to the units it is asked for.
"""

from __future__ import annotations

import csv
import io
import math
import os
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Sequence

import numpy as np

from .._errors import InputError
from .._kinematics import _as_tuple3x3, _rot_matrix
from .model import write_texts
from .._model import DEFAULT_PARALLEL_TOL, Frame, Marker, RobotModel, parallel_beta_frames

__all__ = ["from_standard_dh", "read_urdf", "write_urdf", "mdh_table", "write_mdh_csv"]

_EYE3 = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


# ----------------------------------------------------------------------------------------------
# small transform helpers (4x4 homogeneous, active, right-multiplied steps)

def _rot4(axis: int, angle: float) -> np.ndarray:
    X = np.eye(4)
    X[:3, :3] = _rot_matrix(axis, angle)
    return X


def _trans4(axis: int, dist: float) -> np.ndarray:
    X = np.eye(4)
    X[axis, 3] = dist
    return X


def _pose(R, p) -> np.ndarray:
    X = np.eye(4)
    X[:3, :3] = R
    X[:3, 3] = p
    return X


def _inv(X: np.ndarray) -> np.ndarray:
    R, p = X[:3, :3], X[:3, 3]
    return _pose(R.T, -R.T @ p)


def mdh_transform(frame: Frame, q: float = 0.0) -> np.ndarray:
    """``X_parent_frame`` (4x4) of one frame at frame joint variable ``q`` (rad or m).

    ``Rot(z,gamma) Trans(z,b) Rot(y,beta) Rot(x,alpha) Trans(x,d) Rot(z,theta) Trans(z,r)`` with q
    added to theta (revolute) or r (prismatic); compliance is not applied.
    """
    th = frame.theta + (q if frame.joint == "revolute" else 0.0)
    r = frame.r + (q if frame.joint == "prismatic" else 0.0)
    return (_rot4(2, frame.gamma) @ _trans4(2, frame.b) @ _rot4(1, frame.beta) @ _rot4(0, frame.alpha)
            @ _trans4(0, frame.d) @ _rot4(2, th) @ _trans4(2, r))


def _rpy_matrix(rpy) -> np.ndarray:
    """URDF fixed-axis roll-pitch-yaw: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    roll, pitch, yaw = rpy
    return _rot_matrix(2, yaw) @ _rot_matrix(1, pitch) @ _rot_matrix(0, roll)


def _matrix_rpy(R: np.ndarray) -> tuple[float, float, float]:
    """Inverse of :func:`_rpy_matrix`, stable through gimbal lock.

    Yaw first, then roll and pitch from ``Rz(-yaw) R``: near pitch = +-pi/2 a poor yaw is absorbed
    by roll, so the rebuilt matrix stays accurate to rounding (separate atan2s would not).
    """
    yaw = math.atan2(R[1, 0], R[0, 0]) if math.hypot(R[1, 0], R[0, 0]) > 1e-300 else 0.0
    M = _rot_matrix(2, -yaw) @ R
    roll = math.atan2(-M[1, 2], M[1, 1])
    pitch = math.atan2(-M[2, 0], M[0, 0])
    return roll, pitch, yaw


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _perpendicular(z: np.ndarray, hint: np.ndarray | None) -> np.ndarray:
    """A unit vector normal to ``z``: ``hint`` made normal when it can be, else the best world axis."""
    if hint is not None:
        h = hint - (hint @ z) * z
        if np.linalg.norm(h) > 1e-9:
            return _unit(h)
    e = np.eye(3)[int(np.argmin(np.abs(z)))]
    return _unit(e - (e @ z) * z)


# ----------------------------------------------------------------------------------------------
# classic DH

def _markers_arg(markers, where: str) -> list[tuple[str, np.ndarray, np.ndarray]]:
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
    X_tail = _trans4(0, prev_a) @ _rot4(0, prev_alpha)
    mk = []
    for mname, p, R in _markers_arg(markers, "markers"):
        X = X_tail @ _pose(R, p)
        mk.append(Marker(mname, len(frames) - 1, tuple(float(v) for v in X[:3, 3]), _as_tuple3x3(X[:3, :3])))
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
        markers=tuple(mk), base_position=tuple(float(v) for v in X_W0[:3, 3]),
        base_rotation=_as_tuple3x3(X_W0[:3, :3]),
        description="imported from classic DH",
    )


# ----------------------------------------------------------------------------------------------
# lines (joint axes) to MDH frames

def _decompose(T: np.ndarray, use_beta: bool) -> dict:
    """MDH parameters of a relative pose built by :func:`_line_frames` (gamma = b = 0).

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
    Rp = _rot_matrix(1, beta) @ _rot_matrix(0, alpha)
    M = Rp.T @ T[:3, :3]
    theta = math.atan2(M[1, 0], M[0, 0])
    t = T[:3, 3]
    out = dict(beta=beta, alpha=alpha, d=float(t @ Rp[:, 0]), theta=theta, r=float(t @ Rp[:, 2]))
    # rounding noise (1e-17) reads as a parameter in tables; below 1e-15 it moves nothing measurable
    return {k: (0.0 if abs(v) < 1e-15 else v) for k, v in out.items()}


def _line_frames(points: np.ndarray, axes: np.ndarray, tol: float) -> tuple[np.ndarray, list[np.ndarray]]:
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
        RB = np.eye(3) if c > 0 else _rot_matrix(0, math.pi)
    else:
        k = _unit(w)
        K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
        ang = math.atan2(np.linalg.norm(w), c)
        RB = np.eye(3) + math.sin(ang) * K + (1 - math.cos(ang)) * K @ K
        RB[:, 2] = z1  # exact z, so frame 1 needs no alpha/beta
    foot = points[0] + (-points[0] @ z1) * z1      # root origin projected on axis 1
    X_0B = _pose(RB, foot)
    frames = []
    x_prev = RB[:, 0]
    for j in range(n):
        zj = axes[j]
        if j + 1 == n:
            O, x = foot, _perpendicular(zj, x_prev)
        else:
            zn, pn = axes[j + 1], points[j + 1]
            cr = np.cross(zj, zn)
            if np.linalg.norm(cr) <= math.sin(tol):
                # parallel: normal through the previous foot (r_j = 0), towards the nearest point of
                # the next axis; a slight tilt of that axis goes to beta of frame j+1
                O = foot
                near = pn + ((O - pn) @ zn) * zn
                x = _perpendicular(zj, near - O) if np.linalg.norm(near - O) > 1e-12 else \
                    _perpendicular(zj, x_prev)
                foot = near
            else:
                # common normal: solve for the feet O = pj + s zj and near = pn + u zn
                pj = points[j]
                A = np.array([[zj @ zj, -(zj @ zn)], [zj @ zn, -(zn @ zn)]])
                rhs = np.array([(pn - pj) @ zj, (pn - pj) @ zn])
                s, u = np.linalg.solve(A, rhs)
                O, near = pj + s * zj, pn + u * zn
                x = _unit(cr)
                if (near - O) @ x < -1e-12:
                    x = -x  # keep d >= 0 where the axes do not meet
                foot = near
        x = _unit(x - (x @ zj) * zj)
        frames.append(_pose(np.column_stack([x, np.cross(zj, x), zj]), O))
        x_prev = x
    return X_0B, frames


def _frames_from_lines(names, joints, couplings, X_0B, X_0F) -> list[Frame]:
    """Serial MDH frames from the base pose and frame poses found by :func:`_line_frames`."""
    out = []
    prev = X_0B
    prev_z = X_0B[:3, 2]
    for i, X in enumerate(X_0F):
        par = abs(float(prev_z @ X[:3, 2])) >= math.cos(DEFAULT_PARALLEL_TOL)
        p = _decompose(_inv(prev) @ X, use_beta=par)
        out.append(Frame(name=names[i], joint=joints[i], parent=i - 1, coupling=couplings[i], **p))
        prev, prev_z = X, X[:3, 2]
    flags = parallel_beta_frames(out)
    return [replace(f, has_beta=b) for f, b in zip(out, flags)]


# ----------------------------------------------------------------------------------------------
# URDF in

_NUM = re.compile(r"\s+")


@dataclass(frozen=True)
class _UJoint:
    name: str
    type: str
    parent: str
    child: str
    X_origin: np.ndarray        # X_parent_joint (4x4)
    axis: np.ndarray            # unit, in the joint frame
    limits: tuple[float, float] | None
    mimic: tuple[str, float, float] | None


def _floats(text: str | None, n: int, default, source: str, where: str) -> np.ndarray:
    if text is None:
        return np.asarray(default, dtype=float)
    parts = [p for p in _NUM.split(text.strip()) if p]
    try:
        vals = np.array([float(p) for p in parts])
    except ValueError:
        raise InputError(f"expected {n} numbers, got {text!r}", source=source, where=where) from None
    if vals.shape != (n,) or not np.all(np.isfinite(vals)):
        raise InputError(f"expected {n} finite numbers, got {text!r}", source=source, where=where)
    return vals


def _attr_float(el, key: str, default: float, source: str, where: str) -> float:
    return float(_floats(el.get(key), 1, [default], source, where + f" {key}")[0])


def _load_xml(path_or_string) -> tuple[ET.Element, str]:
    """Parse URDF text safely: DOCTYPE/ENTITY declarations (entity bombs, external entities) refused."""
    if isinstance(path_or_string, (os.PathLike, Path)) or (
            isinstance(path_or_string, str) and not path_or_string.lstrip().startswith("<")):
        source = os.fspath(path_or_string)
        try:
            raw = Path(source).read_bytes()
        except OSError as e:
            raise InputError(f"cannot read the file: {e.strerror}", source=source) from None
        try:
            text = raw.decode("utf-8-sig")
        except UnicodeDecodeError:
            raise InputError("URDF must be UTF-8 text", source=source) from None
    elif isinstance(path_or_string, str):
        source, text = "<string>", path_or_string
    else:
        raise InputError(f"expected a path or URDF text, got {type(path_or_string).__name__}", source="urdf")
    # URDF never needs a DTD; refusing it before the parser sees it rules out entity expansion
    if re.search(r"<!\s*(DOCTYPE|ENTITY)", text, flags=re.IGNORECASE):
        raise InputError("DOCTYPE/ENTITY declarations are not allowed in URDF", source=source)
    # the declaration may name an encoding; we already decoded, so drop it for the parser
    text = re.sub(r"^\s*<\?xml[^>]*\?>", "", text)
    try:
        root = ET.fromstring(text)
    except ET.ParseError as e:
        raise InputError(f"malformed XML: {e}", source=source) from None
    if root.tag != "robot":
        raise InputError(f"the root element must be <robot>, got <{root.tag}>", source=source)
    return root, source


def _parse_joints(root: ET.Element, source: str) -> tuple[set[str], dict[str, _UJoint], dict]:
    links: set[str] = set()
    inertials: dict[str, tuple[float, np.ndarray]] = {}
    for el in root.findall("link"):
        lname = el.get("name")
        if not lname:
            raise InputError("a <link> has no name", source=source, where="link")
        if lname in links:
            raise InputError("link named twice", source=source, where=f"link {lname!r}")
        links.add(lname)
        iner = el.find("inertial")
        if iner is not None and iner.find("mass") is not None:
            where = f"link {lname!r} inertial"
            m = _attr_float(iner.find("mass"), "value", 0.0, source, where)
            org = iner.find("origin")
            com = _floats(None if org is None else org.get("xyz"), 3, [0, 0, 0], source, where)
            inertials[lname] = (m, com)
    joints: dict[str, _UJoint] = {}
    child_of: dict[str, str] = {}
    for el in root.findall("joint"):
        jname = el.get("name")
        if not jname:
            raise InputError("a <joint> has no name", source=source, where="joint")
        where = f"joint {jname!r}"
        if jname in joints:
            raise InputError("joint named twice", source=source, where=where)
        jtype = el.get("type")
        pe, ce = el.find("parent"), el.find("child")
        parent = None if pe is None else pe.get("link")
        child = None if ce is None else ce.get("link")
        for role, lk in (("parent", parent), ("child", child)):
            if not lk:
                raise InputError(f"<{role} link=...> is missing", source=source, where=where)
            if lk not in links:
                raise InputError(f"{role} link {lk!r} is not defined", source=source, where=where)
        if child in child_of:
            raise InputError(f"link {child!r} is the child of two joints ({child_of[child]!r})",
                             source=source, where=where)
        child_of[child] = jname
        org = el.find("origin")
        xyz = _floats(None if org is None else org.get("xyz"), 3, [0, 0, 0], source, where + " origin xyz")
        rpy = _floats(None if org is None else org.get("rpy"), 3, [0, 0, 0], source, where + " origin rpy")
        ax = el.find("axis")
        axis = _floats(None if ax is None else ax.get("xyz"), 3, [1, 0, 0], source, where + " axis")
        lim = el.find("limit")
        limits = None
        if lim is not None:  # URDF: lower/upper default to 0
            limits = (_attr_float(lim, "lower", 0.0, source, where + " limit"),
                      _attr_float(lim, "upper", 0.0, source, where + " limit"))
        mim = el.find("mimic")
        mimic = None
        if mim is not None:
            if not mim.get("joint"):
                raise InputError("<mimic> needs joint=...", source=source, where=where)
            mimic = (mim.get("joint"), _attr_float(mim, "multiplier", 1.0, source, where + " mimic"),
                     _attr_float(mim, "offset", 0.0, source, where + " mimic"))
        joints[jname] = _UJoint(jname, jtype or "", parent, child, _pose(_rpy_matrix(rpy), xyz), axis,
                                limits, mimic)
    return links, joints, {"child_of": child_of, "inertials": inertials}


def _chain(links, joints, child_of, base_link, tip_link, source) -> list[_UJoint]:
    """Joints from ``base_link`` to ``tip_link`` in order (defaults: the unique root and leaf)."""
    children: dict[str, list[str]] = {lk: [] for lk in links}
    for j in joints.values():
        children[j.parent].append(j.name)
    if base_link is None:
        roots = sorted(lk for lk in links if lk not in child_of)
        if len(roots) != 1:
            raise InputError(f"expected one root link, found {roots}; pass base_link", source=source)
        base_link = roots[0]
    elif base_link not in links:
        raise InputError(f"base link {base_link!r} is not defined", source=source, where="base_link")
    if tip_link is None:
        chain, link = [], base_link
        while children[link]:
            if len(children[link]) > 1:
                raise InputError(f"the chain branches at link {link!r} (joints {children[link]}); pass tip_link",
                                 source=source, where=f"link {link!r}")
            j = joints[children[link][0]]
            chain.append(j)
            link = j.child
        return chain
    if tip_link not in links:
        raise InputError(f"tip link {tip_link!r} is not defined", source=source, where="tip_link")
    chain, link = [], tip_link
    while link != base_link:
        if link not in child_of:
            raise InputError(f"link {tip_link!r} does not descend from {base_link!r}", source=source,
                             where="tip_link")
        j = joints[child_of[link]]
        chain.append(j)
        link = j.parent
    return chain[::-1]


def read_urdf(path_or_string, *, base_link: str | None = None, tip_link: str | None = None,
              markers: Sequence | None = None) -> RobotModel:
    """A serial model from a URDF file (path) or URDF text (a string starting with ``<``).

    The chain runs from ``base_link`` to ``tip_link`` (defaults: the unique root link and the leaf
    of an unbranched chain). Joint types: revolute, prismatic, fixed, and continuous, read as
    revolute with limits +-pi (finite, so pose sampling works; every orientation is reachable).
    Revolute/prismatic joints need ``<limit>`` (the URDF rule); its lower/upper default to 0.
    ``<mimic>`` of a joint on the chain becomes a coupling (multiplier; offset into theta or r).
    Origins and axes may be arbitrary; axes are normalised. Each moving joint is one MDH frame
    named after its child link; the readings are named after the URDF joints, in chain order.
    Fixed joints fold into the frames around them. ``W`` is the base link: ``X_WB`` places the
    robot frame 0 (on the first axis) in it.

    ``markers``: ``(name, xyz)`` or ``(name, xyz, R)`` in the tip link's frame; by default one
    marker ``"tool"`` at the tip link's origin with its orientation.
    Link masses (``<inertial><mass>``, centre of mass from its origin) of links on the chain are
    summed per frame; inertias and links off the chain are ignored.

    Raises InputError naming the source and the joint: malformed XML, DOCTYPE/ENTITY, names used
    twice, missing links, a branching chain without tip_link, zero axis, floating/planar joints.
    """
    root, source = _load_xml(path_or_string)
    links, joints, extra = _parse_joints(root, source)
    chain = _chain(links, joints, extra["child_of"], base_link, tip_link, source)
    moving = []
    for j in chain:
        where = f"joint {j.name!r}"
        if j.type not in ("revolute", "continuous", "prismatic", "fixed"):
            raise InputError(f"joint type {j.type!r} is not supported (revolute, continuous, prismatic, fixed)",
                             source=source, where=where)
        if j.type != "fixed":
            n = float(np.linalg.norm(j.axis))
            if not n > 1e-12:
                raise InputError("the joint axis has zero length", source=source, where=where)
            if j.type in ("revolute", "prismatic") and j.limits is None:
                raise InputError(f"a {j.type} joint needs <limit lower upper>", source=source, where=where)
            if j.limits is not None and j.type != "continuous" and not j.limits[0] <= j.limits[1]:
                raise InputError("limit lower exceeds upper", source=source, where=where)
            moving.append(j.name)
    if not moving:
        raise InputError("no moving joint between base and tip", source=source)
    # readings: every moving joint that is not a mimic of another joint on the chain
    reading_of: dict[str, tuple[int, float, float]] = {}
    readings = []
    for jn in moving:
        mim = joints[jn].mimic
        if mim is None:
            reading_of[jn] = (len(readings), 1.0, 0.0)
            readings.append(jn)
    for jn in moving:
        mim = joints[jn].mimic
        if mim is not None:
            master = joints.get(mim[0])
            if master is None or master.mimic is not None or master.type not in (
                    "revolute", "continuous", "prismatic"):
                raise InputError(f"mimics {mim[0]!r}, which is not an independent moving joint",
                                 source=source, where=f"joint {jn!r}")
            if mim[0] not in reading_of:
                # a master off the chain still is a reading: it drives this joint
                if master.type != "continuous" and master.limits is None:
                    raise InputError(f"a {master.type} joint needs <limit lower upper>", source=source,
                                     where=f"joint {mim[0]!r}")
                reading_of[mim[0]] = (len(readings), 1.0, 0.0)
                readings.append(mim[0])
            k = reading_of[mim[0]][0]
            reading_of[jn] = (k, mim[1], mim[2])
    # walk the chain at zero readings: link poses X_0L, joint lines in frame 0 (root = base link)
    X = np.eye(4)
    X_link = {chain[0].parent: X.copy()}
    points, axes, X_child = [], [], []
    owner: dict[str, int] = {}          # link -> index of the MDH frame it rides on (-1: base)
    owner[chain[0].parent] = -1
    for j in chain:
        X = X @ j.X_origin
        if j.type != "fixed":
            a = X[:3, :3] @ _unit(j.axis)
            points.append(X[:3, 3].copy())
            axes.append(a)
            off = reading_of[j.name][2]    # mimic offset: the joint sits there at zero readings
            if off:
                X = X @ (_pose(_axis_angle(_unit(j.axis), off), np.zeros(3)) if j.type != "prismatic"
                         else _pose(np.eye(3), off * _unit(j.axis)))
            X_child.append(X.copy())
        owner[j.child] = len(axes) - 1
        X_link[j.child] = X.copy()
    X_0B, X_0F = _line_frames(np.array(points), np.array(axes), DEFAULT_PARALLEL_TOL)
    types = ["prismatic" if joints[jn].type == "prismatic" else "revolute" for jn in moving]
    couplings = [((reading_of[jn][0], reading_of[jn][1]),) for jn in moving]
    fnames = [joints[jn].child for jn in moving]
    frames = _frames_from_lines(fnames, types, couplings, X_0B, X_0F)
    # masses of chain links, in the frame they ride on
    mass = np.zeros(len(frames))
    first = np.zeros((len(frames), 3))
    for lk, (m, com) in extra["inertials"].items():
        i = owner.get(lk, -1)
        if i >= 0 and m > 0:
            c0 = X_link[lk][:3, :3] @ com + X_link[lk][:3, 3]
            cF = _inv(X_0F[i]) @ np.append(c0, 1.0)
            mass[i] += m
            first[i] += m * cF[:3]
    frames = [replace(f, mass=float(mass[i]), com=tuple(float(v) for v in first[i] / mass[i]))
              if mass[i] > 0 else f for i, f in enumerate(frames)]
    tip = chain[-1].child
    X_nT = _inv(X_0F[-1]) @ X_link[tip]
    mk = []
    for mname, p, R in _markers_arg(markers if markers is not None else [("tool", (0.0, 0.0, 0.0))], "markers"):
        Xm = X_nT @ _pose(R, p)
        mk.append(Marker(mname, len(frames) - 1, tuple(float(v) for v in Xm[:3, 3]), _as_tuple3x3(Xm[:3, :3])))
    limits = []
    for jn in readings:
        j = joints[jn]
        limits.append((-math.pi, math.pi) if j.type == "continuous" else j.limits)
    return RobotModel(
        name=root.get("name") or "robot", frames=tuple(frames), joint_names=tuple(readings),
        joint_limits=tuple((float(lo), float(hi)) for lo, hi in limits), markers=tuple(mk),
        base_position=tuple(float(v) for v in X_0B[:3, 3]), base_rotation=_as_tuple3x3(X_0B[:3, :3]),
        description=f"imported from URDF {source}, {chain[0].parent} -> {tip}",
    )


def _axis_angle(k: np.ndarray, angle: float) -> np.ndarray:
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


# ----------------------------------------------------------------------------------------------
# URDF out

def _num(v: float) -> str:
    return repr(float(v) + 0.0)  # + 0.0 turns -0.0 into 0.0


def _origin(el: ET.Element, X: np.ndarray) -> None:
    ET.SubElement(el, "origin", xyz=" ".join(_num(v) for v in X[:3, 3]),
                  rpy=" ".join(_num(v) for v in _matrix_rpy(X[:3, :3])))


def write_urdf(model: RobotModel, path, *, force: bool = False) -> None:
    """Write ``model`` as URDF (serial chains and trees), atomically.

    Links: ``world`` (the measurement frame W), ``base_link`` (robot frame 0, fixed joint with
    origin ``X_WB``), one link per frame (named after the frame), one link per marker (fixed joint,
    origin = marker pose). Each frame's joint has the frame's whole constant MDH transform as
    origin and axis 0 0 1 (the joint variable turns/slides about the frame's own z, which commutes
    with the final Rot(z,theta) Trans(z,r)). Revolute joints with infinite limits are written as
    continuous. Lengths in metres, angles in radians, full float precision.

    Coupling: for each reading the first frame driven by it alone with coefficient 1 is the URDF
    joint named after the reading; other frames driven by a single reading become ``<mimic>`` of
    it (multiplier = coefficient). A frame driven by several readings, or a reading that drives no
    frame with coefficient 1, cannot be said in URDF and raises InputError. Masses go out as
    ``<inertial>`` with zero inertia; compliance, gravity and payload are not written.
    """
    primary: dict[int, int] = {}
    for i, f in enumerate(model.frames):
        if len(f.coupling) == 1 and f.coupling[0][1] == 1.0 and f.coupling[0][0] not in primary:
            primary[f.coupling[0][0]] = i
    for i, f in enumerate(model.frames):
        if len(f.coupling) > 1:
            raise InputError("a frame driven by several readings cannot be written as URDF",
                             where=f"frames[{i}] ({f.name})")
        if f.coupling and f.coupling[0][0] not in primary:
            raise InputError(f"reading {model.joint_names[f.coupling[0][0]]!r} drives no frame with "
                             "coefficient 1; URDF cannot express it", where=f"frames[{i}] ({f.name})")
    # URDF keeps link names and joint names apart; each must be unique within its own kind
    used_links: set[str] = set()
    used_joints: set[str] = set()

    def unique(name: str, used: set[str]) -> str:
        out, k = name, 1
        while out in used:
            k += 1
            out = f"{name}_{k}"
        used.add(out)
        return out

    link_w, link_b = unique("world", used_links), unique("base_link", used_links)
    flinks = [unique(f.name, used_links) for f in model.frames]
    mlinks = [unique(m.name, used_links) for m in model.markers]
    jnames = {}
    for k, i in primary.items():
        jnames[i] = unique(model.joint_names[k], used_joints)
    for i, f in enumerate(model.frames):
        if i not in jnames:
            jnames[i] = unique(f"{f.name}_joint", used_joints)
    robot = ET.Element("robot", name=model.name)
    for lk in [link_w, link_b]:
        ET.SubElement(robot, "link", name=lk)
    for i, f in enumerate(model.frames):
        el = ET.SubElement(robot, "link", name=flinks[i])
        if f.mass > 0:
            iner = ET.SubElement(el, "inertial")
            ET.SubElement(iner, "origin", xyz=" ".join(_num(v) for v in f.com), rpy="0 0 0")
            ET.SubElement(iner, "mass", value=_num(f.mass))
            ET.SubElement(iner, "inertia", ixx="0", ixy="0", ixz="0", iyy="0", iyz="0", izz="0")
    for lk in mlinks:
        ET.SubElement(robot, "link", name=lk)
    j = ET.SubElement(robot, "joint", name=unique("world_to_base", used_joints), type="fixed")
    _origin(j, model.X_WB)
    ET.SubElement(j, "parent", link=link_w)
    ET.SubElement(j, "child", link=link_b)
    for i, f in enumerate(model.frames):
        if f.joint == "fixed":
            jtype = "fixed"
        elif f.joint == "prismatic":
            jtype = "prismatic"
        else:
            jtype = "revolute"
        k = f.coupling[0][0] if f.coupling else None
        lo, hi = model.joint_limits[k] if k is not None else (0.0, 0.0)
        if k is not None and primary[k] != i:
            # a mimic follows coef * reading: its own range is the reading's, scaled
            c = f.coupling[0][1]
            lo, hi = sorted((c * lo, c * hi))
        if jtype == "revolute" and not (math.isfinite(lo) and math.isfinite(hi)):
            jtype = "continuous"
        elif jtype == "prismatic" and not (math.isfinite(lo) and math.isfinite(hi)):
            raise InputError("URDF needs finite limits for a prismatic joint", where=f"frames[{i}] ({f.name})")
        j = ET.SubElement(robot, "joint", name=jnames[i], type=jtype)
        _origin(j, mdh_transform(f))
        ET.SubElement(j, "parent", link=link_b if f.parent < 0 else flinks[f.parent])
        ET.SubElement(j, "child", link=flinks[i])
        if jtype != "fixed":
            ET.SubElement(j, "axis", xyz="0 0 1")
        if jtype in ("revolute", "prismatic"):
            ET.SubElement(j, "limit", lower=_num(lo), upper=_num(hi), effort="0", velocity="0")
        if k is not None and primary[k] != i:
            ET.SubElement(j, "mimic", joint=jnames[primary[k]], multiplier=_num(f.coupling[0][1]), offset="0")
    for m, mk in enumerate(model.markers):
        j = ET.SubElement(robot, "joint", name=unique(f"{mk.name}_joint", used_joints), type="fixed")
        _origin(j, _pose(np.asarray(mk.rotation, dtype=float), mk.position))
        ET.SubElement(j, "parent", link=flinks[mk.frame])
        ET.SubElement(j, "child", link=mlinks[m])
    ET.indent(robot)
    text = '<?xml version="1.0" encoding="utf-8"?>\n' + ET.tostring(robot, encoding="unicode") + "\n"
    write_texts({path: text}, force=force)


# ----------------------------------------------------------------------------------------------
# MDH table

# unit system -> (length name, length factor from metres, angle name, angle factor from radians)
_UNITS = {
    "m-rad": ("m", 1.0, "rad", 1.0),
    "mm-deg": ("mm", 1e3, "deg", 180.0 / math.pi),
    "m-deg": ("m", 1.0, "deg", 180.0 / math.pi),
    "mm-rad": ("mm", 1e3, "rad", 1.0),
}
_TABLE_KINDS = ("beta", "alpha", "d", "theta", "r", "gamma", "b")


def mdh_table(model: RobotModel, *, units: str = "m-rad") -> list[dict]:
    """The MDH table, one dict per frame, units in the keys (``alpha_rad``, ``d_m``, ...).

    Keys in order: frame, parent (frame name or ``"base"``), joint (revolute/prismatic/fixed),
    reading (the joint reading(s) driving it, e.g. ``"j3"`` or ``"0.5*j3"``; empty when fixed),
    has_beta, then beta, alpha, d, theta, r, gamma, b with unit suffixes. theta (revolute) and r
    (prismatic) are the offsets at zero reading. ``units``: one of ``m-rad``, ``mm-deg``, ``m-deg``,
    ``mm-rad``.

    >>> from robocal._model import serial_model
    >>> mdh_table(serial_model("r", [dict(d=0.5)]), units="mm-deg")[0]["d_mm"]
    500.0
    """
    if units not in _UNITS:
        raise InputError(f"units must be one of {', '.join(_UNITS)}, got {units!r}", where="units")
    lname, lf, aname, af = _UNITS[units]
    rows = []
    for f in model.frames:
        reading = " + ".join(model.joint_names[k] if c == 1.0 else f"{c!r}*{model.joint_names[k]}"
                             for k, c in f.coupling)
        row = {"frame": f.name, "parent": "base" if f.parent < 0 else model.frames[f.parent].name,
               "joint": f.joint, "reading": reading, "has_beta": f.has_beta}
        for kind in _TABLE_KINDS:
            is_angle = kind in ("beta", "alpha", "theta", "gamma")
            row[f"{kind}_{aname if is_angle else lname}"] = float(getattr(f, kind)) * (af if is_angle else lf)
        rows.append(row)
    return rows


def write_mdh_csv(model: RobotModel, path, *, units: str = "mm-deg", force: bool = False) -> None:
    """Write :func:`mdh_table` as CSV (header with unit suffixes), atomically; 15 significant digits."""
    rows = mdh_table(model, units=units)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(list(rows[0]))
    for row in rows:
        w.writerow([format(v, ".15g") if isinstance(v, float) else v for v in row.values()])
    write_texts({path: buf.getvalue()}, force=force)
