"""ABB RAPID modules: ``jointtarget`` and ``robtarget`` declarations (CONST, PERS, VAR, LOCAL, TASK,
arrays) and the targets written inline in motion instructions (``MoveAbsJ``, ``MoveJ``, ``MoveL``,
``MoveC``...); ``tooldata`` and ``wobjdata`` declarations as named frames.

A robtarget is ``[[x, y, z], [q1, q2, q3, q4], [cf1, cf4, cf6, cfx], [eax_a, ..., eax_f]]``: mm,
a unit quaternion w first, the quadrants of axes 1, 4 and 6 and the posture number; a jointtarget
``[[rax_1, ..., rax_6], [eax_a, ..., eax_f]]``: deg (mm for a linear axis). External axes are
never read nor changed.
"""

from __future__ import annotations

import math

import numpy as np

from .syntax import (
    Aggregate,
    NamedFrame,
    Number,
    Program,
    Scanner,
    Target,
    Use,
    aggregate,
    check_finite,
    closing,
    numbers,
)

NAME = "rapid"
EXTENSIONS = (".mod", ".modx", ".prg", ".sys", ".sysx")
COMMENT = "!"
LENGTH, ANGLE = 1e-3, math.pi / 180            # file units to SI
ORIENTATION = 1.0                              # a quaternion's components
JOINT_TARGET = "[[rax_1, ..., rax_6], [eax_a, ..., eax_f]]"
ROB_TARGET = "[[x, y, z], [q1, q2, q3, q4], [cf1, cf4, cf6, cfx], [eax_a, ..., eax_f]]"
SIZES = {"jointtarget": (6, 6), "robtarget": (3, 4, 4, 6)}      # the parts of each and their lengths
UNUSED = 9e9                                   # the value of an axis a target does not move
DECLARES = ("const", "pers", "var")
MOTION = ("move", "trigg", "search")           # instructions whose literal targets are read
TURN_JOINTS = (0, 3, 5)                         # cf1, cf4, cf6: quadrants of axes 1, 4 and 6
# the flange and the robot's base as the controller names them (wobj0 is the world frame, the base
# of a robot not configured elsewhere), and the functions a target keeps its frames through
BUILTIN = {"tool0": "tool", "wobj0": "wobj"}
FOLLOWED = ("offs", "reltool")
# arguments after the tool: MoveJDO, MoveLAO, MoveCGO... set a signal (name, value) at the point,
# MoveJSync... call a procedure
TRAILING = {"do": 2, "ao": 2, "go": 2, "sync": 1}


def read(text: str, source: str) -> Program:
    """The program's targets, named frames and the motions' uses of declared targets; a malformed
    module is an InputError at its line and column."""
    sc = Scanner(text, source, comment=COMMENT)
    toks = sc.tokens()
    targets: list[Target] = []
    frames: list[NamedFrame] = []
    uses: list[Use] = []
    i = 0
    while i < len(toks):
        k = i
        while k < len(toks) and toks[k].text != ";":
            k = closing(toks, k, sc) + 1 if toks[k].text in "([{" and toks[k].kind == "op" else k + 1
        _statement(toks, i, k, sc, targets, frames, uses)
        i = k + 1
    return Program(source=source, dialect=NAME, text=text, targets=tuple(targets), frames=tuple(frames),
                   uses=tuple(uses))


def key(name: str) -> str:
    """A name as RAPID compares it: without regard to case."""
    return name.lower()


def _statement(toks, i: int, end: int, sc, targets, frames, uses) -> None:
    """The targets or frames of the statement ``toks[i:end]`` (a declaration or a motion)."""
    for d in range(i, end - 3):
        if toks[d].kind == "name" and toks[d].text.lower() in DECLARES and toks[d + 1].kind == "name" \
                and toks[d + 2].kind == "name":
            _declaration(toks, d, end, sc, targets, frames)
            return
    for m in range(i, end):
        if toks[m].kind == "name" and toks[m].text.lower().startswith(MOTION):
            _motion(toks, m, end, sc, targets, uses)
            return


