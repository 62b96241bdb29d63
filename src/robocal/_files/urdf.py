"""URDF in and out. Reading turns a URDF chain's joint axes into our modified DH with Hayati's
beta (``_conversion``: the same forward kinematics, to rounding); writing puts each frame's
constant transform into its joint's origin. URDF speaks metres and radians, as robocal does inside.
"""

from __future__ import annotations

import math
import os
import re
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass, replace
from decimal import Decimal
from pathlib import Path

import numpy as np

from .._base.arguments import (
    FLAG,
    PATH,
    SEQUENCE,
    TEXT,
    accepts,
    is_a,
    optional,
)
from .._base.errors import InputError, excerpt
from .._base.options import MAX_MODEL_BYTES
from .._base.spatial import (
    axis_angle_matrix,
    inverse4,
    matrix_rpy,
    matrix_tuple,
    pose4,
    rpy_matrix,
    unit_vector,
    vector3,
)
from .._base.units import ANGLE_UNITS
from .._model.conversion import frames_from_lines, line_frames, marker_placements
from .._model.robot import DEFAULT_PARALLEL_TOL, Marker, RobotModel, mdh_transform
from .model import FINEST, LARGEST, MAX_MAGNITUDE, model_from_dict, model_to_dict
from .text import read_bytes, refuse_other_form, write_texts

# ----------------------------------------------------------------------------------------------
# URDF in

_NUM = re.compile(r"\s+")
SI = {"length": "m", "angle": "rad"}     # the URDF rule


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


def _floats(text: str | None, n: int, default, source: str, where: str, quantity: str | None = None) -> np.ndarray:
    """The ``n`` numbers of an attribute (``default`` without it); ``quantity`` ("length" or
    "angle", None for a plain number): beyond what a model file holds of it, an InputError."""
    if text is None:
        return np.asarray(default, dtype=float)
    parts = [p for p in _NUM.split(text.strip()) if p]
    try:
        vals = np.array([float(p) for p in parts])
    except ValueError:
        raise InputError(f"expected {n} numbers, got {text!r}", source=source, where=where) from None
    if vals.shape != (n,) or not np.all(np.isfinite(vals)):
        raise InputError(f"expected {n} finite numbers, got {text!r}", source=source, where=where)
    # a model file's own bound, in the unit it holds the largest numbers in (a 1e11 m origin is 1e14 mm)
    largest, said = (LARGEST[quantity], f"{LARGEST[quantity]:g} {SI[quantity]}, what a model file holds") \
        if quantity else (MAX_MAGNITUDE, f"{MAX_MAGNITUDE:g}")
    if not np.all(np.abs(vals) < largest):
        raise InputError(f"{text!r} is too large (magnitude below {said})", source=source, where=where)
    return vals


def _exponent(text: str) -> int:
    """The decimal exponent of a number as written (-3 for 0.125); ValueError for nan and inf."""
    e = Decimal(text).as_tuple().exponent
    if not isinstance(e, int):
        raise ValueError(f"not a finite number: {text!r}")
    return e


def _round_angle(v: float, text: str | None) -> float:
    """An angle written in radians to some decimals (0.820304748437) as the whole degrees or
    fraction it stands for to that precision (47 deg): the file's precision, shown in degrees."""
    try:
        written = 0.5 * 10.0 ** _exponent((text or "0").strip())
    except (ArithmeticError, TypeError, ValueError):
        return v
    if written > 1e-6:   # a short number (-1.0) is the angle it says, not a rounded degree value
        return v
    in_deg = written / ANGLE_UNITS["deg"]
    decimals = max(0, -math.ceil(math.log10(2 * in_deg))) if in_deg > 0 else 15
    return round(v / ANGLE_UNITS["deg"], decimals) * ANGLE_UNITS["deg"]


def _attr_float(el, key: str, default: float, source: str, where: str, quantity: str | None = None) -> float:
    return float(_floats(el.get(key), 1, [default], source, where + f" {key}", quantity)[0])


