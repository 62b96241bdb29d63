"""Universal Robots URScript: the targets of ``movej``, ``movel``, ``movep``, ``movec`` and
``servoj``, written inline or as variables assigned a literal (``global``/``local`` or not);
every variable assigned a pose literal is a named frame (for a tool or a feature).

A joint target is a list of six numbers, rad; a pose ``p[x, y, z, rx, ry, rz]``, m and a rotation
vector, rad. URScript has no configuration data: the controller takes the solution nearest its
current joints, so a pose target is solved nearest the program's preceding joint target.
"""

from __future__ import annotations

import math

import numpy as np

from .syntax import Aggregate, NamedFrame, Number, Program, Scanner, Target, aggregate, closing, numbers

NAME = "urscript"
EXTENSIONS = (".script", ".urscript")
COMMENT = "#"
LENGTH, ANGLE = 1.0, 1.0
ORIENTATION = ANGLE
MOTION = ("movej", "movel", "movep", "movec", "servoj")


def read(text: str, source: str) -> Program:
    """The program's targets and named frames; a malformed script is an InputError at its line and column."""
    sc = Scanner(text, source, comment=COMMENT, quotes="\"'")
    toks = sc.tokens()
    literals, moved, used, j = [], [], set(), 0
    while j < len(toks):
        t = toks[j]
        if t.text in ")]}":
            raise sc.error(t.start, f"{t.text} closes nothing opened here")
        after = toks[j + 1].text if j + 1 < len(toks) else ""
        if t.kind == "name" and after == "=" and j + 2 < len(toks):
            is_pose = toks[j + 2].text == "p" and j + 3 < len(toks) and toks[j + 3].text == "["
            if is_pose or toks[j + 2].text == "[":
                start = toks[j + 2].start
                agg, j = aggregate(toks, j + 2 + is_pose, sc)
                literals.append((t.text, Aggregate(agg.items, start, agg.end, "p" if is_pose else "")))
                continue
        if t.kind == "name" and t.text.lower() in MOTION and after == "(":
            end = closing(toks, j + 1, sc)
            moved.extend(_arguments(toks, j + 2, end, sc, used))
            j = end + 1
            continue
        j = closing(toks, j, sc) + 1 if t.text in "([{" else j + 1
    targets = list(moved)
    frames = []
    for name, agg in literals:
        line = sc.line_col(agg.start)[0]
        if agg.label == "p" and numbers(agg, 6) is not None:
            frames.append(NamedFrame(name, "frame", _pose_matrix([n.value for n in agg.items])))
        if name in used:
            targets.append(_target(f"{name} (line {line})", agg, sc))
    targets.sort(key=lambda t: (t.line, t.column))
    return Program(source=source, dialect=NAME, text=text, targets=tuple(targets), frames=tuple(frames))


def _arguments(toks, j, end, sc, used):
    """Targets among a motion's arguments (literals) and the names of variables it uses."""
    out = []
    while j < end:
        t = toks[j]
        if t.text == "p" and j + 1 < end and toks[j + 1].text == "[" or t.text == "[":
            k = j + (t.text == "p")
            agg, j = aggregate(toks, k, sc)
            agg = Aggregate(agg.items, t.start, agg.end, "p" if t.text == "p" else "")
            line = sc.line_col(t.start)[0]
            out.append(_target(f"line {line}", agg, sc))
            continue
        if t.kind == "name" and (j + 1 >= end or toks[j + 1].text == ","):
            used.add(t.text)
        j = closing(toks, j, sc) + 1 if t.text in "([{" else j + 1
    return out


def _target(name: str, agg: Aggregate, sc) -> Target:
    line, column = sc.line_col(agg.start)
    values = numbers(agg, 6)
    kind = "pose" if agg.label == "p" else "joint"
    if values is None:
        return Target(name, kind, line, column, skip="not six literal numbers")
    if kind == "joint":
        return Target(name, kind, line, column, joints=values)
    return Target(name, kind, line, column, position=values[:3], orientation=values[3:])


def _pose_matrix(v) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    X = np.eye(4)
    X[:3, :3] = Rotation.from_rotvec(v[3:]).as_matrix()
    X[:3, 3] = v[:3]
    return X


# -- the compensation's view ----------------------------------------------------------------------------

def pose(target: Target) -> np.ndarray:
    """X (4x4, SI) of a pose target in the base frame."""
    return _pose_matrix([n.value for n in target.position + target.orientation])


def orientation_values(R: np.ndarray, target: Target) -> list[float]:
    """The rotation vector of ``R``: of the two that turn less than a turn, the one nearest the target's own."""
    from scipy.spatial.transform import Rotation

    r = Rotation.from_matrix(R).as_rotvec()
    old = np.array([n.value for n in target.orientation])
    angle = np.linalg.norm(r)
    if angle > 1e-12:
        other = r * (1 - 2 * math.pi / angle)
        if np.linalg.norm(other - old) < np.linalg.norm(r - old):
            r = other
    return list(r)


def wanted(target: Target, n_joints: int):
    return np.full(3, -1), np.full(n_joints, np.nan)


def configuration_values(q, bits, target, slack) -> list[int]:
    return []


def format_configuration(value: int, old: Number) -> str:
    return old.text
