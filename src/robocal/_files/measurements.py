"""Measurement files (CSV): one row per pose, converted to SI on reading (docs/formats.md).

Units are never guessed: every column that needs one takes it from a suffix on its name
(``j1_deg``, ``tool_x_mm``), from a ``# units: length=mm angle=deg`` line before the header, or
from the ``units`` argument. A marker that was not seen in a pose has empty cells: the pose is
kept and the marker masked.
"""

from __future__ import annotations

import csv
import hashlib
import io
import os
import re
from dataclasses import replace
from typing import NamedTuple

import numpy as np

from .._base.arguments import (
    FLAG,
    PATH,
    SEQUENCE,
    TEXT,
    UNIT_SYSTEM,
    accepts,
    is_a,
    optional,
)
from .._base.errors import InputError, excerpt, suggest
from .._base.options import MAX_POSES, POSES_PER_GB
from .._base.units import ANGLE_UNITS, LENGTH_UNITS, UNITS, check_unit, parse_units
from .._model.measurements import Measurements, approach_sides
from .._model.robot import RobotModel
from .profile import Profile, read_profile
from .table import (
    ColumnMap,
    Table,
    Unfit,
    column_named,
    decimal_hint,
    join_notes,
    join_rows,
    join_tables,
    joined_header,
    map_columns,
    read_columns,
    read_head,
    read_table,
    scan_rows,
)
from .text import SNIFFED_CHARS, decode, read_bytes, refuse_other_form, write_texts

RESERVED = ("pose", "set", "series", "payload_kg")
# approach_<joint>: the direction (+1 or -1) of the joint's last move before the pose (backlash)
APPROACH_PREFIX = "approach_"
POSITION = ("x", "y", "z")
ORIENTATION_PARTS = {"quat": ("qx", "qy", "qz", "qw"), "rpy": ("roll", "pitch", "yaw"), "euler": ("e1", "e2", "e3")}
# per-axis standard deviations of a position, combined into one per point (docs/formats.md)
SIGMA_AXES = ("sigma_x", "sigma_y", "sigma_z")
# per-axis standard deviations of an orientation (angle unit), combined the same way into sigma_rot
SIGMA_ROT_AXES = ("sigma_rx", "sigma_ry", "sigma_rz")
# longest first, so "sigma_rot" is not read as "sigma" plus a unit
PARTS = ("sigma_rot",) + SIGMA_ROT_AXES + SIGMA_AXES + ("sigma",) + POSITION + sum(ORIENTATION_PARTS.values(), ())
_MARKER_COLUMN = re.compile(r"^(?P<m>.+?)_(?P<part>x|y|z)(?:_(?P<unit>[A-Za-z]+))?$")
_NUMBER = re.compile(r"^[+-]?(\d+(\.\d*)?|\.\d+)([eE][+-]?\d+)?$")
_NOT_FINITE = re.compile(r"^[+-]?(nan|inf|infinity)$", re.IGNORECASE)
SETS = ("fit", "validation")
# no coordinate, joint reading or sigma in any unit comes near this; beyond it arithmetic overflows
MAX_MAGNITUDE = 1e12


def parse_orientation(text: str | None, *, source: str | None = None, where: str = "orientation"):
    """``quat_xyzw``/``quat_wxyz``/``rpy``/``euler:SEQ`` -> (kind, euler sequence or None)."""
    if text is None:
        return None
    text = text.strip()
    if text in ("quat_xyzw", "quat_wxyz"):
        return "quat", None
    if text == "rpy":
        return "rpy", None
    if text.startswith("euler:"):
        seq = text.split(":", 1)[1]
        from scipy.spatial.transform import Rotation  # here: half a second of imports a refusal needs not

        try:
            Rotation.from_euler(seq, [0.0, 0.0, 0.0])
        except ValueError:
            raise InputError(f"bad Euler sequence {seq!r}: three axes from xyz, uppercase for intrinsic "
                             "(euler:ZYX), lowercase for extrinsic (euler:zyx)", source=source, where=where) from None
        return "euler", seq
    raise InputError(f"unknown orientation convention {text!r}; use quat_xyzw, quat_wxyz, rpy or euler:ZYX "
                     "(any scipy sequence)", source=source, where=where)


