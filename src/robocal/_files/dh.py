"""DH tables in and out as CSV (docs/formats.md): modified DH (our frames, with Hayati's beta) and
classic DH, each column with its unit suffix. Besides the joints a table holds what the forward
kinematics also needs: a ``base`` row (the pose of the table's first frame in the measurement
frame W) and one ``marker`` row per marker (its pose in its frame), as x, y, z and roll, pitch,
yaw (URDF's convention, R = Rz(yaw) Ry(pitch) Rx(roll)); and each joint's limits."""

from __future__ import annotations

import csv
import io
import math
from dataclasses import replace
from typing import Any

import numpy as np

from .._base.arguments import (
    FLAG,
    PATH,
    POSITIVE_OR_INF,
    TEXT,
    UNIT_SYSTEM,
    accepts,
    is_a,
    one_of,
    optional,
)
from .._base.errors import InputError, excerpt, suggest
from .._base.options import MAX_FRAMES, MAX_MARKERS, MAX_MODEL_BYTES
from .._base.spatial import matrix_rpy, matrix_tuple, pose4, rpy_matrix, vector3
from .._base.units import UNITS, parse_units, unit_factors, unit_kind
from .._model.conversion import MDH_TABLE_KINDS, from_standard_dh, mdh_table, to_standard_dh
from .._model.parameters import KIND_QUANTITY
from .._model.robot import Frame, Marker, RobotModel, parallel_beta_frames, serial_model
from .model import FINEST, LARGEST, MAX_MAGNITUDE
from .text import read_text, refuse_other_form, write_texts

PLACEMENT = (("x", "length"), ("y", "length"), ("z", "length"), ("roll", "angle"), ("pitch", "angle"),
             ("yaw", "angle"))
DH_KINDS = (("theta", "angle"), ("d", "length"), ("a", "length"), ("alpha", "angle"))
ROW_KINDS = ("revolute", "prismatic", "fixed", "base", "marker")
# what a table of theta, d, a, alpha means: classic DH, or modified DH in Craig's layout (row i holds
# alpha_{i-1}, a_{i-1}, theta_i, d_i); the columns fit both, so the convention is stated, never guessed
CONVENTIONS = ("classic", "modified")
# Craig's column -> our frame's parameter
CRAIG = (("alpha", "alpha"), ("a", "d"), ("theta", "theta"), ("d", "r"))
# the columns of each form of table: its words, and its numbers with the quantity of each (None: a
# limit, an angle or a length as its joint is)
LIMITS = (("lower", None), ("upper", None))
CLASSIC_COLUMNS = (("name", "joint"), dict(DH_KINDS + LIMITS + PLACEMENT))
MODIFIED_COLUMNS = (("frame", "parent", "joint", "reading", "has_beta"),
                    dict(tuple((k, KIND_QUANTITY[k]) for k in MDH_TABLE_KINDS) + LIMITS + PLACEMENT))


def _placement(X: np.ndarray, names: dict, factors: dict) -> dict:
    vals = list(X[:3, 3]) + list(matrix_rpy(X[:3, :3]))
    return {f"{p}_{names[q]}": float(v) / factors[q] for (p, q), v in zip(PLACEMENT, vals)}


def _limits(model: RobotModel, reading: int | None, names: dict, factors: dict) -> dict:
    out = {f"{b}_{names[q]}": "" for q in ("angle", "length") for b in ("lower", "upper")}
    if reading is not None:
        q = model.reading_quantities[reading]
        lo, hi = model.joint_limits[reading]
        out[f"lower_{names[q]}"], out[f"upper_{names[q]}"] = lo / factors[q], hi / factors[q]
    return out


def _csv(rows: list[dict]) -> str:
    header = list(dict.fromkeys(k for row in rows for k in row))
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    for row in rows:
        # below 1e-12 (mm, m, deg or rad) a value is round-off of the conversion, not a dimension
        w.writerow([repr(0.0 if abs(v) < 1e-12 else v + 0.0) if isinstance(v, float) else v
                    for v in (row.get(k, "") for k in header)])
    return buf.getvalue()


