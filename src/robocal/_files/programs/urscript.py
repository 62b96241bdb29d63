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

from .frames import THROUGH
from .syntax import (
    Aggregate,
    NamedFrame,
    Program,
    Scanner,
    Target,
    Use,
    aggregate,
    check_finite,
    closing,
    numbers,
)

NAME = "urscript"
EXTENSIONS = (".script", ".urscript")
COMMENT = "#"
LENGTH, ANGLE = 1.0, 1.0
ORIENTATION = ANGLE
MOTION = ("movej", "movel", "movep", "movec", "servoj")
# a pose in a motion is in the robot's base frame; no expression keeps a target's frames (a
# feature's pose_trans and an offset's pose_add look alike)
BASE = "robot base"
BUILTIN = {BASE: "wobj"}
FOLLOWED: tuple[str, ...] = ()


def read(text: str, source: str) -> Program:
    """The program's targets, named frames and the motions' uses of variables, with the TCP each
    motion moves with (the last ``set_tcp`` before it in the text); a malformed script is an
    InputError at its line and column."""
    sc = Scanner(text, source, comment=COMMENT, quotes="\"'")
    walk = _Walk(sc)
    walk.run(sc.tokens())
    frames = list(walk.frames)
    for name, agg, _ in walk.literals:
        if agg.label == "p" and numbers(agg, 6) is not None and all(math.isfinite(n.value) for n in agg.items):
            frames.append(NamedFrame(name, "frame", _pose_matrix([n.value for n in agg.items])[0]))
    used = {u.name for u in walk.uses}
    lines: dict[str, list[int]] = {}
    for name, agg, _ in walk.literals:
        lines.setdefault(name, []).append(sc.line_col(agg.start)[0])
    targets = list(walk.moved)
    for name, agg, anchor in walk.literals:
        if name in used:
            label = _label(name, sc.line_col(agg.start)[0], lines)
            targets.append(replace(_target(label, agg, sc), anchor=anchor))
    targets.sort(key=lambda t: (t.line, t.column))
    # the uses under the names the variables' targets get
    uses = [replace(u, name=_label(u.name, n, lines)) for u in walk.uses for n in lines.get(u.name, ())]
    return Program(source=source, dialect=NAME, text=text, targets=tuple(targets), frames=tuple(frames),
                   uses=tuple(uses))


def _label(name: str, line: int, lines: dict) -> str:
    """A variable's target: its declared name; one assigned more than once, each with its line
    (``approach (line 5)``)."""
    return name if len(lines[name]) == 1 else f"{name} (line {line})"


def key(name: str) -> str:
    """A name as URScript compares it: as written."""
    return name


class _Walk:
    """One pass over a script's tokens: the variables assigned a literal (name, literal, where the
    assignment begins), the targets written in motions, the motions' uses of variables and the
    TCP in force (``set_tcp``; "" with ``unknown`` saying why before any)."""

    def __init__(self, sc):
        self.sc = sc
        self.literals: list = []
        self.moved: list[Target] = []
        self.uses: list[Use] = []
        self.frames: list[NamedFrame] = []
        self.tool, self.unknown = "", "no set_tcp before it: its TCP is the installation's"

    def run(self, toks) -> None:
        j = 0
        while j < len(toks):
            t = toks[j]
            after = toks[j + 1].text if j + 1 < len(toks) else ""
            found = _literal(toks, j + 2, len(toks), self.sc, t.text) if t.kind == "name" and after == "=" else None
            if found is not None:
                anchor = toks[j - 1].start if j and toks[j - 1].text in ("global", "local") else t.start
                self.literals.append((t.text, found[0], anchor))
                j = found[1]
            elif t.kind == "name" and after == "(" and t.text in ("set_tcp",) + MOTION:
                end = closing(toks, j + 1, self.sc)
                self._call(toks, j, end)
                j = end + 1
            else:
                j = closing(toks, j, self.sc) + 1 if t.text in "([{" else j + 1

    def _call(self, toks, j: int, end: int) -> None:
        line = self.sc.line_col(toks[j].start)[0]
        if toks[j].text == "set_tcp":
            self._tcp(toks, j + 2, end, line)
            return
        for a, b in _spans(toks, j + 2, end):
            self._argument(toks, a, b, line, anchor=toks[j].start)

    def _tcp(self, toks, a: int, b: int, line: int) -> None:
        found = _literal(toks, a, b, self.sc)
        self.tool, self.unknown = "", f"set_tcp is given an expression at line {line}"
        if found is not None and found[1] == b and found[0].label == "p" and numbers(found[0], 6) is not None:
            self.tool, self.unknown = f"set_tcp (line {line})", ""
            self.frames.append(NamedFrame(self.tool, "tool", _pose_matrix([n.value for n in found[0].items])[0]))
        elif b == a + 1 and toks[a].kind == "name":
            self.tool, self.unknown = toks[a].text, ""

    def _argument(self, toks, a: int, b: int, line: int, anchor: int) -> None:
        """One argument of a motion: a literal (a target), a variable, or an expression whose
        variables and literals are listed as reached only through it."""
        frames = dict(tool=self.tool, wobj=BASE, unknown=self.unknown)
        found = _literal(toks, a, b, self.sc)
        if found is not None and found[1] == b:
            self.moved.append(replace(_target(f"line {line}", found[0], self.sc), anchor=anchor, **frames))
        elif b == a + 1 and toks[a].kind == "name":
            self.uses.append(Use(toks[a].text, line, self.tool, BASE, "", self.unknown))
        elif toks[a].kind == "name" and a + 1 < b and toks[a + 1].text == "(":
            how = toks[a].text
            for k in range(a + 2, b):
                inner = _literal(toks, k, b, self.sc)
                if inner is not None and (toks[k - 1].text in ",(" or toks[k].text == "p" and toks[k - 1].text != "p"):
                    t = _target(f"line {line}", inner[0], self.sc)
                    self.moved.append(replace(t, anchor=anchor, unknown=f"{THROUGH} {how} (line {line})"))
                elif toks[k].kind == "name" and toks[k + 1].text in ",)" and toks[k - 1].text in ",(":
                    self.uses.append(Use(toks[k].text, line, self.tool, BASE, how, self.unknown))


def _spans(toks, j: int, end: int) -> list[tuple[int, int]]:
    """The token spans of a call's arguments (``a=1.4`` keyword arguments left out)."""
    out, start = [], j
    while j <= end:
        if j == end or toks[j].text == ",":
            if j > start and not (j > start + 1 and toks[start + 1].text == "="):
                out.append((start, j))
            start = j + 1
            j += 1
        else:
            j = toks.partner[j] + 1 if toks[j].text in "([{" and toks.partner[j] > j else j + 1
    return out


def _literal(toks, k: int, end: int, sc, name: str = "") -> tuple[Aggregate, int] | None:
    """The list ``[...]`` or pose ``p[...]`` written at token ``k`` (of the tokens before ``end``; the
    value of the variable ``name``, if one) and the token after it; None where none begins there."""
    if k >= end:
        return None
    is_pose = toks[k].text == "p" and k + 1 < end and toks[k + 1].text[:1] == "["
    if not is_pose and toks[k].text[:1] != "[":
        return None
    agg, after = aggregate(toks, k + is_pose, sc, name=name)
    return Aggregate(agg.items, toks[k].start, agg.end, "p" if is_pose else ""), after


def _target(name: str, agg: Aggregate, sc) -> Target:
    line, column = sc.target_at(agg.start)
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
