"""Robot programs in, compensated programs out: ABB RAPID, KUKA KRL and URScript (docs/formats.md,
"Robot programs").

A program is read into its targets (``syntax.Target``: each number with its exact place in the
text) and written back with only those numbers replaced: comments, layout, names, motion
parameters, external axes and every other character stay as they were. Units are converted here
and nowhere else: the dialect modules say what a target's numbers mean.
"""

from __future__ import annotations

import codecs
import math
import re
from pathlib import Path

import numpy as np

from ..._base.arguments import PATH, accepts, is_a, one_of, optional
from ..._base.errors import InputError, suggest
from ..._model.robot import RobotModel
from ..text import decode, read_bytes
from . import krl, rapid, urscript
from .syntax import Program

# a program of 30,000 targets as RAPID or KRL writes them is about 6 MB and fits syntax.MAX_TOKENS
MAX_PROGRAM_BYTES = 32 * 2 ** 20
DIALECTS = {"rapid": rapid, "krl": krl, "urscript": urscript}
EXTENSIONS = {ext: name for name, module in DIALECTS.items() for ext in module.EXTENSIONS}
# a new number replaces the old one only where they differ by more than this (SI: m, rad, or a
# quaternion's component), and is written to this resolution (decimals in the file's units)
KEEP = 5e-10
DIGITS = {1e-3: 7, 1.0: 10, math.pi / 180: 9}
# what the summary and the flag comments say of a target
REACHED, UNREACHED, BEYOND, NO_SOLUTION = ("ok", "out of reach of the calibrated robot", "beyond a joint limit",
                                           "no nominal solution in its configuration")
NOT_CONVERGED = "the calibrated robot's commands did not converge"
CONFIGURATION = "its configuration data no longer fit"


def dialect_of(path, dialect: str | None = None) -> str:
    """The dialect named, or the one the file's extension says (.mod/.prg/.sys: rapid, .src/.dat: krl,
    .script: urscript)."""
    if dialect is not None:
        if dialect not in DIALECTS:
            raise InputError(f"no dialect {dialect!r}{suggest(dialect, DIALECTS)}", where="--dialect")
        return dialect
    ext = Path(path).suffix.lower()
    if ext not in EXTENSIONS:
        raise InputError(f"cannot tell the program's dialect from {ext or 'no extension'!r}; give --dialect "
                         f"({', '.join(DIALECTS)})", source=str(path))
    return EXTENSIONS[ext]


# how each dialect's files begin (their first line that is neither blank nor a comment)
_OPENINGS = (("urscript", re.compile(r"\s*def\s+\w+\s*\(\s*\)\s*:")),
             ("rapid", re.compile(r"(?i)\s*(%%%|module\s+\w)")),
             ("krl", re.compile(r"(?i)\s*(&(access|rel|param|comment)\b|(global\s+)?def(dat|fct)?\s+\w)")))
_SNIFF_BYTES = 1 << 16


def dialect_in(path) -> str | None:
    """The dialect a regular file's text opens as (``MODULE name``, ``DEF name()``, ``def name():``),
    None for anything else; a stream is never read here (it could not be read again)."""
    p = Path(path)
    if not p.is_file():
        return None
    try:
        with p.open("rb") as f:
            head = f.read(_SNIFF_BYTES).decode("utf-8", errors="replace").lstrip("\ufeff")
    except OSError:
        return None
    comments = tuple(DIALECTS[name].COMMENT for name in DIALECTS)
    line = next((ln for ln in head.splitlines() if ln.strip() and not ln.lstrip().startswith(comments)), "")
    return next((name for name, opening in _OPENINGS if opening.match(line)), None)


_DIALECT = optional(one_of(tuple(DIALECTS)))


@accepts(path=PATH, dialect=_DIALECT)
def read_program(path, *, dialect: str | None = None) -> Program:
    """Read a robot program.

    Parameters
    ----------
    path : str or Path
        The program file (UTF-8).
    dialect : str, optional
        ``rapid``, ``krl`` or ``urscript``; default from the extension.

    Returns
    -------
    Program
        Its text, targets in source order and named frames; a malformed program is an InputError
        naming the file, line and column.
    """
    name = dialect_of(path, dialect)
    raw = read_bytes(path, limit=MAX_PROGRAM_BYTES)
    text = decode(raw, str(path))
    if raw.startswith(codecs.BOM_UTF8):          # kept, so that the program is written back as it came
        text = "\ufeff" + text
    del raw
    return DIALECTS[name].read(text, str(path))