class _Columns:
    """What each header column holds, with its unit resolved (or an InputError saying how to declare it)."""

    def __init__(self, header, model, declared, orientation, source, line: str, unknown: str = "refuse",
                 targets: bool = False, renamed=None):
        """``line``: where messages place the header (``"line 3"``); ``renamed``: {name a column map
        gave: the file's column}, which messages name."""
        self.source, self.line = source, line
        self.renamed = dict(renamed or {})
        self.names = header
        self._check_names(header)
        if model is not None:
            joint_names, kinds = list(model.joint_names), list(model.reading_quantities)
            marker_names = list(model.marker_names)
        else:
            marker_names = _markers_named(header)
            joint_names, kinds = self._joints_without_model(header, marker_names, unknown)
        self.joint_names, self.joint_kinds = joint_names, kinds
        self.declared = declared
        self.joint_cols: dict[str, tuple[int, float]] = {}
        self.marker_cols: dict[str, dict[str, tuple[int, float]]] = {}
        self.special: dict[str, int] = {}
        self.approach_cols: dict[str, int] = {}
        self.ignored = self._assign(header, model, marker_names, unknown)
        self._check_complete(marker_names, targets)
        self.orientation = {mn: self._marker_checked(mn, parts, orientation) for mn, parts in self.marker_cols.items()}
        # markers in the model's order (or the file's, without a model)
        self.markers = [m for m in marker_names if m in self.marker_cols]

    def _check_names(self, header) -> None:
        for k, c in enumerate(header):
            if not c:
                raise InputError(f"column {k + 1} has no name", source=self.source, where=self.line)
            if header.count(c) > 1:
                raise InputError(f"column {c!r} appears twice", source=self.source, where=self.line)

    def _assign(self, header, model, marker_names, unknown) -> tuple[str, ...]:
        """Each column to what it holds (its unit resolved); the unknown columns ignored, or an
        InputError naming the first."""
        ignored = []
        for k, c in enumerate(header):
            if c.startswith(APPROACH_PREFIX) and c[len(APPROACH_PREFIX):] in self.joint_names:
                self.approach_cols[c[len(APPROACH_PREFIX):]] = k
                continue
            mn, part, unit = _marker_part(c, marker_names)
            jn = _joint_of(c, self.joint_names)
            if c in RESERVED:
                self.special[c] = k
            elif mn is not None:
                self.marker_cols.setdefault(mn, {})[part] = (k, self._part_scale(c, part, unit))
            elif jn is not None:
                if jn in self.joint_cols:
                    raise InputError(f"joint {jn!r} has two columns", source=self.source, where=self.line)
                kind = self.joint_kinds[self.joint_names.index(jn)]
                self.joint_cols[jn] = (k, self._scale(c, c[len(jn) + 1:] or None, kind))
            elif unknown == "ignore":
                ignored.append(c)
            else:
                raise self._unknown(c, model, marker_names)
        return tuple(ignored)

    def _unknown(self, column: str, model, marker_names) -> InputError:
        """The error of a column robocal does not know: what it might be, and how to map or ignore it."""
        joint_names = self.joint_names
        valid = list(RESERVED) + joint_names + [f"{m}_{p}" for m in marker_names for p in POSITION]
        known = f"; the model has joints {', '.join(joint_names)} and markers {', '.join(marker_names)}" \
            if model is not None else ""
        if column in self.renamed:      # a name the map gave: the map is what to fix
            given = self.renamed[column]
            return InputError(f"unknown column {column!r}, the name --map gives the file's column {given!r}"
                              f"{suggest(column, valid)}{known}; map it to one of those (--map '{given}=NAME')",
                              source=self.source, where=self.line)
        return InputError(f"unknown column {column!r}{suggest(column, valid)}{known}; map it (--map '{column}=NAME'), "
                          f"ignore it (--ignore '{column}') or ignore every unknown column (--unknown ignore)",
                          source=self.source, where=self.line)

    def _check_complete(self, marker_names, targets: bool) -> None:
        """Approach directions for every joint or none, a column per joint, and a marker's columns
        (unless the file lists targets)."""
        joint_names = self.joint_names
        if self.approach_cols and len(self.approach_cols) != len(joint_names):
            lacking = next(j for j in joint_names if j not in self.approach_cols)
            raise InputError(f"missing column {APPROACH_PREFIX}{lacking}: approach directions are given per joint, "
                             "for every joint or none", source=self.source, where=self.line)
        missing = [j for j in joint_names if j not in self.joint_cols]
        if missing:
            have = len(self.joint_cols)
            raise InputError(f"missing column {missing[0]!r}: the model has {len(joint_names)} joints "
                             f"({', '.join(joint_names)}), the file has {have} of them", source=self.source,
                             where=self.line)
        if not self.marker_cols and not targets:
            raise InputError("no marker columns (like tool_x, tool_y, tool_z)"
                             + (f"; the model's markers are {', '.join(marker_names)}" if marker_names else ""),
                             source=self.source, where=self.line)

    def _marker_checked(self, mn: str, parts, declared):
        """A marker's orientation convention (None without orientation columns), once its columns are
        checked: a whole position, standard deviations one per point or one per axis."""
        for p in POSITION:
            if p not in parts:
                raise InputError(f"missing column {mn}_{p}", source=self.source, where=self.line)
        for one, axes in (("sigma", SIGMA_AXES), ("sigma_rot", SIGMA_ROT_AXES)):
            given = [p for p in axes if p in parts]
            if given and (len(given) < 3 or one in parts):
                raise InputError(f"marker {mn!r}: give {mn}_{one} or all of {', '.join(f'{mn}_{p}' for p in axes)}"
                                 ", not a part of them", source=self.source, where=self.line)
        return self._orientation_of(mn, parts, declared)

    def _joints_without_model(self, header, marker_names, unknown):
        names, kinds = [], []
        for c in header:
            if c in RESERVED or _marker_part(c, marker_names)[0] is not None:
                continue
            base, _, unit = c.rpartition("_")
            kind = next((k for k, units in UNITS.items() if unit in units), None)
            if (not base or kind is None) and unknown == "ignore":
                continue
            if not base or kind is None:
                raise InputError(f"column {c!r}: without a model a joint column must carry its unit "
                                 f"({c}_deg, {c}_rad, {c}_mm or {c}_m), since the joint type is unknown; "
                                 "or pass the model", source=self.source, where=self.line)
            names.append(base)
            kinds.append(kind)
        return names, kinds

    def _scale(self, column: str, unit: str | None, kind: str) -> float:
        """SI per file unit for ``column`` holding a ``kind`` ("length"/"angle") quantity."""
        where = f"{self.line}, {column_named(column, self.renamed)}"
        if unit is None:
            unit = self.declared.get(kind)
            if unit is None:
                example = "mm" if kind == "length" else "deg"
                fix = "map it to" if column in self.renamed else "name it"
                raise InputError(
                    f"no {kind} unit declared for this column: {fix} {column}_{example}, put "
                    f"'# units: length=mm angle=deg' before the header, or pass units='mm-deg' "
                    f"(--units mm-deg on the command line)", source=self.source, where=where)
        return UNITS[kind][check_unit(unit, kind, source=self.source, where=where)]

    def _part_scale(self, column: str, part: str, unit: str | None) -> float:
        if part in ORIENTATION_PARTS["quat"]:
            if unit is not None:
                raise InputError("a quaternion component has no unit", source=self.source,
                                 where=f"{self.line}, {column_named(column, self.renamed)}")
            return 1.0
        kind = "length" if part in POSITION + ("sigma",) + SIGMA_AXES else "angle"
        return self._scale(column, unit, kind)

    def _orientation_of(self, mn, parts, declared):
        kinds = [k for k, ps in ORIENTATION_PARTS.items() if any(p in parts for p in ps)]
        if not kinds:
            if _sigma_parts(parts, "sigma_rot", SIGMA_ROT_AXES):
                raise InputError(f"column {mn}_{_sigma_parts(parts, 'sigma_rot', SIGMA_ROT_AXES)[0]} without "
                                 "orientation columns", source=self.source,
                                 where=self.line)
            return None
        if len(kinds) > 1:
            raise InputError(f"marker {mn!r} has orientation columns of two conventions ({' and '.join(kinds)})",
                             source=self.source, where=self.line)
        kind = kinds[0]
        if declared is not None and declared[0] != kind:
            raise InputError(f"orientation columns of marker {mn!r} are {kind}, but the declared convention is "
                             f"{declared[0]}", source=self.source, where=self.line)
        if kind == "euler" and declared is None:
            raise InputError(f"columns {mn}_e1.. need the Euler sequence: orientation='euler:ZYX' "
                             "(--orientation euler:ZYX) or a line '# orientation: euler:ZYX' before the header",
                             source=self.source, where=self.line)
        for p in ORIENTATION_PARTS[kind]:
            if p not in parts:
                raise InputError(f"missing column {mn}_{p}", source=self.source, where=self.line)
        return kind, (declared[1] if declared else None)