@accepts(model=is_a(RobotModel), units=UNIT_SYSTEM)
def mdh_csv(model: RobotModel, *, units: str = "mm-deg") -> str:
    """The CSV text of the modified-DH table: :func:`mdh_table` per frame with each reading's
    limits on the first frame it drives alone, then the base and marker rows.

    Parameters
    ----------
    {model, units}

    Returns
    -------
    str
        The CSV text.
    """
    names = dict(zip(("length", "angle"), parse_units(units)))
    factors = unit_factors(units)
    first: dict[int, int] = {}
    for i, f in enumerate(model.frames):
        if len(f.coupling) == 1 and f.coupling[0][1] == 1.0:
            first.setdefault(f.coupling[0][0], i)
    owner = {i: k for k, i in first.items()}
    rows = [{**row, **_limits(model, owner.get(i), names, factors)}
            for i, row in enumerate(mdh_table(model, units=units))]
    rows.insert(0, {"frame": "base", "parent": "world", "joint": "base", **_placement(model.X_WB, names, factors)})
    for mk in model.markers:
        rows.append({"frame": mk.name, "parent": model.frames[mk.frame].name, "joint": "marker",
                     **_placement(pose4(np.asarray(mk.rotation), mk.position), names, factors)})
    return _csv(rows)


@accepts(model=is_a(RobotModel), path=PATH, units=UNIT_SYSTEM, force=FLAG)
def write_mdh_csv(model: RobotModel, path, *, units: str = "mm-deg", force: bool = False) -> None:
    """Write :func:`mdh_csv`, atomically; full float precision.

    Parameters
    ----------
    {model, path, units, force}

    Returns
    -------
    None
    """
    write_texts({path: mdh_csv(model, units=units)}, force=force)


@accepts(model=is_a(RobotModel), units=UNIT_SYSTEM, max_offset=optional(POSITIVE_OR_INF))
def dh_csv(model: RobotModel, *, units: str = "mm-deg", max_offset: float | None = None) -> str:
    """The CSV text of the classic DH table of ``model`` (:func:`to_standard_dh`, which refuses
    where nearly parallel axes make it ill-conditioned).

    Parameters
    ----------
    {model, units, max_offset}

    Returns
    -------
    str
        The CSV text of the classic DH table.
    """
    names = dict(zip(("length", "angle"), parse_units(units)))
    factors = unit_factors(units)
    dh = to_standard_dh(model, max_offset=max_offset)
    rows = [{"name": "base", "joint": "base", **_placement(dh.X_W0, names, factors)}]
    for i, r in enumerate(dh.rows):
        rows.append({"name": r["name"], "joint": r["joint"],
                     **{f"{k}_{names[q]}": r[k] / factors[q] for k, q in DH_KINDS},
                     **_limits(model, i, names, factors)})
    rows += [{"name": n, "joint": "marker", **_placement(X, names, factors)} for n, X in dh.markers]
    return "# convention: classic\n" + _csv(rows)


# ----------------------------------------------------------------------------------------------
# in

