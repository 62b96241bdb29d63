"""Repeatability files (CSV): repeated measurements of commanded poses, for ISO 9283 (docs/formats.md)."""

from __future__ import annotations

import csv
import io

import numpy as np

from .._accuracy.limit import RepeatabilityData
from .._base.arguments import (
    PATH,
    accepts,
    one_of,
    optional,
)
from .._base.errors import InputError, excerpt
from .._base.options import MAX_HEADER_LINES, MAX_POSES
from .._base.units import LENGTH_UNITS
from .measurements import MAX_MAGNITUDE
from .text import read_text

CSV_COLUMNS = ("pose", "cycle", "x", "y", "z")


@accepts(path=PATH, units=optional(one_of(tuple(LENGTH_UNITS))))
def read_repeatability_csv(path, *, units: str | None = None) -> RepeatabilityData:
    """Read repeated measurements: columns ``pose, cycle, x, y, z`` (header required, any order,
    further columns ignored). The coordinates' unit is never guessed: it comes from the column
    names (``x_mm, y_mm, z_mm`` or ``x_m``...) or, for plain ``x, y, z``, from ``units`` ("mm" or
    "m"); a suffix that disagrees with ``units`` is an error. The result is in metres.

    Errors name the file and ``row N, column 'c'`` with N the line number in the file (header = 1).

    Parameters
    ----------
    {path}
    units : str, optional
        Length unit of columns without a suffix (``mm`` or ``m``).

    Returns
    -------
    RepeatabilityData
        Pose ids and points, m.
    """
    if units is not None and units not in LENGTH_UNITS:
        raise InputError(f"units must be one of {', '.join(LENGTH_UNITS)}, got {units!r}", where="units")
    src = str(path)
    text = read_text(path, lines=MAX_POSES + MAX_HEADER_LINES, rows=(MAX_POSES, "rows", None))[0]
    reader = csv.reader(io.StringIO(text, newline=""))
    try:
        header = next(reader, None)
        if header is None:
            raise InputError("the file is empty; a header pose, cycle, x, y, z is required", source=src)
        col, scale = _repeatability_columns([h.strip().lower() for h in header], units, src)
        pose_ids, cycles, points = [], [], []
        seen: dict[tuple[str, int], int] = {}    # (pose, cycle) -> its row, in the file's order
        for row in reader:
            if not any(cell.strip() for cell in row):
                continue
            line = reader.line_num
            pose, cycle, xyz = _repeatability_row(row, col, scale, src, line)
            if (pose, cycle) in seen:
                raise InputError(f"pose {excerpt(pose)} cycle {cycle} already given in row {seen[pose, cycle]}",
                                 source=src, where=f"row {line}")
            seen[pose, cycle] = line
            pose_ids.append(pose)
            cycles.append(cycle)
            points.append(xyz)
    except csv.Error as e:
        raise InputError(f"not readable as CSV: {e}", source=src, where=f"row {reader.line_num}") from None
    if not points:
        raise InputError("no measurements after the header", source=src)
    if len(points) > MAX_POSES:
        raise InputError(f"{len(points):,} rows; robocal reads up to {MAX_POSES:,} per file (docs/formats.md)",
                         source=src)
    _refuse_single_cycles(seen, src)
    return RepeatabilityData(pose_ids=tuple(pose_ids), cycles=np.array(cycles, dtype=int),
                             points=np.array(points, dtype=float), source=src)


def _repeatability_row(row: list[str], col: dict, scale: dict, src: str, line: int) -> tuple[str, int, list[float]]:
    """(pose, cycle, [x, y, z] in metres) of one row (``line``: its line in the file)."""
    cells = {}
    for c in CSV_COLUMNS:
        if col[c] >= len(row) or not row[col[c]].strip():
            raise InputError("empty cell", source=src, where=f"row {line}, column {c!r}")
        cells[c] = row[col[c]].strip()
    return cells["pose"], _cycle(cells["cycle"], src, line), [_coordinate(cells[c], c, src, line) * scale[c]
                                                               for c in "xyz"]


def _cycle(text: str, src: str, line: int) -> int:
    if len(text) < 10:     # a cycle number, not a long run of digits
        try:
            return int(text)
        except ValueError:
            pass
    raise InputError(f"expected an integer cycle number, got {excerpt(text)}", source=src,
                     where=f"row {line}, column 'cycle'")


def _coordinate(text: str, column: str, src: str, line: int) -> float:
    """The number in a coordinate's cell, in the file's unit."""
    where = f"row {line}, column {column!r}"
    try:
        v = float(text)
    except ValueError:
        raise InputError(f"expected a number, got {excerpt(text)}", source=src, where=where) from None
    if not abs(v) <= MAX_MAGNITUDE:
        raise InputError(f"expected a finite number of magnitude up to {MAX_MAGNITUDE:g}, got {excerpt(text)}",
                         source=src, where=where)
    return v


def _refuse_single_cycles(seen: dict[tuple[str, int], int], src: str) -> None:
    """An InputError at the first row of the first pose measured in one cycle only."""
    first: dict[str, int] = {}
    count: dict[str, int] = {}
    for (pose, _), line in seen.items():
        first.setdefault(pose, line)
        count[pose] = count.get(pose, 0) + 1
    for pose, n in count.items():
        if n < 2:
            raise InputError(f"pose {excerpt(pose)} has a single cycle; repeatability needs at least two",
                             source=src, where=f"row {first[pose]}")


def _repeatability_columns(names: list[str], units: str | None, src: str) -> tuple[dict, dict]:
    """Column index of pose, cycle, x, y, z and the metres per unit of each coordinate."""
    col, scale = {}, {}
    for c in CSV_COLUMNS:
        found = [(i, n[len(c) + 1:] if n != c else None) for i, n in enumerate(names)
                 if n == c or (c in "xyz" and n.startswith(c + "_") and n[len(c) + 1:] in LENGTH_UNITS)]
        if not found:
            raise InputError(f"missing column {c!r} (need {', '.join(CSV_COLUMNS)}; coordinates may carry their "
                             f"unit, e.g. x_mm)", source=src, where="header")
        if len(found) > 1:
            raise InputError(f"column {c!r} is given {len(found)} times", source=src, where="header")
        i, suffix = found[0]
        col[c] = i
        if c not in "xyz":
            continue
        unit = suffix if suffix is not None else units
        if unit is None:
            raise InputError(f"the unit of column {c!r} is not declared: name it {c}_mm or {c}_m, or give the "
                             "units (--csv-units mm|m)", source=src, where="header")
        if suffix is not None and units is not None and suffix != units:
            raise InputError(f"column {names[i]!r} says {suffix} but units {units!r} were given",
                             source=src, where="header")
        scale[c] = LENGTH_UNITS[unit]
    return col, scale