def _marker_part(column: str, markers):
    """(marker, part, unit) when ``column`` is a marker column, else (None, None, None).

    ``markers`` longest name first, so "tool_2_x" belongs to "tool_2", not to "tool".
    """
    for mn in sorted(markers, key=len, reverse=True):
        if column.startswith(mn + "_"):
            part, unit = _split_part(column[len(mn) + 1:])
            if part is not None:
                return mn, part, unit
    return None, None, None


def _markers_named(header) -> list[str]:
    """The markers of a file read without a model: the names before ``_x`` columns, in the file's order."""
    names: list[str] = []
    for c in header:
        mt = _MARKER_COLUMN.match(c)
        if mt and mt["part"] == "x" and mt["m"] not in names:
            names.append(mt["m"])
    return names


def _joint_of(column: str, joint_names) -> str | None:
    """The joint whose column ``column`` is (its name, or its name and a unit suffix), else None."""
    if column in joint_names:
        return column
    return next((j for j in joint_names if column.startswith(j + "_") and column[len(j) + 1:].isalpha()), None)


def _split_part(rest: str):
    """``x_mm`` -> ("x", "mm"), ``sigma_rot`` -> ("sigma_rot", None); (None, None) if not a part."""
    for p in PARTS:
        if rest == p:
            return p, None
        if rest.startswith(p + "_") and rest[len(p) + 1:].isalpha():
            return p, rest[len(p) + 1:]
    return None, None


def _directive(text: str, name: str) -> str | None:
    body = text.lstrip("#").strip()
    if body.lower().startswith(name + ":"):
        return body.split(":", 1)[1].strip()
    return None


def _comment_units(text: str, source: str, line: int) -> dict:
    where = f"line {line}"
    out = {}
    for item in text.replace(",", " ").replace(";", " ").split():
        key, sep, unit = item.partition("=")
        if not sep or key not in UNITS:
            raise InputError(f"expected '# units: length=mm angle=deg', got {item!r}", source=source, where=where)
        out[key] = check_unit(unit, key, source=source, where=f"{where}, units.{key}")
    return out


@accepts(path=PATH, model=optional(is_a(RobotModel)), units=optional(UNIT_SYSTEM), sep=optional(TEXT),
         decimal=optional(TEXT), orientation=optional(TEXT), columns=optional(is_a(dict, ColumnMap)),
         unknown=optional(TEXT), joints=optional(PATH), key=optional(TEXT),
         profile=optional(is_a(str, os.PathLike, Profile)), targets=FLAG, header=optional(SEQUENCE))
def read_measurements(path, model: RobotModel | None = None, *, units: str | None = None, sep: str | None = None,
                      decimal: str | None = None, orientation: str | None = None, columns=None,
                      unknown: str | None = None, joints=None, key: str | None = None,
                      profile=None, targets: bool = False, header=None) -> Measurements:
    """Read a measurement file (docs/formats.md) into Measurements in SI units.

    ``model``: check joint and marker names against it and take each joint's type (angle or
    length) from it; without it, joint columns must carry a unit suffix. ``units``: "mm-deg" etc.
    for columns without a suffix. ``sep``/``decimal``: e.g. ";" and "," as instrument software in
    many locales writes them; None detects them (said in ``extra["notes"]``). ``orientation``: the
    convention of 6D pose columns. ``columns``: {file column: robocal column, or None to ignore it}
    (or a ``ColumnMap``); ``unknown``: "refuse" (default) or "ignore" columns robocal does not know.
    ``joints``: a second file with the joint readings, joined on column ``key`` (default "pose").
    ``profile``: an instrument profile (a path or a ``Profile``) giving any of these; the
    arguments given here win over it. ``targets``: the file lists poses to reach or to measure,
    not measurements: marker columns may be absent or empty (positions NaN there). ``header``:
    the column names of a file without a header line (a sequence of names; a profile's ``header``).
    A ``series`` column (any text per pose: a series, a fold) is kept in ``extra["series"]``.

    Parameters
    ----------
    {path}
    model : RobotModel, optional
        The model the file measures (gives joint order and units).
    units : str, optional
        Units of columns without a suffix, ``"mm-deg"`` etc.
    {sep, decimal}
    orientation : str, optional
        Convention of the orientation columns (``quat_xyzw``, ``quat_wxyz``, ``rpy``, ``euler:XYZ``,
        ...).
    {columns, unknown, joints, key, profile}
    targets : bool
        Read targets, not measurements: marker columns may be absent or empty.
    {header}

    Returns
    -------
    Measurements
        The measurements, SI.
    """
    source = str(path)
    prof = _profile(profile)
    opts = prof.options(units=units, sep=sep, decimal=decimal, orientation=orientation, columns=columns,
                        unknown=unknown, key=key, header=header)
    declared = dict(zip(("length", "angle"), parse_units(opts["units"]))) if opts["units"] is not None else {}
    orient = parse_orientation(opts["orientation"])
    raw = _table_bytes(path)
    refuse_other_form(_head(raw), source, "a measurement file", ("measurements",))
    jraw = None if joints is None or _is_program(joints) else _table_bytes(joints)
    if jraw is not None:
        refuse_other_form(_head(jraw), str(joints), "a measurement file", ("measurements",))
    digest = hashlib.sha256(raw).hexdigest()
    try:
        data, table, cols, other = _read_fast(raw, jraw, digest, source, opts, declared, orient, model, targets,
                                              joints=joints)
        slow: tuple[str, ...] = ()
    except Unfit as e:  # the row reader reads the files or names their fault
        data, table, cols, other = _read_slow(raw, jraw, digest, source, opts, declared, orient, model, targets,
                                              joints=joints)
        slow = (f"read row by row, not by the compiled parser: {e.why}",)
    notes = tuple(f"reading {source}: {n}"
                  for n in table.notes + _unknown_note(cols.ignored, other, exclude=True) + slow)
    if other is not None:
        notes += tuple(f"reading {other.source}: {n}" for n in other.notes + _unknown_note(cols.ignored, other))
    return replace(data, extra={**data.extra, "notes": notes}) if notes else data


def _head(raw: bytes) -> str:
    """A table's first characters, for ``refuse_other_form`` (a character cut at the end dropped)."""
    return raw[:SNIFFED_CHARS].decode("utf-8", errors="ignore")


def _table_bytes(path) -> bytes:
    """The bytes of a measurement or joint file (read once, within the budget of rows and bytes)."""
    return read_bytes(path, rows=(MAX_POSES, "poses", POSES_PER_GB))