class _Table:
    """The rows of a DH table file as SI numbers by column base name, with the file named in errors."""

    def __init__(self, path) -> None:
        self.source = str(path)
        text, _ = read_text(path, limit=MAX_MODEL_BYTES)
        refuse_other_form(text, self.source, "a DH table", ("dh", "xml", "json"))
        numbered = [(i, ln) for i, ln in enumerate(text.splitlines(), 1)
                    if ln.strip() and not ln.lstrip().startswith("#")]
        self.convention = None  # a '# convention: classic' line before the header
        for i, ln in enumerate(text.splitlines()[:numbered[0][0] - 1 if numbered else 0], 1):
            body = ln.lstrip().lstrip("#").strip()
            if body.lower().startswith("convention:"):
                self.convention = _convention(body.split(":", 1)[1].strip(), self.source, f"line {i}")
        if not numbered:
            raise InputError("empty table", source=self.source)
        if len(numbered) > MAX_FRAMES + MAX_MARKERS + 2:   # the header, the base row, frames, markers
            raise InputError(f"{len(numbered) - 1:,} rows; a model holds up to {MAX_FRAMES} frames and {MAX_MARKERS} "
                             "markers (docs/formats.md)", source=self.source)
        try:
            parsed = list(csv.reader([ln for _, ln in numbered]))
        except csv.Error as e:
            raise InputError(f"not readable as CSV: {e}", source=self.source) from None
        header = [c.strip() for c in parsed[0]]
        self.header_line = numbered[0][0]
        self.scale: dict[str, list[tuple[int, float, str]]] = {}   # limits have a column per quantity
        self.text: dict[str, int] = {}
        for k, c in enumerate(header):
            base, _, unit = c.rpartition("_")
            kind = unit_kind(unit) if base else None
            if kind is None:
                self.text.setdefault(c, k)
            else:
                self.scale.setdefault(base, []).append((k, UNITS[kind][unit], kind))
        self.rows = [(line, row) for (line, _), row in zip(numbered[1:], parsed[1:])]
        self.header = header

    def where(self, line: int, column: str | None = None) -> str:
        return f"line {line}" + (f", column {column!r}" if column else "")

    def check_columns(self, form: tuple[tuple[str, ...], dict], required: tuple[str, ...]) -> None:
        """Every column one of the ``form``'s (its words, its numbers with the unit of their quantity),
        each once, and the ``required`` ones there; an InputError naming the header's column otherwise."""
        words, numbers = form
        seen: dict[tuple[str, str | None], str] = {}
        for c in filter(None, self.header):     # an empty name: a separator at the end of the header
            detail = self._column_fault(c, words, numbers, seen)
            if detail:
                raise InputError(detail, source=self.source, where=self.where(self.header_line, c))
        for c in required:
            if c not in self.text and c not in self.scale:
                detail = f"no column {c} ({self._named(c, numbers[c])})" if c in numbers else f"no column {c!r}"
                raise InputError(detail, source=self.source, where=self.where(self.header_line))

    def _column_fault(self, c: str, words: tuple[str, ...], numbers: dict, seen: dict) -> str:
        """What is wrong with column ``c`` of a table of ``words`` and ``numbers`` ('' when nothing;
        ``seen``: the columns before it, by base name and quantity)."""
        base, _, unit = c.rpartition("_")
        kind = unit_kind(unit) if base and c not in words else None
        if kind is None and c in numbers:
            return f"{c} needs its unit: {self._named(c, numbers[c])}"
        if (kind is None and c not in words) or (kind is not None and base not in numbers):
            known = list(words) + [f"{n}_{u}" for n, q in numbers.items() for kind in ((q,) if q else UNITS)
                                   for u in UNITS[kind]]
            return f"unknown column {excerpt(c)}{suggest(c, known)}"
        if kind is not None and numbers[base] not in (None, kind):
            return f"{base} is {'an angle' if numbers[base] == 'angle' else 'a length'}: " \
                   f"{self._named(base, numbers[base])}"
        key = (base if kind else c, kind)
        if key in seen:
            return f"column {excerpt(c)} repeats column {seen[key]!r}"
        seen[key] = c
        return ""

    @staticmethod
    def _named(base: str, quantity: str | None) -> str:
        """``"alpha_deg or alpha_rad"``: the names a column of ``quantity`` may have (a limit: either)."""
        units = {"angle": ("deg", "rad"), "length": ("mm", "m")}.get(quantity or "", ("deg", "mm"))
        return " or ".join(f"{base}_{u}" for u in units)

    def get(self, line, row, name: str, default=None, quantity: str | None = None) -> float:
        columns = [(k, s, q) for k, s, q in self.scale.get(name, ()) if quantity in (None, q)]
        if not columns:
            if default is None:
                raise InputError(f"no column {name}", source=self.source, where=self.where(self.header_line))
            return default
        filled = [(k, s, q) for k, s, q in columns if k < len(row) and row[k].strip()]
        k, s, q = (filled or columns)[0]
        cell = row[k].strip() if k < len(row) else ""
        where = self.where(line, self.header[k])
        if not cell:
            if default is None:
                raise InputError("empty cell", source=self.source, where=where)
            return default
        try:
            v = float(cell)
        except ValueError:
            raise InputError(f"expected a number, got {excerpt(cell)}", source=self.source, where=where) from None
        if not math.isfinite(v):
            raise InputError("expected a finite number", source=self.source, where=where)
        if not abs(v * s) < LARGEST[q]:   # beyond it a model file cannot hold the value
            raise InputError(f"{excerpt(cell)} is too large for a robot (magnitude below {MAX_MAGNITUDE:g} in "
                             f"{FINEST[q]})", source=self.source, where=where)
        return v * s

    def word(self, line, row, name: str) -> str:
        if name not in self.text:
            raise InputError(f"no column {name!r}", source=self.source, where=self.where(self.header_line))
        k = self.text[name]
        return row[k].strip() if k < len(row) else ""

    def placement(self, line, row) -> np.ndarray:
        v = [self.get(line, row, p, 0.0) for p, _ in PLACEMENT]
        return pose4(rpy_matrix(v[3:]), v[:3])

    def limits(self, line, row, joint: str) -> tuple[float, float]:
        """A joint's limits from the lower and upper columns of its quantity (an angle for a revolute
        joint); the default +-180 degrees, or 0 to 1 m, where they are empty."""
        quantity = "angle" if joint == "revolute" else "length"
        for b in ("lower", "upper"):
            other = [k for k, _, q in self.scale.get(b, ()) if q != quantity and k < len(row) and row[k].strip()]
            if other:
                raise InputError(f"a {joint} joint's limits are {self._named(b, quantity)}", source=self.source,
                                 where=self.where(line, self.header[other[0]]))
        default = (-math.pi, math.pi) if joint == "revolute" else (0.0, 1.0)
        lo, hi = (self.get(line, row, b, d, quantity) for b, d in zip(("lower", "upper"), default))
        if not lo < hi:
            raise InputError(f"lower limit {excerpt(self.cell(row, 'lower', quantity))} is not below upper limit "
                             f"{excerpt(self.cell(row, 'upper', quantity))}: a joint that cannot move",
                             source=self.source, where=self.where(line))
        return lo, hi

    def cell(self, row, name: str, quantity: str) -> str:
        """The text of the first filled ``name`` cell of ``quantity`` in ``row`` (the default's '' if none)."""
        return next((row[k].strip() for k, _, q in self.scale.get(name, ())
                     if q == quantity and k < len(row) and row[k].strip()), "")