def _load_xml(path_or_string) -> tuple[ET.Element, str]:
    """Parse URDF text safely: DOCTYPE/ENTITY declarations (entity bombs, external entities) refused."""
    if isinstance(path_or_string, (os.PathLike, Path)) or (
            isinstance(path_or_string, str) and not path_or_string.lstrip().startswith("<")):
        source = os.fspath(path_or_string)
        raw = read_bytes(source, limit=MAX_MODEL_BYTES)
        try:
            text = raw.decode("utf-8-sig")
        except UnicodeDecodeError:
            raise InputError("URDF must be UTF-8 text", source=source) from None
        refuse_other_form(text, source, "a URDF", ("urdf", "xml", "json"))
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
    check_tree(root, source)  # before anything walks the joints
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
        path: dict[str, None] = {}  # insertion-ordered: the links walked so far
        link = start
        while link in parent_of and link not in done:
            if link in path:
                loop = list(path)[list(path).index(link):]
                raise InputError(f"the joints form a cycle through the links {', '.join(map(excerpt, loop))}",
                                 source=source, where=f"joint {excerpt(parent_of[link][1])}")
            path[link] = None
            link = parent_of[link][0]
        done.update(path)


def _parse_joints(root: ET.Element, source: str) -> tuple[set[str], dict[str, _UJoint], dict]:
    links, inertials = _parse_links(root, source)
    joints: dict[str, _UJoint] = {}
    child_of: dict[str, str] = {}
    for el in root.findall("joint"):
        jname = el.get("name")
        if not jname:
            raise InputError("a <joint> has no name", source=source, where="joint")
        where = f"joint {jname!r}"
        if jname in joints:
            raise InputError("joint named twice", source=source, where=where)
        parent, child = (_joint_link(el, role, links, source, where) for role in ("parent", "child"))
        if child in child_of:
            raise InputError(f"link {child!r} is the child of two joints ({child_of[child]!r})",
                             source=source, where=where)
        child_of[child] = jname
        joints[jname] = _parse_joint(el, jname, parent, child, source, where)
    return links, joints, {"child_of": child_of, "inertials": inertials}


def _parse_links(root: ET.Element, source: str) -> tuple[set[str], dict[str, tuple[float, np.ndarray]]]:
    """The link names, and the mass and centre of mass of each link with an inertial."""
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
            if m < 0:   # summed onto its frame it would take mass off the links beside it, or make none
                raise InputError(f"mass must be non-negative, got {m:g} kg", source=source, where=f"{where} mass")
            org = iner.find("origin")
            com = _floats(None if org is None else org.get("xyz"), 3, [0, 0, 0], source, f"{where} origin xyz",
                          "length")
            inertials[lname] = (m, com)
    return links, inertials


def _joint_link(el: ET.Element, role: str, links: set[str], source: str, where: str) -> str:
    """The joint's ``role`` ("parent" or "child") link, which must be defined."""
    found = el.find(role)
    link = "" if found is None else found.get("link", "")
    if not link:
        raise InputError(f"<{role} link=...> is missing", source=source, where=where)
    if link not in links:
        raise InputError(f"{role} link {link!r} is not defined", source=source, where=where)
    return link


def _parse_joint(el: ET.Element, jname: str, parent: str, child: str, source: str, where: str) -> _UJoint:
    """A joint's origin, axis, limits and mimic."""
    jtype = el.get("type")
    org = el.find("origin")
    xyz = _floats(None if org is None else org.get("xyz"), 3, [0, 0, 0], source, where + " origin xyz", "length")
    rpy = _floats(None if org is None else org.get("rpy"), 3, [0, 0, 0], source, where + " origin rpy", "angle")
    moves = "length" if jtype == "prismatic" else "angle"   # what its limits and a mimic's offset are
    ax = el.find("axis")
    axis = _floats(None if ax is None else ax.get("xyz"), 3, [1, 0, 0], source, where + " axis")
    lim = el.find("limit")
    limits = None
    if lim is not None:  # URDF: lower/upper default to 0
        lower, upper = (_attr_float(lim, k, 0.0, source, where + " limit", moves) for k in ("lower", "upper"))
        if jtype in ("revolute", "continuous"):
            lower, upper = _round_angle(lower, lim.get("lower")), _round_angle(upper, lim.get("upper"))
        limits = (lower, upper)
    mim = el.find("mimic")
    mimic = None
    if mim is not None:
        master = mim.get("joint")
        if not master:
            raise InputError("<mimic> needs joint=...", source=source, where=where)
        mimic = (master, _attr_float(mim, "multiplier", 1.0, source, where + " mimic"),
                 _attr_float(mim, "offset", 0.0, source, where + " mimic", moves))
    return _UJoint(jname, jtype or "", parent, child, pose4(rpy_matrix(rpy), xyz), axis, limits, mimic)