def _read_slow(raw: bytes, jraw: bytes | None, digest: str, source, opts, declared, orient, model, targets, *,
               joints=None):
    """What :func:`_read_fast` returns, read row by row: every fault named at its line and column."""
    table = map_columns(read_table(decode(raw, source), source, sep=opts["sep"], decimal=opts["decimal"],
                                   header=opts["header"]), opts["columns"])
    other = None
    if joints is not None:
        # joint readings logged as controller code: a robot program's joint targets
        from .programs import program_joint_table

        raw_table = program_joint_table(joints, model, opts["key"] or "pose") if jraw is None else \
            read_table(decode(jraw, str(joints)), str(joints), sep=opts["sep"], decimal=opts["decimal"])
        other = map_columns(raw_table, opts["columns"])
        table = join_tables(table, other, opts["key"] or "pose")
    cols = _columns(table, source, declared, orient, opts, model, targets)
    if not table.rows:
        raise InputError("no data rows after the header", source=source)
    if len(table.rows) > MAX_POSES:
        raise InputError(f"{len(table.rows):,} rows; robocal reads up to {MAX_POSES:,} poses per file "
                         "(docs/formats.md)", source=source)
    return _parse_rows(table.rows, cols, table, source, digest, targets), table, cols, other


def _columns(table: Table, source: str, declared: dict, orient, opts: dict, model, targets: bool) -> _Columns:
    """What each column of ``table`` holds, with the units and orientation its comment lines declare."""
    declared = dict(declared)
    comment_units, comment_orient, orient_text = _directives(table)
    for kind, unit in comment_units.items():
        if kind in declared and declared[kind] != unit:
            raise InputError(f"the file declares {kind} in {unit}, the units option says {declared[kind]}; "
                             "they must agree", source=source, where="units")
        declared[kind] = unit
    if orient is not None and comment_orient is not None and orient != comment_orient:
        raise InputError(f"the file declares orientation {orient_text}, the option says {opts['orientation']}",
                         source=source, where="orientation")
    return _Columns(list(table.header), model, declared, orient or comment_orient, source, table.header_where,
                    unknown=opts["columns"].unknown, targets=targets, renamed=table.renamed)


def _is_program(joints) -> bool:
    """Whether ``joints`` names a robot program (its joint targets are read from the code)."""
    if joints is None:
        return False
    from .programs import is_program

    return is_program(joints)


def _read_fast(raw: bytes, jraw: bytes | None, digest: str, source, opts, declared, orient, model, targets, *,
               joints=None):
    """(Measurements, head table, columns, the joint file's head table or None) parsed by numpy's
    compiled parser from the files' bytes (with ``joints``, both files, joined on the key as
    ``join_tables`` joins them); ``Unfit`` where it cannot vouch for the files (the row-by-row
    reader then reads them or names the fault)."""
    if joints is not None and jraw is None:
        raise Unfit("the joint readings are a robot program's")
    try:
        table, other, files, raw_cols, keys = _heads(raw, jraw, source, opts, joints)
        cols = _columns(table, source, declared, orient, opts, model, targets)
        scans = [scan_rows(b, h) for b, h in files]
        wanted = _wanted(cols, raw_cols, keys, len(files))
        read = [read_columns(b, h, scan, w) for (b, h), scan, w in zip(files, scans, wanted)]
        n_rows = scans[0].n_rows
        take: list = [None] * len(files)
        if joints is not None:
            rows, jrows, lost, jlost = join_rows(*(read[f][raw_cols[k][1][0]] for f, k in zip((0, 1), keys)))
            if "pose" not in cols.special:
                raise Unfit("poses without a pose label in a join")  # the joined lines name both files
            table = table.with_notes(*join_notes(table, other, opts["key"] or "pose", len(rows), lost, jlost))
            n_rows, take = len(rows), [rows, jrows]
        arrays = {k: _summed([_taken(read[raw_cols[k][0]][r], take[raw_cols[k][0]]) for r in raw_cols[k][1]])
                  for k in _used_columns(cols)}
        if joints is not None and "" in arrays[cols.special["pose"]]:
            raise Unfit
        data = _parse_columns(arrays, cols, n_rows, scans[0].first_line, source, digest, targets)
    except InputError:
        raise Unfit from None
    return data, table, cols, other


def _heads(raw: bytes, jraw: bytes | None, source, opts, joints):
    """What the compiled parser reads from the files' heads: the table of the file's head (joined on
    the key with the joint file's, as :func:`join_tables` joins them), the joint file's table or None,
    (bytes, head) per file, for each column of the table (its file, its columns in that file) and the
    key's columns in the table (in the first file, then the second's, last), or [] without ``joints``."""
    head = read_head(raw, source, sep=opts["sep"], decimal=opts["decimal"], header=opts["header"])
    table = map_columns(head, opts["columns"])
    raw_cols = [(0, r) for r in _file_columns(head.header, opts["columns"])]
    if joints is None or jraw is None:
        return table, None, [(raw, head)], raw_cols, []
    jhead = read_head(jraw, str(joints), sep=opts["sep"], decimal=opts["decimal"])
    other = map_columns(jhead, opts["columns"])
    key = opts["key"] or "pose"
    header, kr = joined_header(table, other, key)
    jraw_cols = _file_columns(jhead.header, opts["columns"])
    raw_cols += [(1, r) for k, r in enumerate(jraw_cols) if k != kr] + [(1, jraw_cols[kr])]
    return replace(table, header=header, renamed={**other.renamed, **table.renamed}), other, \
        [(raw, head), (jraw, jhead)], raw_cols, \
        [header.index(key), len(header)]


def _wanted(cols: _Columns, raw, keys: list[int], n_files: int) -> list[dict[int, str]]:
    """Per file, the columns to read, each as "text" or "number"; ``Unfit`` for a sum of text columns
    (the row reader says what is wrong)."""
    texts = [cols.special.get(c) for c in ("pose", "set", "series")] + keys
    wanted: list[dict[int, str]] = [{} for _ in range(n_files)]
    for k in _used_columns(cols) + keys:
        f, parts = raw[k]
        if len(parts) > 1 and k in texts:
            raise Unfit
        wanted[f].update({r: "text" if k in texts else "number" for r in parts})
    return wanted


def _taken(column, rows):
    """A column read (float array or list of text) at ``rows`` (all of it for None)."""
    if rows is None:
        return column
    if isinstance(column, np.ndarray):
        return column[rows]
    return [column[i] for i in rows.tolist()]


def _file_columns(header, columns) -> list[list[int]]:
    """For each column of the mapped table (``map_columns``), the file columns it is read from: one,
    or the parts of a sum ``"A+B"`` (in place of A); ignored columns dropped."""
    sums = {k: [header.index(p.strip()) for p in k.split("+")] for k in columns.rename
            if "+" in k and k not in header and all(p.strip() in header for p in k.split("+"))}
    used = [k for parts in sums.values() for k in parts]
    if len(used) != len(set(used)):
        raise Unfit  # a column in two sums: the row reader says what is wrong
    later = {k for parts in sums.values() for k in parts[1:]}
    firsts = {parts[0]: name for name, parts in sums.items()}
    out = []
    for k, c in enumerate(header):
        name = firsts.get(k, c)
        if k not in later and name not in columns.ignore:
            out.append(sums[name] if k in firsts else [k])
    return out


