"""URDF in and out. Reading turns a URDF chain's joint axes into our modified DH with Hayati's
beta (``_conversion``: the same forward kinematics, to rounding); writing puts each frame's
constant transform into its joint's origin. URDF speaks metres and radians, as robocal does inside.
"""

from __future__ import annotations

import math
import os
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Sequence

import numpy as np

from .._errors import InputError, excerpt
from .._conversion import frames_from_lines, line_frames, marker_placements
from .._model import DEFAULT_PARALLEL_TOL, Marker, RobotModel, mdh_transform
from .._spatial import axis_angle_matrix, inverse4, matrix_rpy, matrix_tuple, pose4, rpy_matrix, unit_vector
from .text import read_bytes, write_texts

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
        raw = read_bytes(source)
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


# bounds on a URDF (docs/formats.md): a robot arm has tens of elements nested a few deep
MAX_XML_DEPTH = 32
MAX_XML_ELEMENTS = 100_000


def check_tree(root: ET.Element, source: str) -> None:
    """Refuse, before anything walks it, a document nested or sized beyond the bounds, and joints
    whose links form a cycle (following parents from a link must end at a root)."""
    count, stack = 0, [(root, 1)]
    while stack:
        el, depth = stack.pop()
        count += 1
        if depth > MAX_XML_DEPTH or count > MAX_XML_ELEMENTS:
            what = f"nested more than {MAX_XML_DEPTH} elements deep" if depth > MAX_XML_DEPTH else \
                f"more than {MAX_XML_ELEMENTS:,} elements"
            raise InputError(f"{what}: not a robot description", source=source)
        stack.extend((child, depth + 1) for child in el)
    parent_of: dict = {}
    for el in root.findall("joint"):
        pe, ce = el.find("parent"), el.find("child")
        if pe is not None and ce is not None and ce.get("link") not in parent_of:
            parent_of[ce.get("link")] = (pe.get("link"), el.get("name"))
    done: set = set()
    for start in parent_of:
        path, link = {}, start  # insertion-ordered: the links walked so far
        while link in parent_of and link not in done:
            if link in path:
                loop = list(path)[list(path).index(link):]
                raise InputError(f"the joints form a cycle through the links {', '.join(map(excerpt, loop))}",
                                 source=source, where=f"joint {excerpt(parent_of[link][1])}")
            path[link] = None
            link = parent_of[link][0]
        done.update(path)


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
        joints[jname] = _UJoint(jname, jtype or "", parent, child, pose4(rpy_matrix(rpy), xyz), axis,
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
    check_tree(root, source)
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
            a = X[:3, :3] @ unit_vector(j.axis)
            points.append(X[:3, 3].copy())
            axes.append(a)
            off = reading_of[j.name][2]    # mimic offset: the joint sits there at zero readings
            if off:
                X = X @ (pose4(axis_angle_matrix(unit_vector(j.axis), off), np.zeros(3)) if j.type != "prismatic"
                         else pose4(np.eye(3), off * unit_vector(j.axis)))
            X_child.append(X.copy())
        owner[j.child] = len(axes) - 1
        X_link[j.child] = X.copy()
    X_0B, X_0F = line_frames(np.array(points), np.array(axes), DEFAULT_PARALLEL_TOL)
    types = ["prismatic" if joints[jn].type == "prismatic" else "revolute" for jn in moving]
    couplings = [((reading_of[jn][0], reading_of[jn][1]),) for jn in moving]
    fnames = [joints[jn].child for jn in moving]
    frames = frames_from_lines(fnames, types, couplings, X_0B, X_0F)
    # masses of chain links, in the frame they ride on
    mass = np.zeros(len(frames))
    first = np.zeros((len(frames), 3))
    for lk, (m, com) in extra["inertials"].items():
        i = owner.get(lk, -1)
        if i >= 0 and m > 0:
            c0 = X_link[lk][:3, :3] @ com + X_link[lk][:3, 3]
            cF = inverse4(X_0F[i]) @ np.append(c0, 1.0)
            mass[i] += m
            first[i] += m * cF[:3]
    frames = [replace(f, mass=float(mass[i]), com=tuple(float(v) for v in first[i] / mass[i]))
              if mass[i] > 0 else f for i, f in enumerate(frames)]
    tip = chain[-1].child
    X_nT = inverse4(X_0F[-1]) @ X_link[tip]
    mk = []
    for mname, p, R in marker_placements(markers if markers is not None else [("tool", (0.0, 0.0, 0.0))], "markers"):
        Xm = X_nT @ pose4(R, p)
        mk.append(Marker(mname, len(frames) - 1, tuple(float(v) for v in Xm[:3, 3]), matrix_tuple(Xm[:3, :3])))
    limits = []
    for jn in readings:
        j = joints[jn]
        limits.append((-math.pi, math.pi) if j.type == "continuous" else j.limits)
    return RobotModel(
        name=root.get("name") or "robot", frames=tuple(frames), joint_names=tuple(readings),
        joint_limits=tuple((float(lo), float(hi)) for lo, hi in limits), markers=tuple(mk),
        base_position=tuple(float(v) for v in X_0B[:3, 3]), base_rotation=matrix_tuple(X_0B[:3, :3]),
        description=f"imported from URDF {source}, {chain[0].parent} -> {tip}",
    )


# ----------------------------------------------------------------------------------------------
# URDF out

def _num(v: float) -> str:
    return repr(float(v) + 0.0)  # + 0.0 turns -0.0 into 0.0


def _origin(el: ET.Element, X: np.ndarray) -> None:
    ET.SubElement(el, "origin", xyz=" ".join(_num(v) for v in X[:3, 3]),
                  rpy=" ".join(_num(v) for v in matrix_rpy(X[:3, :3])))


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
        _origin(j, pose4(np.asarray(mk.rotation, dtype=float), mk.position))
        ET.SubElement(j, "parent", link=flinks[mk.frame])
        ET.SubElement(j, "child", link=mlinks[m])
    ET.indent(robot)
    text = '<?xml version="1.0" encoding="utf-8"?>\n' + ET.tostring(robot, encoding="unicode") + "\n"
    write_texts({path: text}, force=force)