def _children(links, joints) -> dict[str, list[str]]:
    children: dict[str, list[str]] = {lk: [] for lk in links}
    for j in joints.values():
        children[j.parent].append(j.name)
    return children


def _moves(link: str, children, joints) -> bool:
    """Whether any joint below ``link`` moves."""
    return any(joints[j].type != "fixed" or _moves(joints[j].child, children, joints) for j in children[link])


@dataclass(frozen=True)
class ChainEnd:
    """Where a URDF's chain ends when no tip link is given, and why.

    ``link`` is the chain's last link; ``reason`` says why it goes no further (no child, moving
    branches parting, several fixed branches); ``further`` names the links below it reached through
    fixed joints only that hold nothing more (a ball, a tool point): each could be the tip link.
    """

    link: str
    reason: str
    further: tuple[str, ...] = ()


def _fixed_leaves(link: str, children, joints) -> list[str]:
    """The links below ``link`` reached through fixed joints only that have no child, in tree order."""
    out: list[str] = []
    for j in children[link]:
        if joints[j].type == "fixed":
            child = joints[j].child
            out += _fixed_leaves(child, children, joints) if children[child] else [child]
    return out


def _default_tip(base_link: str, children, joints, source: str) -> ChainEnd:
    """The end of the arm below ``base_link``: follow the one branch that moves; branches that hold
    only fixed links (a flange, a tool point) are not branches of the arm; where two or more moving
    branches part after the arm has moved (a gripper's fingers), stop, and go on only into a single
    fixed branch there (its tool point)."""
    link, arm_moved = base_link, False
    while children[link]:
        kids = [joints[j] for j in children[link]]
        moving = [j for j in kids if j.type != "fixed" or _moves(j.child, children, joints)]
        fixed = [j for j in kids if j not in moving]
        if len(moving) == 1:
            nxt = moving[0]
        elif len(moving) > 1 and not arm_moved:
            raise InputError(f"the chain branches at link {link!r} (joints {', '.join(j.name for j in moving)}); "
                             "give the tip link", source=source, where="tip_link")
        elif len(fixed) == 1:
            nxt = fixed[0]
        else:
            why = []
            if moving:
                why.append(f"{len(moving)} moving branches part there (joints {', '.join(j.name for j in moving)}: "
                           "a gripper's fingers, not imported)")
            if fixed:
                why.append(f"it holds {len(fixed)} fixed branches (links {', '.join(j.child for j in fixed)}) and "
                           "which one is the tool is not known")
            return ChainEnd(link, " and ".join(why), tuple(_fixed_leaves(link, children, joints)))
        arm_moved |= nxt.type != "fixed"
        link = nxt.child
    return ChainEnd(link, "it has no child link")


def _default_markers(chain, links, joints) -> list[tuple[str, np.ndarray]]:
    """The markers of a URDF read without ``markers``: (name, X_tip_marker).

    A tool point reached through fixed joints at the chain's end keeps its link's name; where the tip
    holds several leaf links on fixed joints named ``<link>_joint`` (the markers of a model
    :func:`urdf_text` wrote), each is a marker named after its link; otherwise one marker ``"tool"``
    at the tip link's origin.
    """
    tip = chain[-1].child
    if chain[-1].type == "fixed":
        return [(tip, np.eye(4))]
    children = _children(links, joints)
    leaves = [joints[j] for j in children[tip]]
    if len(leaves) > 1 and all(j.type == "fixed" and not children[j.child] and j.name == f"{j.child}_joint"
                               for j in leaves):
        return [(j.child, j.X_origin) for j in leaves]
    return [("tool", np.eye(4))]