def _summed(parts: list) -> np.ndarray:
    """One column, or the sum of several as ``map_columns`` makes it: empty where all parts are empty
    (``Unfit`` where only some are), else 0.0 + a + b in that order."""
    if len(parts) == 1:
        return parts[0]
    empty = np.stack([np.isnan(a) for a in parts])
    if np.any(empty.any(axis=0) != empty.all(axis=0)):
        raise Unfit
    total = np.zeros(len(parts[0]))
    for a in parts:
        total = total + a
    return total


def _used_columns(cols: _Columns) -> list[int]:
    """The columns of the mapped table that the reader reads (unknown ones ignored are not)."""
    used = [k for k, _ in cols.joint_cols.values()] + list(cols.special.values()) + list(cols.approach_cols.values())
    used += [k for mc in cols.marker_cols.values() for k, _ in mc.values()]
    return sorted(set(used))


def _unknown_note(ignored, other: Table | None, *, exclude: bool = False) -> tuple[str, ...]:
    """The note naming the unknown columns ignored that came from ``other`` (the joint file), or
    with ``exclude`` the others."""
    mine = [c for c in ignored if (other is not None and c in other.header) != exclude]
    return (f"columns robocal does not know, ignored: {', '.join(mine)}",) if mine else ()


def _profile(profile) -> Profile:
    if profile is None:
        return Profile()
    return profile if isinstance(profile, Profile) else read_profile(profile)


def _directives(table: Table):
    """The ``# units:`` and ``# orientation:`` lines before the header."""
    comment_units: dict[str, str] = {}
    comment_orient, orient_text = None, ""
    stated: dict[str, int] = {}
    for line, text in table.comments:
        u = _directive(text, "units")
        if u is not None:
            for key, unit in _comment_units(u, table.source, line).items():
                if key in stated:
                    raise InputError(f"units.{key} stated twice (line {stated[key]}: {comment_units[key]}, line "
                                     f"{line}: {unit}): state each unit once", source=table.source,
                                     where=f"line {line}")
                stated[key], comment_units[key] = line, unit
        o = _directive(text, "orientation")
        if o is not None:
            comment_orient = parse_orientation(o, source=table.source, where=f"line {line}")
            orient_text = f"{o.strip()} (line {line})"
    return comment_units, comment_orient, orient_text


class _Marker(NamedTuple):
    """One marker's columns as both readers take them: ``cols`` part -> (column, SI per file unit),
    the parts of its position's and its orientation's standard deviations (``_sigma_parts``) and its
    orientation convention ((kind, Euler sequence), or None without orientation columns)."""

    name: str
    cols: dict[str, tuple[int, float]]
    sigma: tuple[str, ...]
    orientation: tuple[str, str | None] | None
    sigma_rot: tuple[str, ...]


def _markers(cols: _Columns) -> list[_Marker]:
    """The file's markers, in the order they are read."""
    return [_Marker(mn, cols.marker_cols[mn], _sigma_parts(cols.marker_cols[mn], "sigma", SIGMA_AXES),
                    cols.orientation[mn], _sigma_parts(cols.marker_cols[mn], "sigma_rot", SIGMA_ROT_AXES))
            for mn in cols.markers]


class _PerPose(NamedTuple):
    """The columns of one value per pose besides joints and markers: payload mass (kg), approach
    directions, the set (True: validation) and the series; None where the file has no such column."""

    payload: np.ndarray | None
    approach: np.ndarray | None
    validation: np.ndarray | None
    series: list | None


def _empty_arrays(markers: list[_Marker], n: int):
    """(positions, sigma, rotations, sigma_rot) of ``n`` poses, NaN (unseen) until read; None where the
    file has no such columns."""
    nm = len(markers)
    has_sigma = any(mk.sigma for mk in markers)
    has_rot = any(mk.orientation for mk in markers)
    has_sigma_rot = any(mk.sigma_rot for mk in markers)
    return (np.full((n, nm, 3), np.nan), np.full((n, nm), np.nan) if has_sigma else None,
            np.full((n, nm, 3, 3), np.nan) if has_rot else None, np.full((n, nm), np.nan) if has_sigma_rot else None)


def _parse_rows(rows, cols: _Columns, table: Table, source: str, digest: str, targets: bool = False) -> Measurements:
    """The measurements in ``rows`` ((line, cells) of the table), read cell by cell: a fault is an
    InputError at its line and column."""
    n = len(rows)
    q = np.empty((n, len(cols.joint_names)))
    markers = _markers(cols)
    arrays = _empty_arrays(markers, n)
    special = cols.special
    per_pose = _PerPose(np.empty(n) if "payload_kg" in special else None,
                        np.empty((n, len(cols.joint_names))) if cols.approach_cols else None,
                        np.zeros(n, dtype=bool) if "set" in special else None, [] if "series" in special else None)
    joints = [cols.joint_cols[jn] for jn in cols.joint_names]
    labels = []
    width = len(cols.names)
    for i, (line, row) in enumerate(rows):
        if len(row) != width:
            raise InputError(f"{len(row)} cells where the header has {width} columns",
                             source=source, where=f"line {line}")

        def num(k, *, required=True, row=row, line=line):
            return number_cell(row[k], table, source, line, cols.names[k], required)

        def at(k, line=line):
            return table.cell_where(line, cols.names[k])

        for j, (k, s) in enumerate(joints):
            q[i, j] = num(k) * s
        for m, mk in enumerate(markers):
            _marker_cells(mk, i, m, arrays, num, source, line, at)
        _per_pose_cells(per_pose, i, row, num, cols, source, at)
        label = row[special["pose"]].strip() if "pose" in special else ""
        labels.append(label or f"line {line}")
    if not targets and not np.any(np.isfinite(arrays[0])):
        raise InputError("no marker position in any row", source=source)
    return _measurements(cols, q, arrays, per_pose, tuple(labels), source, digest)


def _marker_cells(mk: _Marker, i: int, m: int, arrays, num, source: str, line, at) -> None:
    """Marker ``m``'s cells in row ``i`` into ``arrays`` (positions, sigma, rotations, sigma_rot); a
    group of cells left empty (the marker not seen) stays NaN. ``at(k)``: where messages place the
    cell of column ``k``."""
    pos, sigma, rot, sigma_rot = arrays
    xyz = _group(mk.cols, POSITION, num, source, line, mk.name, at)
    if xyz is not None:
        pos[i, m] = xyz
        if mk.sigma:
            sigma[i, m] = _sigma(num, mk.cols, mk.sigma, source, at)
    if mk.orientation:
        kind, seq = mk.orientation
        vals = _group(mk.cols, ORIENTATION_PARTS[kind], num, source, line, mk.name, at)
        if vals is not None:
            rot[i, m] = _rotation(kind, seq, vals, source, at(mk.cols[ORIENTATION_PARTS[kind][0]][0]))
            if mk.sigma_rot:
                sigma_rot[i, m] = _sigma(num, mk.cols, mk.sigma_rot, source, at)