def _arguments(toks, j: int, end: int) -> list[tuple[list, list]]:
    """A motion's arguments: per comma at depth 0, its main tokens and its switches (``\\WObj:=w``)."""
    out: list[tuple[list, list]] = [([], [])]
    while j < end:
        t = toks[j]
        nxt = toks.partner[j] + 1 if t.kind == "op" and t.text in "([{" else j + 1
        if t.text == ",":
            out.append(([], []))
        elif t.text == "\\" or out[-1][1]:
            out[-1][1].extend(toks[j:nxt])
        else:
            out[-1][0].extend(range(j, nxt))
        j = nxt
    return out


def _frames(toks, args, instruction: str) -> tuple[str, str, str]:
    """The tool (the last positional argument, before those ``TRAILING`` gives the instruction) and
    work object (``\\WObj:=``, else ``wobj0``) a motion moves with, and why either is not known
    where it is an expression."""
    last = args[-1 - _trailing(instruction)][0] if len(args) > 1 + _trailing(instruction) else []
    tool = toks[last[0]].text if len(last) == 1 and toks[last[0]].kind == "name" else ""
    wobj, unknown = "wobj0", "" if tool else "its tool is not a name"
    for _, switches in args:
        for k in range(len(switches) - 3):
            if switches[k].text == "\\" and switches[k + 1].text.lower() == "wobj" and switches[k + 2].text == ":=":
                simple = switches[k + 3].kind == "name" and (k + 4 == len(switches) or switches[k + 4].text == "\\")
                wobj = switches[k + 3].text if simple else ""
                unknown = unknown or ("" if simple else "its work object is not a name")
    return tool, wobj, unknown


def _trailing(instruction: str) -> int:
    """How many arguments follow a motion's tool: MoveLDO's signal and value, MoveLSync's procedure."""
    name = instruction.lower()
    return next((n for end, n in TRAILING.items() if name.startswith(("movej", "movel", "movec")) and
                 name.endswith(end)), 0)


def _named(toks, main: list) -> list[tuple[str, str]]:
    """The declared targets a motion argument names (``p``, ``p{2}``; ``p{*}`` where the index is
    computed) and the function it goes through ("" for the target itself)."""
    how = toks[main[0]].text if len(main) > 1 and toks[main[0]].kind == "name" and toks[main[1]].text == "(" else ""
    out, j = [], 0
    while j < len(main):
        t = toks[main[j]]
        after = toks[main[j + 1]].text if j + 1 < len(main) else ""
        if t.kind != "name" or after == "(":
            j += 1
            continue
        if after == "{":
            close = main.index(toks.partner[main[j + 1]], j)
            index = [toks[k] for k in main[j + 2:close]]
            element = index[0].text if len(index) == 1 and index[0].kind == "num" else "*"
            out.append((f"{t.text}{{{element}}}", how))
            j = close + 1
        else:
            out.append((t.text, how))
            j += 1
    return out


def _motion(toks, m: int, end: int, sc, targets, uses) -> None:
    """The literal targets of a motion instruction, with the tool and work object it moves them
    with, and its uses of declared targets (by name, by index, through ``Offs`` or ``RelTool``)."""
    args = _arguments(toks, m + 1, end)
    tool, wobj, unknown = _frames(toks, args, toks[m].text)
    line = sc.line_col(toks[m].start)[0]
    for main, _ in args[:-1]:
        if not main:
            continue
        if toks[main[0]].text[:1] == "[":
            agg, _ = aggregate(toks, main[0], sc)
            _inline(agg, sc, targets, toks[m].start, tool=tool, wobj=wobj, unknown=unknown)
        else:
            uses.extend(Use(name, line, tool, wobj, how, unknown) for name, how in _named(toks, main))