def _base(links, child_of, base_link, source) -> str:
    """``base_link``, or the unique root link when it is None."""
    if base_link is None:
        roots = sorted(lk for lk in links if lk not in child_of)
        if len(roots) != 1:
            raise InputError(f"expected one root link, found {roots}; give the base link", source=source,
                             where="base_link")
        return roots[0]
    if base_link not in links:
        raise InputError(f"base link {base_link!r} is not defined", source=source, where="base_link")
    return base_link


def _chain(links, joints, child_of, base_link, tip_link, source) -> list[_UJoint]:
    """Joints from ``base_link`` to ``tip_link`` in order (defaults: the unique root, and
    :func:`_default_tip`)."""
    base_link = _base(links, child_of, base_link, source)
    if tip_link is None:
        tip_link = _default_tip(base_link, _children(links, joints), joints, source).link
    elif tip_link not in links:
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


@accepts(path_or_string=PATH, base_link=optional(TEXT))
def chain_end(path_or_string, *, base_link: str | None = None) -> ChainEnd:
    """Where :func:`read_urdf` without ``tip_link`` ends the chain of a URDF, and why.

    Parameters
    ----------
    {path_or_string, base_link}

    Returns
    -------
    ChainEnd
        The last link, the reason the chain goes no further, and the links below it reached through
        fixed joints only (candidates for ``tip_link``).
    """
    root, source = _load_xml(path_or_string)
    links, joints, extra = _parse_joints(root, source)
    base = _base(links, extra["child_of"], base_link, source)
    return _default_tip(base, _children(links, joints), joints, source)


def _moving_joints(chain, source: str) -> list[str]:
    """The names of the chain's moving joints, once each joint's type, axis and limits are checked."""
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
            if j.limits is not None and j.type != "continuous" and j.mimic is None and j.limits[0] == j.limits[1]:
                raise InputError(f"limit lower and upper are both {j.limits[0]:g} (a <limit> without them gives 0 and "
                                 "0): a joint that cannot move; give its range", source=source, where=where)
            moving.append(j.name)
    if not moving:
        raise InputError("no moving joint between base and tip", source=source)
    return moving


def _readings(moving, joints, source: str) -> tuple[list[str], dict[str, tuple[int, float, float]]]:
    """The readings (every moving joint that mimics no other, and masters off the chain) and, per
    moving joint, (reading index, multiplier, offset)."""
    reading_of: dict[str, tuple[int, float, float]] = {}
    readings: list[str] = []
    for jn in moving:
        if joints[jn].mimic is None:
            reading_of[jn] = (len(readings), 1.0, 0.0)
            readings.append(jn)
    for jn in moving:
        mim = joints[jn].mimic
        if mim is None:
            continue
        master = joints.get(mim[0])
        if master is None or master.mimic is not None or master.type not in ("revolute", "continuous", "prismatic"):
            raise InputError(f"mimics {mim[0]!r}, which is not an independent moving joint",
                             source=source, where=f"joint {jn!r}")
        if mim[0] not in reading_of:
            # a master off the chain still is a reading: it drives this joint
            if master.type != "continuous" and master.limits is None:
                raise InputError(f"a {master.type} joint needs <limit lower upper>", source=source,
                                 where=f"joint {mim[0]!r}")
            reading_of[mim[0]] = (len(readings), 1.0, 0.0)
            readings.append(mim[0])
        reading_of[jn] = (reading_of[mim[0]][0], mim[1], mim[2])
    return readings, reading_of


@dataclass(frozen=True)
class _Walk:
    """The chain at zero readings, in the base link's frame: each link's pose, each moving joint's
    line (point, axis), and the index of the MDH frame each link rides on (-1: the base)."""

    X_link: dict
    points: np.ndarray
    axes: np.ndarray
    owner: dict