def _per_pose_cells(per_pose: _PerPose, i: int, row, num, cols: _Columns, source: str, at) -> None:
    """Row ``i``'s payload, approach directions, set and series into ``per_pose`` (``at(k)``: where
    messages place the cell of column ``k``)."""
    if per_pose.payload is not None:
        per_pose.payload[i] = num(cols.special["payload_kg"])
    if per_pose.approach is not None:
        for j, jn in enumerate(cols.joint_names):
            per_pose.approach[i, j] = num(cols.approach_cols[jn])
            if per_pose.approach[i, j] not in (-1.0, 1.0):
                raise InputError(f"an approach direction is +1 or -1, got {row[cols.approach_cols[jn]]!r}",
                                 source=source, where=at(cols.approach_cols[jn]))
    if per_pose.validation is not None:
        value = row[cols.special["set"]].strip().lower()
        if value not in SETS:
            raise InputError(f"set must be fit or validation, got {row[cols.special['set']]!r}", source=source,
                             where=at(cols.special["set"]))
        per_pose.validation[i] = value == "validation"
    if per_pose.series is not None:
        per_pose.series.append(row[cols.special["series"]].strip())


def _measurements(cols: _Columns, q: np.ndarray, arrays, per_pose: _PerPose, labels: tuple[str, ...], source: str,
                  digest: str) -> Measurements:
    """The record both readers make of what they read (``arrays``: positions, sigma, rotations,
    sigma_rot)."""
    pos, sigma, rot, sigma_rot = arrays
    extra: dict[str, object] = {"joint_kinds": tuple(cols.joint_kinds)}
    if per_pose.validation is not None:
        extra["validation"] = per_pose.validation
    if per_pose.series is not None:
        extra["series"] = np.array(per_pose.series, dtype=str)
    if per_pose.approach is not None:
        extra["approach"] = per_pose.approach
    return Measurements(q=q, positions=pos, marker_names=tuple(cols.markers), joint_names=tuple(cols.joint_names),
                        rotations=rot, sigma=sigma, sigma_rot=sigma_rot, payload_mass=per_pose.payload,
                        labels=labels, source=source, sha256=digest, extra=extra)


def _parse_columns(arrays: dict, cols: _Columns, n: int, first_line: int, source: str, digest: str,
                   targets: bool) -> Measurements:
    """:func:`_parse_rows` over whole columns of ``n`` rows, the first on line ``first_line``
    (``arrays``: column -> float array, NaN where empty, or list of str); ``Unfit`` wherever that
    reader would stop with an error, so that it names the cell."""
    numbers = [a for a in arrays.values() if isinstance(a, np.ndarray)]
    if any(np.any(np.abs(a) > MAX_MAGNITUDE) for a in numbers):
        raise Unfit
    q = np.empty((n, len(cols.joint_names)))
    for j, jn in enumerate(cols.joint_names):
        q[:, j] = _needed(arrays, *cols.joint_cols[jn])
    markers = _markers(cols)
    out = _empty_arrays(markers, n)
    for m, mk in enumerate(markers):
        _marker_column(mk, m, arrays, out)
    per_pose = _per_pose_columns(arrays, cols)
    given = arrays[cols.special["pose"]] if "pose" in cols.special else [""] * n
    labels = tuple(given) if "" not in given else \
        tuple(label or f"line {i + first_line}" for i, label in enumerate(given))
    if not targets and not np.any(np.isfinite(out[0])):
        raise Unfit
    return _measurements(cols, q, out, per_pose, labels, source, digest)


def _needed(arrays, k: int, scale: float = 1.0) -> np.ndarray:
    """Column ``k`` times ``scale``; ``Unfit`` for an empty cell where a value is required."""
    a = arrays[k]
    if np.isnan(a).any():
        raise Unfit
    return a * scale


def _marker_column(mk: _Marker, m: int, arrays, out) -> None:
    """Marker ``m``'s columns into ``out`` (positions, sigma, rotations, sigma_rot)."""
    pos, sigma, rot, sigma_rot = out
    seen = _group_seen(arrays, mk.cols, POSITION)
    pos[seen, m] = _scaled(arrays, mk.cols, POSITION, seen)
    if mk.sigma:
        sigma[seen, m] = _sigma_column(arrays, mk.cols, mk.sigma, seen)
    if mk.orientation:
        kind, seq = mk.orientation
        rseen = _group_seen(arrays, mk.cols, ORIENTATION_PARTS[kind])
        rot[rseen, m] = _rotation_column(kind, seq, _scaled(arrays, mk.cols, ORIENTATION_PARTS[kind], rseen))
        if mk.sigma_rot:
            sigma_rot[rseen, m] = _sigma_column(arrays, mk.cols, mk.sigma_rot, rseen)


def _scaled(arrays, mc, parts, seen) -> np.ndarray:
    """(n_seen, len(parts)) values of a marker's group of ``parts`` at the rows ``seen``, SI."""
    return np.stack([arrays[mc[p][0]][seen] * mc[p][1] for p in parts], axis=-1)


def _rotation_column(kind: str, seq: str | None, vals: np.ndarray) -> np.ndarray:
    """:func:`_rotation` over rows of orientation values; ``Unfit`` for a quaternion of zero norm."""
    if kind == "quat":
        norm = np.linalg.norm(vals, axis=-1)
        if not np.all((norm > 1e-12) & (norm < np.inf)):
            raise Unfit
    return _matrices(kind, seq, vals) if len(vals) else np.empty((0, 3, 3))


def _per_pose_columns(arrays, cols: _Columns) -> _PerPose:
    """:func:`_per_pose_cells` over whole columns; ``Unfit`` for an approach direction other than
    +1 or -1 or a set other than fit or validation."""
    special = cols.special
    payload = _needed(arrays, special["payload_kg"]) if "payload_kg" in special else None
    approach = None
    if cols.approach_cols:
        approach = np.stack([_needed(arrays, cols.approach_cols[jn]) for jn in cols.joint_names], axis=-1)
        if not np.all(np.abs(approach) == 1.0):
            raise Unfit
    validation = None
    if "set" in special:
        value = arrays[special["set"]]
        if not {v.lower() for v in set(value)} <= set(SETS):
            raise Unfit
        validation = np.array([v.lower() == "validation" for v in value], dtype=bool)
    return _PerPose(payload, approach, validation, arrays[special["series"]] if "series" in special else None)