def _rows_by_kind(table: _Table, name_column: str):
    base, joints, markers = None, [], []
    base_line = None
    named: dict[tuple[bool, str], int] = {}     # (a marker?, name) -> its line
    for line, row in table.rows:
        kind = table.word(line, row, "joint")
        name = table.word(line, row, name_column)
        if kind not in ROW_KINDS:
            raise InputError(f"joint must be one of {', '.join(ROW_KINDS)}, got {kind!r}", source=table.source,
                             where=table.where(line, "joint"))
        if not name:
            raise InputError("no name", source=table.source, where=table.where(line, name_column))
        if kind == "base" and base_line is not None:
            raise InputError(f"a second base row (the first is line {base_line}): a table places its first frame "
                             "once", source=table.source, where=table.where(line, "joint"))
        if kind != "base" and (kind == "marker", name) in named:
            raise InputError(f"{'marker ' if kind == 'marker' else ''}{excerpt(name)} already names line "
                             f"{named[kind == 'marker', name]}", source=table.source,
                             where=table.where(line, name_column))
        named[kind == "marker", name] = line
        if kind == "base":
            base, base_line = table.placement(line, row), line
        elif kind == "marker":
            markers.append((line, row, name))
        else:
            joints.append((line, row, name, kind))
    if not joints:
        raise InputError("no joint rows", source=table.source)
    return base, joints, markers


def _convention(text: str, source: str | None, where: str) -> str:
    if text not in CONVENTIONS:
        raise InputError(f"the DH convention is classic or modified, got {text!r}", source=source, where=where)
    return text