def _walk(chain, reading_of) -> _Walk:
    X = np.eye(4)
    X_link = {chain[0].parent: X.copy()}
    points, axes = [], []
    owner = {chain[0].parent: -1}
    for j in chain:
        X = X @ j.X_origin
        if j.type != "fixed":
            points.append(X[:3, 3].copy())
            axes.append(X[:3, :3] @ unit_vector(j.axis))
            off = reading_of[j.name][2]    # mimic offset: the joint sits there at zero readings
            if off:
                X = X @ (pose4(axis_angle_matrix(unit_vector(j.axis), off), np.zeros(3)) if j.type != "prismatic"
                         else pose4(np.eye(3), off * unit_vector(j.axis)))
        owner[j.child] = len(axes) - 1
        X_link[j.child] = X.copy()
    return _Walk(X_link, np.array(points), np.array(axes), owner)


def _with_masses(frames, walk: _Walk, X_0F, inertials) -> list:
    """Masses of the chain's links summed on the frame each rides on (centre of mass in that frame)."""
    mass = np.zeros(len(frames))
    first = np.zeros((len(frames), 3))
    for lk, (m, com) in inertials.items():
        i = walk.owner.get(lk, -1)
        if i >= 0 and m > 0:
            c0 = walk.X_link[lk][:3, :3] @ com + walk.X_link[lk][:3, 3]
            cF = inverse4(X_0F[i]) @ np.append(c0, 1.0)
            mass[i] += m
            first[i] += m * cF[:3]
    return [replace(f, mass=float(mass[i]), com=vector3(first[i] / mass[i]))
            if mass[i] > 0 else f for i, f in enumerate(frames)]


def _source_angle_tol(root: ET.Element) -> float:
    """How far the file's angles stand from the multiples of pi/2 they were written for: an rpy
    number within half a unit of its last written digit of such a multiple meant it (pi written
    to 11 decimals is 2e-12 off); four times the largest such gap, at least 1e-13 rad. Gaps over
    1e-10 rad (pi written as 3.1416) are kept: the file says that angle, and snapping it would move
    the tool by more than 1e-10 m per metre of arm."""
    gaps = [1e-13]
    for el in root.iter("origin"):
        for part in _NUM.split((el.get("rpy") or "").strip()):
            try:
                v, written = float(part), 0.5 * 10.0 ** _exponent(part)
            except (ValueError, ArithmeticError, TypeError):
                continue
            gap = abs(v - round(v / (math.pi / 2)) * (math.pi / 2))
            if gap <= min(written, 1e-10):
                gaps.append(4 * gap)
    return max(gaps)


def _source_decimals(root: ET.Element) -> int:
    """The most decimals of a metre any origin's xyz is written with (at most 14): lengths the
    import computes from them carry no more."""
    most = 0
    for el in root.iter("origin"):
        for part in _NUM.split((el.get("xyz") or "").strip()):
            try:
                most = max(most, -_exponent(part))
            except (ArithmeticError, TypeError, ValueError):
                continue
    return min(most, 14)


def _clean(v: float, angle: bool, tol: float, decimals: int = 14) -> float:
    """``v`` without the source's round-off: an angle within ``tol`` of a multiple of pi/2 is that
    multiple; a length within 1e-12 m of ``decimals`` decimals of a metre (those of the source)
    is rounded to them."""
    if angle:
        k = round(v / (math.pi / 2))
        return k * (math.pi / 2) + 0.0 if abs(v - k * (math.pi / 2)) <= tol else v
    short = round(v, decimals)
    # a length the source's numbers add up to sits within float noise of that many decimals;
    # one through a skew axis does not, and keeps its digits
    return (short if abs(short - v) <= 1e-12 else round(v, 14)) + 0.0


def _clean_frames(frames, tol: float, decimals: int) -> list:
    angles, lengths = ("beta", "alpha", "theta", "gamma"), ("d", "r", "b")
    return [replace(f, **{k: _clean(getattr(f, k), True, tol) for k in angles},
                    **{k: _clean(getattr(f, k), False, tol, decimals) for k in lengths},
                    com=tuple(_clean(v, False, tol, decimals) for v in f.com)) for f in frames]