def _group_seen(arrays, mc, parts) -> np.ndarray:
    """The rows where a marker's group of ``parts`` is filled; ``Unfit`` where it is partly filled."""
    empty = np.stack([np.isnan(arrays[mc[p][0]]) for p in parts], axis=-1)
    if np.any(empty.any(axis=-1) != empty.all(axis=-1)):
        raise Unfit
    return ~empty[:, 0]


def _sigma_column(arrays, mc, parts, seen) -> np.ndarray:
    """:func:`_sigma` over the rows ``seen``: positive values, combined as their root mean square."""
    vals = np.stack([arrays[mc[p][0]][seen] for p in parts], axis=-1)
    if not np.all(vals > 0):  # NaN (empty) fails this too
        raise Unfit
    return np.sqrt(np.mean(np.square(vals * np.array([mc[p][1] for p in parts])), axis=-1))


def _approach_to_write(data: Measurements):
    """The approach directions to write: None where the row order gives them (the reader's default)."""
    approach = data.extra.get("approach")
    if approach is not None and np.array_equal(approach, approach_sides(data.q)):
        return None
    return approach


def number_cell(text: str, table: Table, source: str, line, column: str, required: bool) -> float:
    """The number in a cell of ``table`` (in its decimal mark); NaN for an empty cell that is not
    ``required`` (a marker not seen), an InputError naming ``line`` and ``column`` otherwise (the
    file's own name of a column a map renamed)."""
    decimal = table.decimal
    t = text.strip()
    where = table.cell_where(line, column)
    if not t:
        if required:
            raise InputError("empty cell", source=source, where=where)
        return np.nan
    if _NOT_FINITE.match(t):
        raise InputError(f"{t!r} is not a measurement" + ("" if required else "; leave a missing marker's cells "
                                                                              "empty"), source=source, where=where)
    if decimal != ".":
        if "." in t:
            raise InputError(f"expected a number with decimal mark {decimal!r}, got {t!r}{decimal_hint(t, table)}",
                             source=source, where=where)
        t = t.replace(decimal, ".")
    if not _NUMBER.match(t):
        raise InputError(f"expected a number, got {excerpt(text.strip())}{decimal_hint(text, table)}",
                         source=source, where=where)
    v = float(t)
    if not abs(v) <= MAX_MAGNITUDE:
        raise InputError(f"{excerpt(t)} is too large for a measurement (magnitude up to {MAX_MAGNITUDE:g})",
                         source=source, where=where)
    return v


def _group(mc, parts, num, source, line, marker, at):
    """The values of ``parts`` of one marker, or None when all their cells are empty."""
    vals = [num(mc[p][0], required=False) for p in parts]
    empty = [np.isnan(v) for v in vals]
    if all(empty):
        return None
    if any(empty):
        p = parts[empty.index(True)]
        raise InputError(f"empty cell while other {marker} cells of this group are filled; leave all of "
                         f"{', '.join(f'{marker}_{q}' for q in parts)} empty when the marker was not seen",
                         source=source, where=at(mc[p][0]))
    return np.array(vals) * np.array([mc[p][1] for p in parts])


def _sigma_parts(mc, one: str, axes: tuple[str, ...]) -> tuple[str, ...]:
    """The standard-deviation columns of one marker's position (``sigma``, or ``sigma_x/y/z``) or
    orientation (``sigma_rot``, or ``sigma_rx/ry/rz``); () without any."""
    return (one,) if one in mc else axes if axes[0] in mc else ()


def _sigma(num, mc, parts, source, at) -> float:
    """One standard deviation per point (or orientation); per-axis ones combine as their root mean
    square, which gives the weighted residual the same expected size (docs/formats.md)."""
    vals = [_positive(num, mc[p], source, at) for p in parts]
    return float(np.sqrt(np.mean(np.square(vals))))


def _positive(num, col, source, at) -> float:
    k, s = col
    v = num(k)
    if not v > 0:
        raise InputError(f"a standard deviation must be positive, got {v}", source=source,
                         where=at(k))
    return v * s


def _rotation(kind, seq, vals, source, where: str) -> np.ndarray:
    if kind == "quat" and not 1e-12 < np.linalg.norm(vals) < np.inf:
        raise InputError("quaternion of zero norm (or too large)", source=source, where=where)
    return _matrices(kind, seq, vals)


def _matrices(kind: str, seq: str | None, vals) -> np.ndarray:
    """The rotation matrix of orientation values ``vals`` (or one per row of them) in convention ``kind``."""
    from scipy.spatial.transform import Rotation

    if kind == "quat":
        return Rotation.from_quat(vals).as_matrix()  # scalar-last (x, y, z, w): the column names say which
    return Rotation.from_euler("xyz" if kind == "rpy" else seq, vals).as_matrix()


@accepts(data=is_a(Measurements))
def split_sets(data: Measurements) -> tuple[Measurements, Measurements | None]:
    """(fit, validation) from a file's ``set`` column; (data, None) without one. Both keep the
    approach directions of the file's visiting order (``Measurements.with_approach``).

    Parameters
    ----------
    {data}

    Returns
    -------
    (Measurements, Measurements or None)
        The fit poses and the held-out poses (None: no ``set`` column).
    """
    flags = data.extra.get("validation")
    if flags is None:
        return data, None
    data = data.with_approach()

    def part(index):
        sub = data.subset(index)
        return replace(sub, extra={k: v for k, v in sub.extra.items() if k != "validation"})

    fit = part(~flags)
    if not flags.any():
        return fit, None
    if flags.all():
        raise InputError("every row is in the validation set; mark some rows fit", source=data.source, where="set")
    return fit, part(flags)