def joint_units(model: RobotModel, module) -> np.ndarray:
    return np.array([module.LENGTH if k == "length" else module.ANGLE for k in model.reading_quantities])


def joint_values(program: Program, targets, model: RobotModel) -> np.ndarray:
    """(N, n_joints) readings (SI) of joint ``targets``: their first axes, one per joint of ``model``."""
    for t in targets:
        if len(t.joints) < model.n_joints:
            raise InputError(f"{t.name}: {len(t.joints)} robot axes, the model has {model.n_joints} joints",
                             source=program.source, where=f"line {t.line}, column {t.column}")
    values = np.array([[n.value for n in t.joints[:model.n_joints]] for t in targets]).reshape(-1, model.n_joints)
    return values * joint_units(model, DIALECTS[program.dialect])


@accepts(program=is_a(Program), model=is_a(RobotModel))
def program_joints(program: Program, model: RobotModel) -> tuple[list[str], np.ndarray]:
    """The program's joint targets as readings: labels (the target names) and q (N, n_joints), SI.

    For a campaign whose joint readings were recorded as controller code (``MoveAbsJ`` lines,
    ``E6AXIS`` declarations, ``movej`` lists).

    Parameters
    ----------
    program : Program
        As ``read_program`` gives it.
    model : RobotModel
        The model whose joints the targets' first axes are (their kinds give the units).

    Returns
    -------
    (list of str, numpy.ndarray)
        The labels (the target names) and the readings q (N, n_joints), SI.
    """
    targets = [t for t in program.targets if t.kind == "joint" and not t.skip]
    if not targets:
        raise InputError("no joint targets with literal values", source=program.source)
    return [t.name for t in targets], joint_values(program, targets, model)


@accepts(path=PATH, model=is_a(RobotModel), dialect=_DIALECT)
def read_program_joints(path, model: RobotModel, *, dialect: str | None = None) -> tuple[list[str], np.ndarray]:
    """Joint readings written as a robot program (``program_joints`` of ``read_program``).

    Parameters
    ----------
    path : str or Path
        The program file.
    model : RobotModel
        The model whose joints the targets' axes are, in order (their kinds give the units).
    dialect : str, optional
        As in ``read_program``.

    Returns
    -------
    (list of str, numpy.ndarray)
        The labels (the target names) and the readings q (N, n_joints), SI.
    """
    return program_joints(read_program(path, dialect=dialect), model)


def is_program(path) -> bool:
    """Whether ``path``'s extension is a robot program's (``EXTENSIONS``)."""
    return Path(path).suffix.lower() in EXTENSIONS


def program_joint_table(path, model: RobotModel | None, key: str = "pose"):
    """The joint targets of the program at ``path`` as a table of joint readings (``table.Table``):
    column ``key`` holds the target names, one column per joint of ``model`` with the dialect's unit
    as suffix; for joining to an instrument's file (``read_measurements(..., joints=path)``)."""
    from ..table import read_table

    if model is None:
        raise InputError("joint readings in a robot program need the model (which axes are linear)",
                         source=str(path))
    program = read_program(path)
    module = DIALECTS[program.dialect]
    labels, _ = program_joints(program, model)
    targets = [t for t in program.targets if t.kind == "joint" and not t.skip]
    suffix = {"length": "mm" if module.LENGTH == 1e-3 else "m", "angle": "deg" if module.ANGLE != 1.0 else "rad"}
    header = [key] + [f"{j}_{suffix[k]}" for j, k in zip(model.joint_names, model.reading_quantities)]
    lines = [",".join(header)] + [",".join([f'"{name}"'] + [repr(n.value) for n in t.joints[:model.n_joints]])
                                  for name, t in zip(labels, targets)]
    return read_table("\n".join(lines) + "\n", str(path), sep=",", decimal=".")