def _clean_pose(X: np.ndarray, decimals: int) -> tuple[tuple, tuple]:
    R = np.where(np.abs(X[:3, :3]) < 1e-12, 0.0, X[:3, :3])
    R = np.where(np.abs(np.abs(R) - 1.0) < 1e-12, np.sign(R), R)
    return tuple(_clean(float(v), False, 0.0, decimals) for v in X[:3, 3]), matrix_tuple(R)


@accepts(path_or_string=PATH, base_link=optional(TEXT), tip_link=optional(TEXT), markers=optional(SEQUENCE))
def read_urdf(path_or_string, *, base_link: str | None = None, tip_link: str | None = None,
              markers: Sequence | None = None) -> RobotModel:
    """A serial model from a URDF file (path) or URDF text (a string starting with ``<``).

    The chain runs from ``base_link`` to ``tip_link`` (defaults: the unique root link, and the end
    of the arm: the one moving branch is followed, branches of fixed links only (a flange, a tool
    point) do not count, and where a gripper's fingers part it stops, going on only into a single
    fixed branch; joints beyond the tip are not imported). Joint types: revolute, prismatic, fixed,
    and continuous, read as revolute with limits +-pi (finite, so pose sampling works; every
    orientation is reachable). Revolute/prismatic joints need ``<limit>`` (the URDF rule); its
    lower/upper default to 0. ``<mimic>`` of a joint on the chain becomes a coupling (multiplier;
    offset into theta or r). Origins and axes may be arbitrary; axes are normalised. Each moving
    joint is one MDH frame named after its child link; the readings are named after the URDF
    joints, in chain order. Fixed joints fold into the frames around them. ``W`` is the base link:
    ``X_WB`` places the robot frame 0 (on the first axis) in it. Values are cleaned of the
    source's round-off (``_clean``): the forward kinematics moves by less than 1e-9 m.

    ``markers``: ``(name, xyz)`` or ``(name, xyz, R)`` in the tip link's frame; by default the tip
    link itself when the chain ends in fixed joints (a tool point: the marker keeps the link's name),
    the leaf links on fixed joints ``<link>_joint`` at the tip when there are several (the markers
    of an exported model), else one marker ``"tool"`` at the tip link's origin with its orientation.
    Link masses (``<inertial><mass>``, centre of mass from its origin) of links on the chain are
    summed per frame; inertias and links off the chain are ignored.

    Raises InputError naming the source and the joint: malformed XML, DOCTYPE/ENTITY, names used
    twice, missing links, a chain that branches before the arm moves without tip_link, zero axis,
    floating/planar joints.

    Parameters
    ----------
    {path_or_string, base_link, tip_link}
    markers : sequence, optional
        Markers on the tip link as ``(name, (x, y, z))`` or ``(name, (x, y, z), R)`` (default: one
        marker ``tool`` at its origin).

    Returns
    -------
    RobotModel
        The model in modified DH.
    """
    root, source = _load_xml(path_or_string)
    links, joints, extra = _parse_joints(root, source)
    chain = _chain(links, joints, extra["child_of"], base_link, tip_link, source)
    moving = _moving_joints(chain, source)
    readings, reading_of = _readings(moving, joints, source)
    walk = _walk(chain, reading_of)
    X_0B, X_0F = line_frames(walk.points, walk.axes, DEFAULT_PARALLEL_TOL)
    types = ["prismatic" if joints[jn].type == "prismatic" else "revolute" for jn in moving]
    couplings = [((reading_of[jn][0], reading_of[jn][1]),) for jn in moving]
    frames = frames_from_lines([joints[jn].child for jn in moving], types, couplings, X_0B, X_0F)
    tol, decimals = _source_angle_tol(root), _source_decimals(root)
    frames = _clean_frames(_with_masses(frames, walk, X_0F, extra["inertials"]), tol, decimals)
    tip = chain[-1].child
    X_nT = inverse4(X_0F[-1]) @ walk.X_link[tip]
    mk = []
    if markers is None:
        for mname, X_TM in _default_markers(chain, links, joints):
            position, rotation = _clean_pose(X_nT @ X_TM, decimals)
            mk.append(Marker(mname, len(frames) - 1, position, rotation))
    for mname, p, R in marker_placements(markers or [], "markers"):
        position, rotation = _clean_pose(X_nT @ pose4(R, p), 14)
        mk.append(Marker(mname, len(frames) - 1, position, rotation))
    limits = [(-math.pi, math.pi) if joints[jn].type == "continuous" else
              tuple(_clean(v, joints[jn].type == "revolute", tol) for v in joints[jn].limits or ())
              for jn in readings]  # a reading's limits are given (checked as the joints are read)
    base_position, base_rotation = _clean_pose(X_0B, decimals)
    model = RobotModel(
        name=root.get("name") or "robot", frames=tuple(frames), joint_names=tuple(readings),
        joint_limits=tuple((float(lo), float(hi)) for lo, hi in limits), markers=tuple(mk),
        base_position=base_position, base_rotation=base_rotation,
        description=f"imported from URDF {source}, {chain[0].parent} -> {tip}",
    )
    _refuse_unwritable(model, moving, chain, source)
    return model


