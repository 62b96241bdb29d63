"""The tool and work object each target of a robot program moves with, and where they are
(docs/formats.md, "Robot programs", "Tool and work object").

A target written inline in a motion holds its motion's frames; a declared one takes those of the
motions that use it (``Use``), in its own file or in the files read with it (a KRL ``.src`` for its
``.dat``). Where the program does not tell, or tells two different things, the target's frames are
not known and it is left alone: never solved in a guessed frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .syntax import NamedFrame, Program, Target, Use

NOT_MOVED = "not moved to by a motion of the program: its tool and work object are not known"
# the prefix of a target compensated nowhere because motions reach it only through expressions
THROUGH = "not compensated: moved to only through"


@dataclass(frozen=True)
class TargetFrames:
    """A target's ``tool`` and work object ``wobj`` (names), or why they are not known
    (``unknown``); ``through``: the expressions motions also reach it through (``Offs (line 30)``)."""

    tool: str = ""
    wobj: str = ""
    unknown: str = ""
    through: str = ""


def index_uses(module, uses) -> dict[str, list[tuple[int, Use]]]:
    """``uses`` by the name they use (as the dialect compares names), each with its place in ``uses``."""
    index: dict[str, list[tuple[int, Use]]] = {}
    for k, u in enumerate(uses):
        index.setdefault(module.key(u.name), []).append((k, u))
    return index


def _uses_of(module, target: Target, index) -> list[Use]:
    """The uses of ``target``: of its name, and of its array's (``p{*}``, an index computed at run time)."""
    name = module.key(target.name)
    array = name.split("{", 1)[0]
    found = [p for k in dict.fromkeys((name, array, f"{array}{{*}}")) for p in index.get(k, ())]
    return [u for _, u in sorted(found, key=lambda p: p[0])]


def frames_of(module, target: Target, index) -> TargetFrames:
    """The frames ``target`` moves with, from its own motion (inline) or from the uses ``index``
    (``index_uses``) holds."""
    if target.tool or target.wobj or target.unknown:
        return TargetFrames(target.tool, target.wobj, target.unknown)
    mine = _uses_of(module, target, index)
    if not mine:
        return TargetFrames(unknown=NOT_MOVED)
    direct = [u for u in mine if not u.how or u.how.lower() in module.FOLLOWED]
    through = ", ".join(f"{u.how} (line {u.line})" for u in mine if u.how)
    if not direct:
        return TargetFrames(unknown=f"{THROUGH} {through}", through=through)
    unsure = next((u for u in direct if u.unknown), None)
    if unsure is not None:
        return TargetFrames(unknown=f"moved to at line {unsure.line}, where {unsure.unknown}", through=through)
    seen = {(module.key(u.tool), module.key(u.wobj)): u for u in direct}
    if len(seen) > 1:
        said = "; ".join(f"tool {u.tool}, work object {u.wobj} at line {u.line}" for u in seen.values())
        return TargetFrames(unknown=f"moved to with several tools or work objects ({said})", through=through)
    return TargetFrames(direct[0].tool, direct[0].wobj, through=through)


class Catalogue:
    """The tools and work objects a program can name: its own declarations, those of the files
    read with it, and the dialect's own (the flange, the robot's base) at the identity."""

    def __init__(self, module, program: Program, companions=()):
        self.module = module
        self.frames: dict[str, NamedFrame] = {}
        for name, kind in getattr(module, "BUILTIN", {}).items():
            self.frames[module.key(name)] = NamedFrame(name, kind, np.eye(4))
        for p in (*companions, program):            # the program's own declarations win
            for f in p.frames:
                self.frames[module.key(f.name)] = f

    def canonical(self, name: str) -> str:
        """The name of the frame ``name`` stands for (a KRL FDAT's ``F.TOOL_NO``: ``TOOL_DATA[n]``)."""
        f = self.frames.get(self.module.key(name))
        return f.alias if f is not None and f.alias else name

    def names(self, kinds) -> list[str]:
        return [f.name for f in self.frames.values() if f.kind in kinds]

    def find(self, name: str, kinds) -> np.ndarray | str:
        """The pose (4x4, SI) of the frame ``name`` of one of ``kinds``, or why there is none."""
        f = self.frames.get(self.module.key(name))
        what = "tool" if "tool" in kinds else "work object"
        if f is not None and f.alias:
            name = f"{f.alias} ({name})"
            f = self.frames.get(self.module.key(f.alias))
        if f is None:
            hint = getattr(self.module, "DECLARED_IN", {}).get(self.module.key(name).split("[", 1)[0], "")
            return f"its {what} {name} is declared neither in the program nor in the files read with it{hint}"
        if f.kind not in kinds:
            return f"its {what} {name} is a {f.kind}, not one robocal can use"
        return f.X
