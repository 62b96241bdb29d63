"""Universal Robots URScript: the targets of ``movej``, ``movel``, ``movep``, ``movec`` and
``servoj``, written inline or as variables assigned a literal (``global``/``local`` or not);
every variable assigned a pose literal is a named frame (for a tool or a feature).

A joint target is a list of six numbers, rad; a pose ``p[x, y, z, rx, ry, rz]``, m and a rotation
vector, rad. URScript has no configuration data: the controller takes the solution nearest its
current joints, so a pose target is solved nearest the program's preceding joint target.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from .syntax import Aggregate, NamedFrame, Program, Scanner, Target, aggregate, check_finite, closing, numbers

NAME = "urscript"
EXTENSIONS = (".script", ".urscript")
COMMENT = "#"
LENGTH, ANGLE = 1.0, 1.0
ORIENTATION = ANGLE
MOTION = ("movej", "movel", "movep", "movec", "servoj")


def read(text: str, source: str) -> Program:
    """The program's targets and named frames; a malformed script is an InputError at its line and column."""
    sc = Scanner(text, source, comment=COMMENT, quotes="\"'")
    literals, targets, used = _walk(sc.tokens(), sc)
    frames = []
    for name, agg, anchor in literals:
        line = sc.line_col(agg.start)[0]
        if agg.label == "p" and numbers(agg, 6) is not None and all(math.isfinite(n.value) for n in agg.items):
            frames.append(NamedFrame(name, "frame", _pose_matrix([n.value for n in agg.items])[0]))
        if name in used:
            targets.append(replace(_target(f"{name} (line {line})", agg, sc), anchor=anchor))
    targets.sort(key=lambda t: (t.line, t.column))
    return Program(source=source, dialect=NAME, text=text, targets=tuple(targets), frames=tuple(frames))


def _walk(toks, sc) -> tuple[list, list[Target], set[str]]:
    """One pass over the tokens: the variables assigned a literal (name, literal, where the
    assignment begins), the targets written in motions and the names of variables motions use."""
    literals: list = []
    moved: list[Target] = []
    used: set[str] = set()
    j = 0
    while j < len(toks):
        t = toks[j]
        after = toks[j + 1].text if j + 1 < len(toks) else ""
        found = _literal(toks, j + 2, len(toks), sc) if t.kind == "name" and after == "=" else None
        if found is not None:
            anchor = toks[j - 1].start if j and toks[j - 1].text in ("global", "local") else t.start
            literals.append((t.text, found[0], anchor))
            j = found[1]
        elif t.kind == "name" and t.text.lower() in MOTION and after == "(":
            end = closing(toks, j + 1, sc)
            moved.extend(replace(t_, anchor=t.start) for t_ in _arguments(toks, j + 2, end, sc, used))
            j = end + 1
        else:
            j = closing(toks, j, sc) + 1 if t.text in "([{" else j + 1
    return literals, moved, used


def _literal(toks, k: int, end: int, sc) -> tuple[Aggregate, int] | None:
    """The list ``[...]`` or pose ``p[...]`` written at token ``k`` (of the tokens before ``end``) and
    the token after it; None where none begins there."""
    if k >= end:
        return None
    is_pose = toks[k].text == "p" and k + 1 < end and toks[k + 1].text[:1] == "["
    if not is_pose and toks[k].text[:1] != "[":
        return None
    agg, after = aggregate(toks, k + is_pose, sc)
    return Aggregate(agg.items, toks[k].start, agg.end, "p" if is_pose else ""), after


def _arguments(toks, j, end, sc, used):
    """Targets among a motion's arguments (literals) and the names of variables it uses."""
    out = []
    while j < end:
        t = toks[j]
        found = _literal(toks, j, end, sc)
        if found is not None:
            agg, j = found
            out.append(_target(f"line {sc.line_col(agg.start)[0]}", agg, sc))
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
    check_finite(values, sc, name)
    if kind == "joint":
        return Target(name, kind, line, column, joints=values)
    return Target(name, kind, line, column, position=values[:3], orientation=values[3:])


def _pose_matrix(v) -> np.ndarray:
    """(N, 4, 4) X of poses ``v`` (N, 6): x, y, z and a rotation vector."""
    from scipy.spatial.transform import Rotation

    v = np.asarray(v, dtype=float).reshape(-1, 6)
    X = np.tile(np.eye(4), (len(v), 1, 1))
    if len(v):
        X[:, :3, :3] = Rotation.from_rotvec(v[:, 3:]).as_matrix()
    X[:, :3, 3] = v[:, :3]
    return X


# -- the compensation's view ----------------------------------------------------------------------------

def poses(targets) -> np.ndarray:
    """(N, 4, 4) X (SI) of pose targets in the base frame."""
    return _pose_matrix([[n.value for n in (*t.position, *t.orientation)] for t in targets])


def orientation_values(R: np.ndarray, targets) -> np.ndarray:
    """(N, 3) rotation vectors of rotations ``R`` (N, 3, 3): of the two that turn less than a turn,
    the one nearest the target's own."""
    from scipy.spatial.transform import Rotation

    r = Rotation.from_matrix(R).as_rotvec()
    old = np.array([[n.value for n in t.orientation] for t in targets]).reshape(-1, 3)
    angle = np.linalg.norm(r, axis=1, keepdims=True)
    other = r * (1 - 2 * math.pi / np.maximum(angle, 1e-300))
    closer = (angle[:, 0] > 1e-12) & (np.linalg.norm(other - old, axis=1) < np.linalg.norm(r - old, axis=1))
    return np.where(closer[:, None], other, r)


def wanted(target: Target, n_joints: int):
    return np.full(3, -1), np.full(n_joints, np.nan)


def configuration_values(q, bits, target, slack) -> list[int]:
    return []