def _refuse_unwritable(model: RobotModel, moving: list[str], chain, source: str) -> None:
    """An InputError naming the URDF joint (or links) behind a value of ``model`` that a model file
    cannot hold in the units it holds the largest numbers in: origins each within the bound that
    add up beyond it, masses summed onto a frame."""
    units = f"{FINEST['length']}-{FINEST['angle']}"
    try:
        model_from_dict(model_to_dict(model, units=units), source=source)
    except InputError as e:
        where = e.where or ""
        at = re.match(r"(frames|joints|markers)\[(\d+)\]", where)
        whose = f"link {chain[-1].child!r}" if at and at[1] == "markers" else \
            f"joint {(moving if at[1] == 'frames' else model.joint_names)[int(at[2])]!r}" if at else \
            f"link {chain[0].parent!r} to joint {moving[0]!r}" if where.startswith("base") else None
        raise InputError(f"the model it gives holds {e.where}, in {units}, beyond what a model file holds: {e.detail}",
                         source=source, where=whose) from None


# ----------------------------------------------------------------------------------------------
# URDF out

def _num(v: float) -> str:
    return repr(float(v) + 0.0)  # + 0.0 turns -0.0 into 0.0


def _origin(el: ET.Element, X: np.ndarray) -> None:
    ET.SubElement(el, "origin", xyz=" ".join(_num(v) for v in X[:3, 3]),
                  rpy=" ".join(_num(v) for v in matrix_rpy(X[:3, :3])))


def _primary_frames(model: RobotModel) -> dict[int, int]:
    """Reading -> the first frame it drives alone with coefficient 1 (the URDF joint named after it);
    InputError where URDF cannot say the coupling."""
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
    return primary


class _Names:
    """URDF keeps link names and joint names apart; each must be unique within its own kind."""

    def __init__(self, model: RobotModel, primary: dict[int, int]):
        self.used_links: set[str] = set()
        self.used_joints: set[str] = set()
        self.world, self.base = self.link("world"), self.link("base_link")
        self.frames = [self.link(f.name) for f in model.frames]
        self.markers = [self.link(m.name) for m in model.markers]
        self.joints = {i: self.joint(model.joint_names[k]) for k, i in primary.items()}
        for i, f in enumerate(model.frames):
            if i not in self.joints:
                self.joints[i] = self.joint(f"{f.name}_joint")

    @staticmethod
    def _unique(name: str, used: set[str]) -> str:
        out, k = name, 1
        while out in used:
            k += 1
            out = f"{name}_{k}"
        used.add(out)
        return out

    def link(self, name: str) -> str:
        return self._unique(name, self.used_links)

    def joint(self, name: str) -> str:
        return self._unique(name, self.used_joints)


