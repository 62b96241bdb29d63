"""Repeatability files (CSV): repeated measurements of commanded poses, for ISO 9283 (docs/formats.md)."""

from __future__ import annotations

from typing import NamedTuple

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
from .measurements import number_cell
from .table import Table, read_table
from .text import read_text

CSV_COLUMNS = ("pose", "cycle", "x", "y", "z")


@accepts(path=PATH, units=optional(one_of(tuple(LENGTH_UNITS))))
def read_repeatability_csv(path, *, units: str | None = None) -> RepeatabilityData:
    """Read repeated measurements: columns ``pose, cycle, x, y, z`` (header required, any order,
    further columns ignored). The coordinates' unit is never guessed: it comes from the column
    names (``x_mm, y_mm, z_mm`` or ``x_m``...) or, for plain ``x, y, z``, from ``units`` ("mm" or
    "m"); a suffix that disagrees with ``units`` is an error. The result is in metres.

    The separator and the decimal mark are detected as in a measurement file (``;`` with decimal
    commas, tabs...). Errors name the file and ``line N, column 'c'`` (the file's column name).

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
    table = read_table(text, src)   # the separator and the decimal mark detected as in a measurement file
    col = _repeatability_columns(table, units)
    pose_ids, cycles, points = [], [], []
    seen: dict[tuple[str, int], str] = {}    # (pose, cycle) -> its line, in the file's order
    for line, row in table.rows:
        pose, cycle, xyz = _repeatability_row(row, col, table, line)
        if (pose, cycle) in seen:
            raise InputError(f"pose {excerpt(pose)} cycle {cycle} already given in line {seen[pose, cycle]}",
                             source=src, where=f"line {line}")
        seen[pose, cycle] = line
        pose_ids.append(pose)
        cycles.append(cycle)
        points.append(xyz)
    if not points:
        raise InputError("no measurements after the header", source=src)
    if len(points) > MAX_POSES:
        raise InputError(f"{len(points):,} rows; robocal reads up to {MAX_POSES:,} per file (docs/formats.md)",
                         source=src)
    _refuse_single_cycles(seen, src)
    _refuse_copies(pose_ids, points, seen, col, table)
    return RepeatabilityData(pose_ids=tuple(pose_ids), cycles=np.array(cycles, dtype=int),
                             points=np.array(points, dtype=float), source=src)


class _Column(NamedTuple):
    """Where a column is in the file, its name there, and metres per unit of its numbers (coordinates)."""

    at: int
    name: str
    scale: float = 1.0


def _repeatability_row(row: list[str], col: dict[str, _Column], table: Table, line: str) -> tuple[str, int, list]:
    """(pose, cycle, [x, y, z] in metres) of one row (``line``: its line in the file)."""
    cells = {}
    for c in ("pose", "cycle"):
        if col[c].at >= len(row) or not row[col[c].at].strip():
            raise InputError("empty cell", source=table.source, where=f"line {line}, column {col[c].name!r}")
        cells[c] = row[col[c].at].strip()
    xyz = [number_cell(row[col[c].at] if col[c].at < len(row) else "", table, table.source, line,
                       col[c].name, True) * col[c].scale for c in "xyz"]
    return cells["pose"], _cycle(cells["cycle"], table.source, line, col["cycle"].name), xyz


def _cycle(text: str, src: str, line: str, name: str) -> int:
    if len(text) < 10:     # a cycle number, not a long run of digits
        try:
            return int(text)
        except ValueError:
            pass
    raise InputError(f"expected an integer cycle number, got {excerpt(text)}", source=src,
                     where=f"line {line}, column {name!r}")


def _refuse_single_cycles(seen: dict[tuple[str, int], str], src: str) -> None:
    """An InputError at the first row of the first pose measured in one cycle only."""
    first: dict[str, str] = {}
    count: dict[str, int] = {}
    for (pose, _), line in seen.items():
        first.setdefault(pose, line)
        count[pose] = count.get(pose, 0) + 1
    for pose, n in count.items():
        if n < 2:
            raise InputError(f"pose {excerpt(pose)} has a single cycle; repeatability needs at least two",
                             source=src, where=f"line {first[pose]}")


def _refuse_copies(pose_ids: list[str], points: list, seen: dict[tuple[str, int], str], col: dict[str, _Column],
                   table: Table) -> None:
    """Every pose's cycles at one position to the last digit: no robot repeats so, nor does an instrument
    read so; the readings were repeated or the rows copied (the repeatability would read 0)."""
    first: dict[str, list] = {}
    for pose, xyz in zip(pose_ids, points):
        if first.setdefault(pose, xyz) != xyz:
            return
    lines = list(seen.values())
    raise InputError(f"the cycles of each of the {len(first)} poses read the same "
                     f"{', '.join(col[c].name for c in 'xyz')} to the last digit: no robot returns so exactly, nor "
                     "does an instrument read so; the instrument repeated one reading or the rows are copies "
                     "(the repeatability would read 0)", source=table.source, where=f"lines {lines[0]}-{lines[-1]}")


def _repeatability_columns(table: Table, units: str | None) -> dict[str, _Column]:
    """Each column of pose, cycle, x, y, z in ``table``, with the metres per unit of the coordinates."""
    src, where = table.source, table.header_where
    names = [h.strip().lower() for h in table.header]
    col = {}
    for c in CSV_COLUMNS:
        found = [(i, n[len(c) + 1:] if n != c else None) for i, n in enumerate(names)
                 if n == c or (c in "xyz" and n.startswith(c + "_") and n[len(c) + 1:] in LENGTH_UNITS)]
        if not found:
            raise InputError(f"missing column {c!r} (need {', '.join(CSV_COLUMNS)}; coordinates may carry their "
                             f"unit, e.g. x_mm)", source=src, where=where)
        if len(found) > 1:
            raise InputError(f"column {c!r} is given {len(found)} times", source=src, where=where)
        i, suffix = found[0]
        name = table.header[i].strip()
        if c not in "xyz":
            col[c] = _Column(i, name)
            continue
        unit = suffix if suffix is not None else units
        if unit is None:
            raise InputError(f"the unit of column {name!r} is not declared: name it {c}_mm or {c}_m, or give the "
                             "units (--csv-units mm|m)", source=src, where=where)
        if suffix is not None and units is not None and suffix != units:
            raise InputError(f"column {name!r} says {suffix} but units {units!r} were given", source=src, where=where)
        col[c] = _Column(i, name, LENGTH_UNITS[unit])
    if len({col[c].scale for c in "xyz"}) > 1:
        raise InputError(f"columns {', '.join(repr(col[c].name) for c in 'xyz')} are in different units: a "
                         "position's axes share one unit (a column misnamed?)", source=src, where=where)
    return col
