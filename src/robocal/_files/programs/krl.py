"""KUKA KRL programs: ``.dat`` declarations (``E6POS``, ``POS``, ``FRAME``, ``E6AXIS``, ``AXIS``,
with or without ``DECL`` and ``GLOBAL``), ``TOOL_DATA[n]``/``BASE_DATA[n]`` assignments as named
frames, and the targets written inline in ``.src`` motions (``PTP``, ``LIN``, ``CIRC``, ``SPTP``, ``SPL``,
``SLIN``, ``SCIRC``).

A Cartesian target is ``{X, Y, Z, A, B, C, S, T, E1...}``: mm, deg with R = Rz(A) Ry(B) Rx(C), the
Status and Turn bits; an axis target ``{A1, ..., A6, E1...}``: deg (mm for a linear axis). External
axes (E1...) and any other member are never changed. A structure is written on one line.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from .syntax import (
    SLACK,
    Aggregate,
    Field,
    NamedFrame,
    Number,
    Program,
    Scanner,
    Target,
    Token,
    Use,
    aggregate,
    check_finite,
)

NAME = "krl"
EXTENSIONS = (".src", ".dat", ".sub")
COMMENT = ";"
LENGTH, ANGLE = 1e-3, math.pi / 180
ORIENTATION = ANGLE
POSES, AXES = ("E6POS", "POS", "FRAME"), ("E6AXIS", "AXIS")
MOTION = ("PTP", "LIN", "CIRC", "SPTP", "SPL", "SLIN", "SCIRC")
RELATIVE = tuple(f"{m}_REL" for m in MOTION)
CARTESIAN, JOINTS = ("X", "Y", "Z", "A", "B", "C"), tuple(f"A{i}" for i in range(1, 7))
# the flange and the robot's base ($ROBROOT taken as the world, a robot not configured elsewhere);
# no expression keeps a target's frames
BUILTIN = {"$NULLFRAME": "frame"}
FOLLOWED: tuple[str, ...] = ()
# where the controller keeps the frames a program names by number (what a flag says when they are missing)
DECLARED_IN = {k: f" ({k}[n] live in the controller's $config.dat: read it with the program)"
               for k in ("TOOL_DATA", "BASE_DATA")}


def read(text: str, source: str) -> Program:
    """The program's targets, named frames and the motions' uses of declared targets, with the tool
    and base each motion moves with (``$TOOL``/``$BASE``, an FDAT's ``TOOL_NO``/``BASE_NO``, in the
    order of the text); a malformed line is an InputError at its line and column."""
    sc = Scanner(text, source, comment=COMMENT, quotes="\"'", newlines=True, names=r"[A-Za-z_$][A-Za-z0-9_$]*",
                 flat=False)
    toks = sc.tokens()
    state = _State([], [], [], [])
    a = 0
    for b in [i for i, t in enumerate(toks) if t.kind == "nl"] + [len(toks)]:
        if b > a:
            _line(toks.part(a, b), sc, state)
        a = b + 1
    return Program(source=source, dialect=NAME, text=text, targets=tuple(state.targets), frames=tuple(state.frames),
                   uses=tuple(state.uses), relative=tuple(state.relative))


def key(name: str) -> str:
    """A name as KRL compares it: without regard to case."""
    return name.upper()


@dataclass
class _State:
    """What the lines read so far made: targets, frames, uses, relative motions, and the tool and base
    in force ("" with ``unknown`` saying why where the program has not set them)."""

    targets: list
    frames: list
    uses: list
    relative: list
    tool: str = ""
    base: str = ""
    unknown: str = "no $TOOL and $BASE set before it"
    fdat: str = ""


def _balanced(toks, sc) -> None:
    """Every bracket closed on its own line (KRL has no continuation lines)."""
    for t, p in zip(toks, toks.partner):
        if p < 0 and t.kind == "op" and t.text in "([{":
            raise sc.error(t.start, f"{t.text} is not closed on its line")


def _line(toks, sc, state: _State) -> None:
    _balanced(toks, sc)
    words = [t.text.upper() for t in toks]
    if _declaration(toks, words, sc, state.targets, state.frames) or _frame_data(toks, words, sc, state.frames) \
            or _fdat(toks, words, state.frames):
        return
    line = sc.line_col(toks[0].start)[0]
    if len(words) > 2 and words[0] in ("$TOOL", "$BASE") and words[1] == "=":
        _set(state, words[0], _literal_frame(toks, words, sc, state.frames, line) or
             _frame_name(toks[2:], words[0]), line)
    elif len(words) > 2 and words[0] == "FDAT_ACT" and words[1] == "=":
        state.fdat = toks[2].text if len(toks) == 3 else ""
    elif len(words) > 5 and words[:3] == ["BAS", "(", "#"]:
        _bas(words, state, line)
    elif words[0] in MOTION:
        _motion(toks, words, sc, state, line)
    elif words[0] in RELATIVE:
        state.relative.append((words[0], line))


def _frame_name(toks, variable: str) -> str:
    """The frame an assignment to ``$TOOL`` or ``$BASE`` names (``TOOL_DATA[1]``, ``$NULLFRAME``, a
    FRAME variable; ``STOOL2(FP1)``, ``SBASE(FP1.BASE_NO)`` through an FDAT), "" for an expression."""
    text = "".join(t.text for t in toks)
    member = "TOOL_NO" if variable == "$TOOL" else "BASE_NO"
    call = re.fullmatch(r"(?i)(?:STOOL2|SBASE)\((\w+)(?:\.\w+)?\)", text)
    if call:
        return f"{call.group(1)}.{member}"
    return text if re.fullmatch(r"(?i)\$?\w+(?:\[\d+\])?", text) else ""


def _literal_frame(toks, words: list[str], sc, frames, line: int) -> str:
    """``$TOOL = {X 50, Y 0, ...}`` (or ``$BASE``): the frame written there, named by the variable and
    the line; "" where the value is not a literal frame."""
    if words[2] != "{" or toks.partner[2] != len(toks) - 1:
        return ""
    name = f"{words[0]} (line {line})"
    target = _target(name, "FRAME", aggregate(toks, 2, sc, name=name)[0], sc)
    if target.skip:
        return ""
    frames.append(NamedFrame(name, "tool" if words[0] == "$TOOL" else "wobj", poses([target])[0]))
    return name


def _set(state: _State, variable: str, name: str, line: int) -> None:
    if variable == "$TOOL":
        state.tool = name
    else:
        state.base = name
    if not name:
        state.unknown = f"{variable} is set by an expression at line {line}"
    elif state.tool and state.base:
        state.unknown = ""
    elif not state.unknown.startswith("$"):
        state.unknown = f"no {'$BASE' if state.tool else '$TOOL'} set before it"


def _bas(words: list[str], state: _State, line: int) -> None:
    """``BAS(#PTP_PARAMS, ...)`` and ``BAS(#CP_PARAMS, ...)`` set the tool and base of ``FDAT_ACT``;
    ``BAS(#TOOL, n)`` and ``BAS(#BASE, n)`` those of number n."""
    if words[3] in ("PTP_PARAMS", "CP_PARAMS") and state.fdat:
        _set(state, "$TOOL", f"{state.fdat}.TOOL_NO", line)
        _set(state, "$BASE", f"{state.fdat}.BASE_NO", line)
    elif words[3] in ("TOOL", "BASE") and words[4] == "," and words[5].isdigit():
        n = int(words[5])
        _set(state, f"${words[3]}", f"{words[3]}_DATA[{n}]" if n else "$NULLFRAME", line)


def _fdat(toks, words: list[str], frames) -> bool:
    """``DECL FDAT F={TOOL_NO n, BASE_NO m, IPO_FRAME #BASE, ...}``: ``F.TOOL_NO`` and ``F.BASE_NO``
    as names of ``TOOL_DATA[n]`` and ``BASE_DATA[m]`` (0: the flange, the robot's base); with
    ``IPO_FRAME #TCP`` the robot holds the work piece, a set-up robocal does not solve."""
    k = next((i for i, w in enumerate(words) if w == "FDAT"), -1)
    if k < 0 or k + 2 >= len(toks) or words[k + 2] != "=":
        return False
    name, found = toks[k + 1].text, dict[str, object]()
    for i in range(k + 3, len(words) - 1):
        if words[i] in ("TOOL_NO", "BASE_NO") and toks[i + 1].kind == "num":
            found[words[i]] = int(float(toks[i + 1].text))
        elif words[i] == "IPO_FRAME" and i + 2 < len(words):
            found[words[i]] = words[i + 2]
    for member, array in (("TOOL_NO", "TOOL_DATA"), ("BASE_NO", "BASE_DATA")):
        if found.get("IPO_FRAME") == "TCP":
            frames.append(NamedFrame(f"{name}.{member}", "frame of a robot-held work piece (IPO_FRAME #TCP)",
                                     np.eye(4)))
        elif member in found:
            n = found[member]
            frames.append(NamedFrame(f"{name}.{member}", "", np.eye(4), alias=f"{array}[{n}]" if n else "$NULLFRAME"))
    return True


def _motion(toks, words: list[str], sc, state: _State, line: int) -> None:
    """A motion: its inline targets and its uses of declared targets, with the tool and base in
    force (or those its ``WITH $TOOL = ..., $BASE = ...`` gives it)."""
    tool, base, unknown = state.tool, state.base, state.unknown
    end = words.index("WITH") if "WITH" in words else len(words)
    if end < len(words):
        tool, base, unknown = _with(toks, words, end, (tool, base, unknown))
    for a, b in _arguments(toks, words, 1, end):
        if toks[a].text == "{":
            agg, _ = aggregate(toks, a, sc)
            state.targets.append(_target(f"line {line}", "", agg, sc, tool=tool, wobj=base, unknown=unknown))
        elif toks[a].kind == "name":
            names = [t.text for t in toks[a:b] if t.kind == "name"]
            how = "" if b - a == 1 else "".join(t.text for t in toks[a:b])
            state.uses.extend(Use(n, line, tool, base, how, unknown) for n in names)


APPROXIMATION = ("C_DIS", "C_PTP", "C_ORI", "C_VEL", "C_SPL", "CA")


def _arguments(toks, words: list[str], j: int, end: int) -> list[tuple[int, int]]:
    """The spans of a motion's target arguments (split at commas; approximation words ended)."""
    out, start = [], j
    while j < end:
        if words[j] in APPROXIMATION:
            break
        if toks[j].text == ",":
            out.append((start, j))
            start = j + 1
        j = toks.partner[j] + 1 if toks[j].text in "([{" and toks.partner[j] > j else j + 1
    if j > start:
        out.append((start, j))
    return [(a, b) for a, b in out if b > a]


def _with(toks, words: list[str], at: int, current) -> tuple[str, str, str]:
    """The tool, base and why either is unknown, after a motion's ``WITH`` list."""
    tool, base, unknown = current
    for a, b in _arguments(toks, words, at + 1, len(words)):
        if b - a > 2 and words[a] in ("$TOOL", "$BASE") and words[a + 1] == "=":
            name = _frame_name(toks[a + 2:b], words[a])
            tool, base = (name, base) if words[a] == "$TOOL" else (tool, name)
            if not name:
                return tool, base, f"its {words[a]} is an expression"
    return tool, base, "" if tool and base else unknown


def _declaration(toks, words: list[str], sc, targets, frames) -> bool:
    """``[DECL] [GLOBAL] [CONST] TYPE NAME = {...}`` of a position or axis type: its target (a FRAME
    is a named frame, not a target); whether the line is one."""
    k = 0
    while k < len(words) and words[k] in ("DECL", "GLOBAL", "CONST"):
        k += 1
    if not (k + 3 < len(toks) and words[k] in POSES + AXES and toks[k + 1].kind == "name" and words[k + 2] == "="
            and words[k + 3] == "{"):
        return False
    agg, _ = aggregate(toks, k + 3, sc, name=toks[k + 1].text)
    target = _target(toks[k + 1].text, words[k], agg, sc)
    if words[k] != "FRAME":
        targets.append(target)
    elif not target.skip:           # a frame (a base, an offset), never a motion target
        frames.append(NamedFrame(toks[k + 1].text, "frame", poses([target])[0]))
    return True


def _frame_data(toks, words: list[str], sc, frames) -> bool:
    """``NAME[n] = {...}`` (``TOOL_DATA[1]``, ``BASE_DATA[2]``): a named frame; whether the line is one."""
    if not (len(toks) > 5 and words[1] == "[" and words[3] == "]" and words[4] == "=" and words[5] == "{"):
        return False
    name = "".join(t.text for t in toks[:4])
    agg, _ = aggregate(toks, 5, sc, name=name)
    target = _target(name, "FRAME", agg, sc)
    if not target.skip:
        kind = {"TOOL_DATA": "tool", "BASE_DATA": "wobj"}.get(words[0], "frame")
        frames.append(NamedFrame(name, kind, poses([target])[0]))
    return True


def _members(agg: Aggregate, sc) -> dict:
    out = {}
    for item in agg.items:
        if not isinstance(item, Field):
            where = item.start if hasattr(item, "start") else agg.start
            raise sc.error(where, "a KRL structure lists members as NAME value, e.g. {X 10.0, Y 0.0}")
        if item.name.upper() in out:
            raise sc.error(item.start, f"member {item.name} given twice")
        out[item.name.upper()] = item.value
    return out


def _status(value, sc) -> Number | None:
    """S or T as written: a number, or a bit string 'B010'."""
    if isinstance(value, Number):
        if not float(value.value).is_integer() or value.value < 0:     # not infinite either
            raise sc.error(value.start, f"Status and Turn are whole numbers of 0 or more, got {value.text}")
        return value
    if isinstance(value, Token) and value.kind == "str" and value.text[1:2].upper() == "B":
        bits = value.text[2:-1]
        if not bits or set(bits) - {"0", "1"}:
            raise sc.error(value.start, f"a bit string is 'B' then 0s and 1s, got {value.text}")
        return Number(float(int(bits, 2)), value.text, value.start, value.end)
    return None


def _target(name: str, kind: str, agg: Aggregate, sc, **frames) -> Target:
    m = _members(agg, sc)
    line, column = sc.target_at(agg.start)
    joint = kind in AXES or (not kind and "A1" in m)
    need = JOINTS if joint else CARTESIAN
    if not all(isinstance(m.get(f), Number) for f in need):
        missing = [f for f in need if not isinstance(m.get(f), Number)]
        return Target(name, "joint" if joint else "pose", line, column, skip=f"no literal {', '.join(missing)}",
                      **frames)
    check_finite([m[f] for f in need], sc, name)
    if joint:
        return Target(name, "joint", line, column, joints=tuple(m[f] for f in JOINTS))
    status = [_status(m[f], sc) for f in ("S", "T") if f in m]
    conf = tuple(c for c in status if c is not None)
    conf = conf if len(conf) == 2 else ()
    return Target(name, "pose", line, column, position=tuple(m[f] for f in "XYZ"),
                  orientation=tuple(m[f] for f in "ABC"), configuration=conf, **frames)


def zyx_matrix(a, b, c) -> np.ndarray:
    """Rz(a) Ry(b) Rx(c), angles in radians (scalars, or arrays: the matrix's last axes are theirs)."""
    ca, sa, cb, sb, cc, sc = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c), np.sin(c)
    return np.array([[ca * cb, ca * sb * sc - sa * cc, ca * sb * cc + sa * sc],
                     [sa * cb, sa * sb * sc + ca * cc, sa * sb * cc - ca * sc],
                     [-sb, cb * sc, cb * cc]])


# -- the compensation's view ----------------------------------------------------------------------------

def poses(targets) -> np.ndarray:
    """(N, 4, 4) X (SI) of pose targets in their base frame."""
    v = np.array([[n.value for n in (*t.position, *t.orientation)] for t in targets]).reshape(-1, 6)
    X = np.tile(np.eye(4), (len(v), 1, 1))
    X[:, :3, :3] = zyx_matrix(*(v[:, 3:] * ANGLE).T).transpose(2, 0, 1) if len(v) else X[:, :3, :3]
    X[:, :3, 3] = v[:, :3] * LENGTH
    return X


def orientation_values(R: np.ndarray, targets) -> np.ndarray:
    """(N, 3) A, B, C (deg) of rotations ``R`` (N, 3, 3): of the two ZYX triples, the one nearest
    the target's own, each angle within half a turn of its old value."""
    b = np.arctan2(-R[:, 2, 0], np.hypot(R[:, 0, 0], R[:, 1, 0]))
    a, c = np.arctan2(R[:, 1, 0], R[:, 0, 0]), np.arctan2(R[:, 2, 1], R[:, 2, 2])
    old = np.array([[n.value for n in t.orientation] for t in targets]).reshape(-1, 3)
    one = np.degrees(np.stack([a, b, c], axis=1))
    other = np.degrees(np.stack([a + np.pi, np.pi - b, c + np.pi], axis=1))
    one, other = (old + (x - old + 180.0) % 360.0 - 180.0 for x in (one, other))
    closer = np.abs(other - old).sum(axis=1) < np.abs(one - old).sum(axis=1) - 1e-9
    return np.where(closer[:, None], other, one)


def wanted(target: Target, n_joints: int) -> tuple[np.ndarray, np.ndarray]:
    """Posture bits from Status bits 0-2 and turn windows from the Turn bits (bit i: axis i+1 negative)."""
    s, t = (int(n.value) for n in target.configuration)
    turn = np.array([SLACK - 2 * math.pi if (t >> j) & 1 else -SLACK for j in range(n_joints)])
    return np.array([s & 1, (s >> 1) & 1, (s >> 2) & 1]), turn


def configuration_values(q: np.ndarray, bits: np.ndarray, target: Target, slack: float) -> list[int]:
    """S and T of readings ``q`` (SI) with posture ``bits``; S's higher bits kept as they were, and a
    Turn bit while its axis is within ``slack`` (rad) of its side."""
    s_old, t_old = (int(n.value) for n in target.configuration)
    s = (s_old & ~7) | int(bits[0]) | int(bits[1]) << 1 | int(bits[2]) << 2
    t = t_old & ~63
    for j in range(min(len(q), 6)):
        negative = (t_old >> j) & 1
        keep = q[j] < slack if negative else q[j] > -slack
        t |= (negative if keep else int(q[j] < 0)) << j
    return [s, t]