def _link_element(robot: ET.Element, name: str, frame=None) -> None:
    el = ET.SubElement(robot, "link", name=name)
    if frame is not None and frame.mass > 0:
        iner = ET.SubElement(el, "inertial")
        ET.SubElement(iner, "origin", xyz=" ".join(_num(v) for v in frame.com), rpy="0 0 0")
        ET.SubElement(iner, "mass", value=_num(frame.mass))
        ET.SubElement(iner, "inertia", ixx="0", ixy="0", ixz="0", iyy="0", iyz="0", izz="0")


def _frame_joint(robot: ET.Element, model: RobotModel, i: int, names: _Names, primary: dict[int, int]) -> None:
    """The URDF joint of frame i: its constant MDH transform as origin, axis z, limits, mimic."""
    f = model.frames[i]
    jtype = f.joint
    k = f.coupling[0][0] if f.coupling else None
    lo, hi = model.joint_limits[k] if k is not None else (0.0, 0.0)
    mimic = k is not None and primary[k] != i
    if mimic:
        # a mimic follows coef * reading: its own range is the reading's, scaled
        c = f.coupling[0][1]
        lo, hi = sorted((c * lo, c * hi))
    if jtype == "revolute" and not (math.isfinite(lo) and math.isfinite(hi)):
        jtype = "continuous"
    elif jtype == "prismatic" and not (math.isfinite(lo) and math.isfinite(hi)):
        raise InputError("URDF needs finite limits for a prismatic joint", where=f"frames[{i}] ({f.name})")
    j = ET.SubElement(robot, "joint", name=names.joints[i], type=jtype)
    _origin(j, mdh_transform(f))
    ET.SubElement(j, "parent", link=names.base if f.parent < 0 else names.frames[f.parent])
    ET.SubElement(j, "child", link=names.frames[i])
    if jtype != "fixed":
        ET.SubElement(j, "axis", xyz="0 0 1")
    if jtype in ("revolute", "prismatic"):
        ET.SubElement(j, "limit", lower=_num(lo), upper=_num(hi), effort="0", velocity="0")
    if mimic and k is not None:
        ET.SubElement(j, "mimic", joint=names.joints[primary[k]], multiplier=_num(f.coupling[0][1]), offset="0")


@accepts(model=is_a(RobotModel))
def urdf_text(model: RobotModel) -> str:
    """``model`` as URDF text (serial chains and trees).

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

    Parameters
    ----------
    {model}

    Returns
    -------
    str
        The URDF text.
    """
    primary = _primary_frames(model)
    names = _Names(model, primary)
    robot = ET.Element("robot", name=model.name)
    for lk in (names.world, names.base):
        _link_element(robot, lk)
    for name, f in zip(names.frames, model.frames):
        _link_element(robot, name, f)
    for lk in names.markers:
        _link_element(robot, lk)
    j = ET.SubElement(robot, "joint", name=names.joint("world_to_base"), type="fixed")
    _origin(j, model.X_WB)
    ET.SubElement(j, "parent", link=names.world)
    ET.SubElement(j, "child", link=names.base)
    for i in range(len(model.frames)):
        _frame_joint(robot, model, i, names, primary)
    for m, mk in enumerate(model.markers):
        j = ET.SubElement(robot, "joint", name=names.joint(f"{mk.name}_joint"), type="fixed")
        _origin(j, pose4(np.asarray(mk.rotation, dtype=float), mk.position))
        ET.SubElement(j, "parent", link=names.frames[mk.frame])
        ET.SubElement(j, "child", link=names.markers[m])
    ET.indent(robot)
    return '<?xml version="1.0" encoding="utf-8"?>\n' + ET.tostring(robot, encoding="unicode") + "\n"


@accepts(model=is_a(RobotModel), path=PATH, force=FLAG)
def write_urdf(model: RobotModel, path, *, force: bool = False) -> None:
    """Write :func:`urdf_text` of ``model``, atomically.

    Parameters
    ----------
    {model, path, force}

    Returns
    -------
    None
    """
    write_texts({path: urdf_text(model)}, force=force)