def _declaration(toks, d: int, end: int, sc, targets, frames) -> None:
    kind, name, j = toks[d + 1].text.lower(), toks[d + 2].text, d + 3
    if kind not in ("jointtarget", "robtarget", "tooldata", "wobjdata"):
        return
    array = j < end and toks[j].text == "{"
    if array:
        j = closing(toks, j, sc) + 1
    if j + 1 >= end or toks[j].text != ":=" or toks[j + 1].text[:1] != "[":
        return                                   # declared without a literal value
    value, _ = aggregate(toks, j + 1, sc, name=name)
    if kind in ("tooldata", "wobjdata"):
        frames.append(_frame(kind, name, value, sc))
        return
    items = value.items if array else (value,)
    first = d
    while first > 0 and toks[first - 1].kind == "name" and toks[first - 1].text.lower() in ("local", "task"):
        first -= 1
    for n, item in enumerate(items, 1):
        label = f"{name}{{{n}}}" if array else name
        targets.append(_target(kind, label, item, sc, anchor=toks[first].start))


def _inline(agg: Aggregate, sc, targets, anchor: int, **frames) -> None:
    """A motion's bracketed argument shaped as a jointtarget or robtarget: a target, read only where
    something in it is computed (``[[Abs(x0), 10, 20], ...]``), as a declared one is."""
    line = sc.line_col(agg.start)[0]
    for kind in SIZES:
        if _shape(kind, agg, computed=True):
            targets.append(_target(kind, f"line {line}", agg, sc, anchor=anchor, **frames))


def _shape(kind: str, agg, *, computed: bool = False) -> bool:
    """Whether ``agg`` is a ``kind`` of literal numbers; with ``computed``, also one whose parts, or
    numbers in them, are expressions, provided a part of its size tells it from other data."""
    sizes = SIZES[kind]
    if not isinstance(agg, Aggregate) or len(agg.items) != len(sizes):
        return False
    if not computed:
        return all(numbers(a, n) is not None for a, n in zip(agg.items, sizes))
    parts = [isinstance(a, Aggregate) and len(a.items) == n for a, n in zip(agg.items, sizes)]
    return any(parts) and all(p or not isinstance(a, (Aggregate, Number)) for p, a in zip(parts, agg.items))


def _literal(agg) -> bool:
    """Whether every leaf of ``agg`` is a number (a value computed in RAPID is read, never changed)."""
    return all(_literal(x) if isinstance(x, Aggregate) else isinstance(x, Number) for x in agg.items)


def _target(kind: str, name: str, agg, sc, **where) -> Target:
    """The target of a jointtarget or robtarget literal; ``where``: its anchor, tool and work object."""
    line, column = sc.target_at(agg.start)
    if not _shape(kind, agg):
        if isinstance(agg, Aggregate) and _literal(agg):
            raise sc.error(agg.start, f"{name}: a {kind} is {JOINT_TARGET if kind == 'jointtarget' else ROB_TARGET}")
        return Target(name, "joint" if kind == "jointtarget" else "pose", line, column,
                      skip="not a literal value", **where)
    check_finite([n for part in agg.items[:1 if kind == "jointtarget" else 3] for n in part.items], sc, name)
    if kind == "jointtarget":
        robot = agg.items[0].items
        if all(n.value == UNUSED for n in robot):      # MoveExtJ's: it moves external axes only
            return Target(name, "joint", line, column, skip="its robot axes are 9E9 (not used)", **where)
        return Target(name, "joint", line, column, joints=robot, **where)
    quat = agg.items[1].items
    norm = math.hypot(*(n.value for n in quat))   # no overflow for a huge component
    if not 0.9 < norm < 1.1:
        raise sc.error(quat[0].start, f"{name}: the quaternion's norm is {norm:.3g}, not 1")
    conf = agg.items[2].items
    for c in conf:
        if c.value != int(c.value) or not (0 <= c.value <= 7 or c is not conf[3]):
            raise sc.error(c.start, f"{name}: configuration data are whole numbers, cfx 0 to 7; got {c.text}")
    return Target(name, "pose", line, column, position=agg.items[0].items, orientation=agg.items[1].items,
                  configuration=conf, **where)


def _pose(pos, quat, sc, name) -> np.ndarray:
    w, x, y, z = (n.value for n in quat)
    norm = math.hypot(w, x, y, z)
    if not 0.9 < norm < 1.1:
        raise sc.error(quat[0].start, f"{name}: the quaternion's norm is {norm:.3g}, not 1")
    X = np.eye(4)
    X[:3, :3] = quaternion_matrix(np.array([w, x, y, z]) / norm)
    X[:3, 3] = [n.value * LENGTH for n in pos]
    return X