@accepts(path=PATH, name=optional(TEXT), convention=optional(one_of(CONVENTIONS)))
def read_dh_table(path, *, name: str | None = None, convention: str | None = None) -> RobotModel:
    """A model from a DH table file: robocal's modified DH (the columns :func:`mdh_csv` writes:
    frame, beta, alpha, d, theta, r, ...), or a table of theta, d, a, alpha.

    Parameters
    ----------
    path : str or Path
        The table (docs/formats.md).
    name : str, optional
        The robot's name (default: the file's name).
    convention : {"classic", "modified"}, optional
        What a theta, d, a, alpha table means: classic DH, or modified DH in Craig's layout (row i
        holds alpha_{i-1}, a_{i-1}, theta_i, d_i). Such a table fits both, so the convention must be
        stated, here or by a ``# convention: classic`` line before the header; both must agree.

    Returns
    -------
    RobotModel
    """
    table = _Table(path)
    name = name or str(path).replace("\\", "/").rsplit("/", 1)[-1].rsplit(".", 1)[0]
    if convention is not None:
        convention = _convention(convention, None, "convention")
        if table.convention not in (None, convention):
            raise InputError(f"the table says convention {table.convention}, the option says {convention}",
                             source=table.source, where="convention")
    stated = convention or table.convention
    if "r" in table.scale and "frame" in table.text:
        table.check_columns(MODIFIED_COLUMNS, ("frame", "parent", "joint"))
        return _modified(table, name)
    if "a" in table.scale:
        table.check_columns(CLASSIC_COLUMNS, ("name", "joint") + tuple(k for k, _ in DH_KINDS))
        if stated is None:
            raise InputError("columns theta, d, a, alpha fit classic DH and modified (Craig's) DH alike: say which, "
                             "with --convention classic|modified (convention=...) or a '# convention: classic' line "
                             "before the header", source=table.source)
        return _classic(table, name) if stated == "classic" else _craig(table, name)
    raise InputError("neither a classic DH table (columns name, joint, theta, d, a, alpha) nor a modified one "
                     "(frame, parent, joint, reading, beta, alpha, d, theta, r, ...)", source=table.source)


def _classic(table: _Table, name: str) -> RobotModel:
    base, joints, markers = _rows_by_kind(table, "name")
    rows, limits = [], []
    for line, row, jname, kind in joints:
        if kind == "fixed":
            raise InputError("a classic DH row is a revolute or prismatic joint", source=table.source,
                             where=table.where(line, "joint"))
        rows.append({"name": jname, "joint": kind, **{k: table.get(line, row, k) for k, _ in DH_KINDS}})
        limits.append(table.limits(line, row, kind))
    mk: list[tuple] = [(mname, X[:3, 3], X[:3, :3]) for mname, X in
          ((m, table.placement(line, row)) for line, row, m in markers)] or [("tool", (0.0, 0.0, 0.0))]
    model = from_standard_dh(rows, name=name, markers=mk, base=base, joint_limits=limits)
    return model.replace(description=f"imported from the classic DH table {table.source}")


def _craig(table: _Table, name: str) -> RobotModel:
    """Modified DH in Craig's layout: row i's alpha and a are along x of the frame before, theta and
    d along its own z, which are our frames' alpha, d, theta and r (docs/conventions.md)."""
    base, joints, markers = _rows_by_kind(table, "name")
    rows, limits = [], []
    for line, row, jname, kind in joints:
        rows.append({"name": jname, "joint": kind, **{ours: table.get(line, row, theirs) for theirs, ours in CRAIG}})
        limits.append(table.limits(line, row, kind) if kind != "fixed" else None)
    X_WB = np.eye(4) if base is None else base
    model = serial_model(name, rows, joint_limits=[lim for lim in limits if lim is not None],
                         base_position=X_WB[:3, 3], base_rotation=X_WB[:3, :3],
                         description=f"imported from the modified (Craig) DH table {table.source}")
    last = len(model.frames) - 1
    mk = [Marker(m, last, vector3(X[:3, 3]), matrix_tuple(X[:3, :3]))
          for m, X in ((m, table.placement(line, row)) for line, row, m in markers)]
    return model.replace(markers=tuple(mk)) if mk else model