@accepts(data=is_a(Measurements), model=optional(is_a(RobotModel)), units=UNIT_SYSTEM, orientation=TEXT)
def measurements_to_csv(data: Measurements, *, model: RobotModel | None = None, units: str = "mm-deg",
                        orientation: str = "quat_xyzw") -> str:
    """The CSV text of ``data``: every column carries its unit; orientations in the convention
    ``orientation`` (quaternions, whose columns need no unit, or angles in the angle unit).

    Parameters
    ----------
    {data}
    model : RobotModel, optional
        The model (gives each joint's unit).
    {units}
    orientation : str
        Convention of the written orientation columns.

    Returns
    -------
    str
        The CSV text.
    """
    kind, seq = parse_orientation(orientation)
    orientation = orientation.strip()
    lu, au = parse_units(units)
    joint_names, kinds = _joint_kinds(data, model)
    rot_parts = ("qw", "qx", "qy", "qz") if orientation == "quat_wxyz" else ORIENTATION_PARTS[kind]
    rot_unit = "" if kind == "quat" else f"_{au}"      # a quaternion component has no unit
    approach = _approach_to_write(data)
    buf = io.StringIO()
    if data.rotations is not None:
        buf.write(f"# orientation: {orientation}\n")
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(_csv_header(data, joint_names, kinds, lu, au, [p + rot_unit for p in rot_parts], approach))
    L, A = LENGTH_UNITS[lu], ANGLE_UNITS[au]
    rmask = data.rot_mask if data.rot_mask is not None else np.zeros(data.mask.shape, dtype=bool)
    w.writerows(_csv_rows(data, kinds, L, A, _written_rotations(data, kind, seq, orientation, A, rmask), rmask,
                          approach))
    return buf.getvalue()


def _csv_header(data: Measurements, joint_names, kinds: list[str], lu: str, au: str, rot_names: list[str],
                approach) -> list[str]:
    """The header of the CSV text: every column with its unit (``rot_names``: the orientation's
    parts with theirs)."""
    flags, series = data.extra.get("validation"), data.extra.get("series")
    header = ["pose"] + [f"{jn}_{lu if k == 'length' else au}" for jn, k in zip(joint_names, kinds)]
    for mn in data.marker_names:
        header += _marker_header(data, mn, lu, au, rot_names)
    if data.payload_mass is not None:
        header.append("payload_kg")
    header += [name for name, v in (("set", flags), ("series", series)) if v is not None]
    if approach is not None:
        header += [APPROACH_PREFIX + jn for jn in joint_names]
    return header


def _csv_rows(data: Measurements, kinds: list[str], L: float, A: float, rots: np.ndarray, rmask: np.ndarray,
              approach):
    """The rows under :func:`_csv_header`, one per pose (``rots``: the orientations as written)."""
    flags, series = data.extra.get("validation"), data.extra.get("series")
    for i in range(data.n_poses):
        row = [data.labels[i]]
        row += [_cell(v, L if k == "length" else A) for v, k in zip(data.q[i], kinds)]
        for m in range(len(data.marker_names)):
            row += _marker_row(data, i, m, rots[i, m], rmask[i, m], L, A)
        if data.payload_mass is not None:
            row.append(_cell(data.payload_mass[i]))
        if flags is not None:
            row.append("validation" if flags[i] else "fit")
        if series is not None:
            row.append(str(series[i]))
        if approach is not None:
            row += [f"{int(v):+d}" for v in approach[i]]
        yield row


def _joint_kinds(data: Measurements, model: RobotModel | None) -> tuple[tuple[str, ...], list[str]]:
    """The joints to write and each one's quantity (length or angle): from ``model``, or from the
    file the data were read from."""
    if model is not None:
        kinds = [model.reading_quantities[model.joint_names.index(jn)] for jn in data.joint_names] \
            if data.joint_names else list(model.reading_quantities)
        return data.joint_names or model.joint_names, kinds
    kinds = list(data.extra.get("joint_kinds") or ())
    if not kinds or not data.joint_names:
        raise InputError("the joint types are unknown: pass the model so each joint's unit is known",
                         where="model")
    return data.joint_names, kinds


def _marker_header(data: Measurements, mn: str, lu: str, au: str, rot_names: list[str]) -> list[str]:
    """The columns of marker ``mn``: its position, sigma, orientation (``rot_names``: the parts with
    their unit) and sigma_rot, those the data hold."""
    header = [f"{mn}_{p}_{lu}" for p in POSITION]
    if data.sigma is not None:
        header.append(f"{mn}_sigma_{lu}")
    if data.rotations is not None:
        header += [f"{mn}_{p}" for p in rot_names]
        if data.sigma_rot is not None:
            header.append(f"{mn}_sigma_rot_{au}")
    return header


def _marker_row(data: Measurements, i: int, m: int, rot, rot_seen, L: float, A: float) -> list[str]:
    """The cells of marker ``m`` in pose ``i`` under :func:`_marker_header` (``rot``: the orientation
    as written); empty where it was not measured."""
    seen = data.mask[i, m]
    row = [_cell(v, L) if seen else "" for v in data.positions[i, m]]
    if data.sigma is not None:
        row.append(_cell(data.sigma[i, m], L) if seen else "")
    if data.rotations is not None:
        row += [_cell(v) if rot_seen else "" for v in rot]
        if data.sigma_rot is not None:
            row.append(_cell(data.sigma_rot[i, m], A) if rot_seen else "")
    return row


def _cell(v, s: float = 1.0) -> str:
    """``v`` in the file's unit (``s``: SI per file unit), exact; empty for NaN."""
    return "" if not np.isfinite(v) else repr(float(v) / s)


def _written_rotations(data: Measurements, kind: str, seq: str | None, orientation: str, A: float,
                       rmask: np.ndarray) -> np.ndarray:
    """(n_poses, n_markers, parts) orientations in the convention written (angles in the angle unit
    ``A``); the identity's where none was measured."""
    if data.rotations is None:
        return np.zeros((data.n_poses, len(data.marker_names), 0))
    from scipy.spatial.transform import Rotation

    R = Rotation.from_matrix(np.where(rmask[..., None, None], data.rotations, np.eye(3)).reshape(-1, 3, 3))
    if kind == "quat":
        rots = R.as_quat()                  # (x, y, z, w); scalar_first needs scipy 1.14
        if orientation == "quat_wxyz":
            rots = np.roll(rots, 1, axis=-1)
    else:
        rots = R.as_euler("xyz" if kind == "rpy" else seq) / A
    return rots.reshape(data.n_poses, len(data.marker_names), -1)


@accepts(data=is_a(Measurements), path=PATH, units=UNIT_SYSTEM, force=FLAG, model=optional(is_a(RobotModel)),
         orientation=TEXT)
def write_measurements(data: Measurements, path, *, units: str = "mm-deg", force: bool = False,
                       model: RobotModel | None = None, orientation: str = "quat_xyzw") -> None:
    """Write ``data`` as a measurement CSV in ``units``, atomically; refuse to overwrite unless ``force``.

    Joint units follow each joint's type, from ``model`` or from the file the data were read from.
    ``orientation``: how orientations are written (``quat_xyzw``, ``quat_wxyz``, ``rpy``, ``euler:SEQ``).

    Parameters
    ----------
    {data, path, units, force}
    model : RobotModel, optional
        The model (gives each joint's unit).
    orientation : str
        Convention of the written orientation columns.

    Returns
    -------
    None
    """
    write_texts({path: measurements_to_csv(data, model=model, units=units, orientation=orientation)}, force=force)