def _frame(kind, name, value, sc) -> NamedFrame:
    """A tooldata's tool frame (in the flange) or a wobjdata's user frame times object frame (in the base)."""
    at, count = (1, 1) if kind == "tooldata" else (3, 2)
    parts = value.items[at:at + count]
    X = np.eye(4)
    if len(parts) != count:
        raise sc.error(value.start, f"{name}: a {kind} has {at + count} parts or more, this one {len(value.items)}")
    for part in parts:
        if not (isinstance(part, Aggregate) and len(part.items) == 2 and numbers(part.items[0], 3)
                and numbers(part.items[1], 4)):
            raise sc.error(value.start, f"{name}: a {kind} frame is [[x, y, z], [q1, q2, q3, q4]]")
        X = X @ _pose(part.items[0].items, part.items[1].items, sc, name)
    held = value.items[0]
    robot_holds = hasattr(held, "text") and held.text.upper() == "TRUE"
    fixed = kind == "tooldata" or (len(value.items) > 1 and getattr(value.items[1], "text", "").upper() == "TRUE")
    if robot_holds != (kind == "tooldata") or not fixed:
        kind = "stationary " + kind if kind == "tooldata" else "moving " + kind   # not one robocal can use
    return NamedFrame(name, "tool" if kind == "tooldata" else ("wobj" if kind == "wobjdata" else kind), X)


def quaternion_matrix(wxyz) -> np.ndarray:
    """The rotation matrix of a unit quaternion (w, x, y, z)."""
    w, x, y, z = wxyz
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


# -- the compensation's view: SI poses, configurations, and new values --------------------------------

def poses(targets) -> np.ndarray:
    """(N, 4, 4) X (SI) of pose targets in their work object."""
    v = np.array([[n.value for n in (*t.position, *t.orientation)] for t in targets]).reshape(-1, 7)
    q = v[:, 3:] / np.linalg.norm(v[:, 3:], axis=1, keepdims=True)
    X = np.tile(np.eye(4), (len(v), 1, 1))
    X[:, :3, :3] = quaternion_matrix(q.T).transpose(2, 0, 1) if len(v) else X[:, :3, :3]
    X[:, :3, 3] = v[:, :3] * LENGTH
    return X


def orientation_values(R: np.ndarray, targets) -> np.ndarray:
    """(N, 4) quaternions (w first) of rotations ``R`` (N, 3, 3), each on the side of the sphere of
    its target's own."""
    from scipy.spatial.transform import Rotation

    q = Rotation.from_matrix(R).as_quat()[:, [3, 0, 1, 2]]
    old = np.array([[n.value for n in t.orientation] for t in targets]).reshape(-1, 4)
    return np.where(np.einsum("ni,ni->n", q, old)[:, None] < 0, -q, q)


def wanted(target: Target, n_joints: int) -> tuple[np.ndarray, np.ndarray]:
    """Posture bits (3,) and turn windows (n_joints,) that the target's configuration data ask for."""
    cf1, cf4, cf6, cfx = (int(n.value) for n in target.configuration)
    turn = np.full(n_joints, np.nan)
    for j, cf in zip(TURN_JOINTS, (cf1, cf4, cf6)):
        if j < n_joints:
            turn[j] = (cf + 0.5) * math.pi / 2 - math.pi
    return np.array([(cfx >> 2) & 1, (cfx >> 1) & 1, cfx & 1]), turn


def configuration_values(q: np.ndarray, bits: np.ndarray, target: Target, slack: float) -> list[int]:
    """cf1, cf4, cf6 and cfx of readings ``q`` (SI) with posture ``bits``; a quadrant stays as it was
    while its axis is within ``slack`` (rad) of it."""
    out = []
    for j, old in zip(TURN_JOINTS, target.configuration[:3]):
        cf = int(old.value)
        inside = j >= len(q) or cf * math.pi / 2 - slack <= q[j] <= (cf + 1) * math.pi / 2 + slack
        out.append(cf if inside else int(math.floor(q[j] / (math.pi / 2))))
    return out + [int(4 * bits[0] + 2 * bits[1] + bits[2])]