def _modified(table: _Table, name: str) -> RobotModel:
    base, joints, markers = _rows_by_kind(table, "frame")
    frame_names = [j[2] for j in joints]
    readings: list[str] = []
    limits: dict[str, tuple[float, float]] = {}
    frames = []
    for i, (line, row, fname, kind) in enumerate(joints):
        parent = table.word(line, row, "parent")
        if parent not in ("base", *frame_names[:i]):
            raise InputError(f"parent {parent!r} is not 'base' or an earlier frame", source=table.source,
                             where=table.where(line, "parent"))
        coupling = _coupling(table, line, row, kind, readings, limits)
        values: dict[str, Any] = {k: table.get(line, row, k, 0.0) for k in MDH_TABLE_KINDS}
        frames.append(Frame(name=fname, joint=kind, parent=-1 if parent == "base" else frame_names.index(parent),
                            coupling=coupling, **values))
    frames = _with_beta(table, joints, frames)
    X_WB = np.eye(4) if base is None else base
    return RobotModel(name=name, frames=tuple(frames), joint_names=tuple(readings),
                      joint_limits=tuple(limits.get(r, (-math.pi, math.pi)) for r in readings),
                      markers=_markers(table, markers, frame_names) or (Marker("tool", len(frames) - 1),),
                      base_position=vector3(X_WB[:3, 3]), base_rotation=matrix_tuple(X_WB[:3, :3]),
                      description=f"imported from the modified DH table {table.source}")


def _coupling(table: _Table, line: int, row, kind: str, readings: list[str],
              limits: dict[str, tuple[float, float]]) -> tuple[tuple[int, float], ...]:
    """A frame's joint readings from its ``reading`` cell (NAME or COEF*NAME terms joined by +), none
    for a fixed frame. A reading met for the first time joins ``readings``; the limits of the first
    frame it drives alone join ``limits``."""
    if kind == "fixed":
        return ()
    coupling: list[tuple[int, float]] = []
    for term in filter(None, (t.strip() for t in table.word(line, row, "reading").split("+"))):
        coef, _, reading = term.rpartition("*")
        try:
            c = float(coef) if coef else 1.0
        except ValueError:
            raise InputError(f"a reading is NAME or COEF*NAME, got {term!r}", source=table.source,
                             where=table.where(line, "reading")) from None
        if reading not in readings:
            readings.append(reading)
        if c == 1.0 and len(coupling) == 0:
            limits.setdefault(reading, table.limits(line, row, kind))
        coupling.append((readings.index(reading), c))
    if not coupling:
        raise InputError("a moving frame needs a reading", source=table.source, where=table.where(line, "reading"))
    return tuple(coupling)


def _with_beta(table: _Table, joints: list, frames: list[Frame]) -> list[Frame]:
    """``frames`` with Hayati's beta where the table says so (``has_beta``), where the axes are nearly
    parallel or where beta is not zero."""
    said = ["has_beta" in table.text and table.word(line, row, "has_beta").lower() == "true"
            for line, row, _, _ in joints]
    flags = parallel_beta_frames(frames)
    return [replace(f, has_beta=flag or s or f.beta != 0.0) for f, flag, s in zip(frames, flags, said)]


def _markers(table: _Table, markers: list, frame_names: list[str]) -> tuple[Marker, ...]:
    """The marker rows as markers on the frames their ``parent`` names."""
    mk = []
    for line, row, mname in markers:
        parent = table.word(line, row, "parent")
        if parent not in frame_names:
            raise InputError(f"marker parent {parent!r} is not a frame", source=table.source,
                             where=table.where(line, "parent"))
        X = table.placement(line, row)
        mk.append(Marker(mname, frame_names.index(parent), vector3(X[:3, 3]), matrix_tuple(X[:3, :3])))
    return tuple(mk)
