"""The contact file (CSV, docs/formats.md): joint-only recordings grouped by placement and target,
with the fixture's known facts (socket spacings, ball-bar lengths, known planes) as directives.

    # units: length=mm angle=deg
    # distance: A B 200.000 sigma=0.002
    # bar: bar200 200.000 sigma=0.002
    # plane: table normal=0,0,1 offset=0
    # sigma: 0.010
    placement,target,kind,marker,j1,j2,...,sigma

Units are never guessed: the ``units`` directive is required. Joint columns carry the model's joint
names; ``marker`` may be left out when the model has one marker; ``sigma`` (per row) may be left out
when the ``sigma`` directive states one for every row.
"""

from __future__ import annotations

import csv
import difflib
import io
import os
import re
from dataclasses import replace

import numpy as np

from .._base.arguments import (
    FLAG,
    PATH,
    UNIT_SYSTEM,
    accepts,
    is_a,
)
from .._base.errors import InputError, suggest
from .._base.options import MAX_CONTACTS, MAX_DIRECTIVES, MAX_GROUPS
from .._base.spatial import vector3
from .._base.units import UNITS, check_unit
from .._model.contacts import CONTACT_KINDS, Contacts, KnownDistance, KnownPlane
from .._model.robot import RobotModel
from .measurements import MAX_MAGNITUDE
from .seatings import MANIFEST, read_seatings
from .table import Table, Unfit, read_columns, scan_rows
from .text import read_text, refuse_other_form

REQUIRED = ("placement", "target", "kind")
DIRECTIVES = ("units", "distance", "bar", "plane", "sigma")


def _options(words, source, where) -> dict:
    """``key=value`` words as a dict."""
    out = {}
    for w in words:
        key, sep, value = w.partition("=")
        if not sep:
            raise InputError(f"expected key=value, got {w!r}", source=source, where=where)
        out[key] = value
    return out


def _float(text, what, source, where) -> float:
    try:
        v = float(text)
    except (TypeError, ValueError):
        raise InputError(f"{what} is not a number: {text!r}", source=source, where=where) from None
    if not np.isfinite(v):
        raise InputError(f"{what} is not a finite number: {text!r}", source=source, where=where)
    if not abs(v) <= MAX_MAGNITUDE:  # 1e300 of a length overflows the fit's squares into NaN
        raise InputError(f"{what} is too large: {text!r} (magnitude up to {MAX_MAGNITUDE:g})", source=source,
                         where=where)
    return v


class _Facts:
    """What the directives state, SI."""

    def __init__(self) -> None:
        self.units: dict = {}
        self.distances: list[KnownDistance] = []
        self.planes: list[KnownPlane] = []
        self.bars: dict[str, tuple[float, float]] = {}
        self.sigma: float | None = None

    def add(self, name: str, body: str, source: str, where: str) -> None:
        words = body.replace(",", " ").split() if name == "units" else body.split()
        if name == "units":
            if self.units:
                raise InputError("a second units directive: state the units once", source=source, where=where)
            for k, v in _options(words, source, where).items():
                if k not in UNITS:
                    raise InputError(f"expected '# units: length=mm angle=deg', got {k!r}", source=source, where=where)
                self.units[k] = UNITS[k][check_unit(v, k, source=source, where=where)]
            return
        mm = self._length_unit(source, where)
        if name == "sigma":
            self.sigma = self._positive(words[0] if words else "", "sigma", mm, source, where)
        elif name == "distance":
            if len(words) != 4:
                raise InputError("expected '# distance: SOCKET SOCKET LENGTH sigma=S'", source=source, where=where)
            s = _options(words[3:], source, where).get("sigma")
            length = self._positive(words[2], "length", mm, source, where)
            self.distances.append(KnownDistance(words[0], words[1], length,
                                                self._positive(s, "sigma", mm, source, where)))
        elif name == "bar":
            if len(words) != 3:
                raise InputError("expected '# bar: NAME LENGTH sigma=S'", source=source, where=where)
            s = _options(words[2:], source, where).get("sigma")
            self.bars[words[0]] = (self._positive(words[1], "length", mm, source, where),
                                   self._positive(s, "sigma", mm, source, where))
        else:
            self.planes.append(self._plane(words, mm, source, where))

    def _length_unit(self, source, where) -> float:
        if "length" not in self.units:
            raise InputError("the units directive ('# units: length=mm angle=deg') must come first", source=source,
                             where=where)
        return self.units["length"]

    @staticmethod
    def _positive(text, what, factor, source, where) -> float:
        v = _float(text, what, source, where)
        if v <= 0:
            raise InputError(f"{what} must be positive, got {text}", source=source, where=where)
        return v * factor

    @staticmethod
    def _plane(words, factor, source, where) -> KnownPlane:
        opts = _options(words[1:], source, where) if words else {}
        if not words or set(opts) != {"normal", "offset"}:
            raise InputError("expected '# plane: NAME normal=NX,NY,NZ offset=D'", source=source, where=where)
        n = np.array([_float(v, "normal", source, where) for v in opts["normal"].split(",")])
        if len(n) != 3 or not np.linalg.norm(n) > 0:
            raise InputError("a plane's normal has three components, not all zero", source=source, where=where)
        n = n / np.linalg.norm(n)
        offset = _float(opts["offset"], "offset", source, where) * factor
        return KnownPlane(words[0], vector3(n), offset)


@accepts(path=PATH, model=is_a(RobotModel))
def read_contacts(path, model: RobotModel) -> Contacts:
    """Read a contact file for ``model`` (its joints and markers name the columns), or a folder of
    seatings (one joint file per socket, one folder per placement, ``seatings.yaml``), given as the
    folder or as its ``seatings.yaml``; SI out.

    Parameters
    ----------
    path : str or os.PathLike
        The contact file, or the folder of seatings or its ``seatings.yaml`` (docs/formats.md).
    {model}

    Returns
    -------
    Contacts
        The recordings, SI.
    """
    if os.path.isdir(path):
        return read_seatings(path, model)
    if os.path.basename(path) == MANIFEST and os.path.isfile(path):      # a folder's manifest names the folder
        return read_seatings(os.path.dirname(path) or os.curdir, model)
    text, digest = read_text(path, lines=MAX_CONTACTS + MAX_DIRECTIVES + 1)
    source = str(path)
    facts, lines, body_start = _head(text, model, source)
    body = "\n".join(lines[body_start:])
    try:
        return _compiled(body, body_start + 1, model, facts, source, digest)
    except Unfit as e:  # the row reader reads the file or names its fault
        why = (f"reading {source}: read row by row, not by the compiled parser: {e.why}",)
    try:
        rows = list(csv.reader(io.StringIO(body)))
    except csv.Error as e:
        raise InputError(f"not readable as CSV: {e}", source=source) from None
    header = [h.strip() for h in rows[0]]
    contacts = _rows(rows[1:], header, body_start + 1, model, facts, source, digest)
    return replace(contacts, notes=contacts.notes + why)


def _meant_directive(word: str) -> str | None:
    """The directive a comment's ``word:`` most likely misspells (a socket plate's spacing is a
    ``distance``), or None for a comment of its own."""
    if word in ("spacing", "spacings"):
        return "distance"
    close = difflib.get_close_matches(word, DIRECTIVES, n=1, cutoff=0.85)   # not "plate" for "plane"
    return close[0] if close else None


def _head(text: str, model: RobotModel, source: str) -> tuple[_Facts, list[str], int]:
    """A contact file's directives, its lines and the index of its header line, checked: a file of
    another kind (``refuse_other_form``) or without the columns of contacts named so, the units stated, the
    bounds kept."""
    refuse_other_form(text, source, "a contact file", ("contacts",))
    facts = _Facts()
    lines = text.splitlines()
    body_start = 0
    for i, line in enumerate(lines):
        stripped = line.strip()
        if stripped and not stripped.startswith("#"):
            body_start = i
            break
        name, colon, rest = stripped.lstrip("#").strip().partition(":")
        word = name.strip().lower()
        if colon and word in DIRECTIVES:
            facts.add(word, rest.strip(), source, f"line {i + 1}")
        elif colon and (close := _meant_directive(word)):
            raise InputError(f"unknown directive {word!r}; did you mean {close!r}? (a comment that reads as a "
                             "directive is refused rather than ignored)", source=source, where=f"line {i + 1}")
    else:
        raise InputError("no header row", source=source)
    if not {c.strip().strip('"').lower() for c in re.split(r"[,;\t]", lines[body_start])} & set(REQUIRED):
        raise InputError(f"none of the columns {', '.join(REQUIRED)}: not a contact file (measurements of points are "
                         "given after the model, not as the contacts)", source=source, where="header")
    if "angle" not in facts.units and "angle" in model.reading_quantities:
        raise InputError("the units directive must give the angle unit of the joint readings "
                         "('# units: length=mm angle=deg')", source=source)
    if len(lines) - body_start > MAX_CONTACTS + 1 or body_start > MAX_DIRECTIVES:
        what = ("rows", len(lines) - body_start - 1, MAX_CONTACTS) if body_start <= MAX_DIRECTIVES else \
            ("lines before the header", body_start, MAX_DIRECTIVES)
        raise InputError(f"{what[1]:,} {what[0]}; a contact file holds up to {what[2]:,} (docs/formats.md)",
                         source=source)
    return facts, lines, body_start


def _compiled(body: str, first_line: int, model: RobotModel, facts: _Facts, source: str, digest: str) -> Contacts:
    """The contacts in ``body`` (the header, on line ``first_line``, and the rows) parsed by numpy's
    compiled text reader; ``Unfit`` wherever :func:`_rows` would read them otherwise or stop."""
    head_line = body.split("\n", 1)[0]
    header = [h.strip() for h in head_line.split(",")]
    if '"' in head_line:
        raise Unfit("quoted cells")
    try:
        col = _columns(header, model, facts, source)
    except InputError:
        raise Unfit from None  # the row reader names it, after any fault among the rows it meets first
    raw = body.encode()
    head = Table(header=tuple(header), rows=(), source=source, sep=",", decimal=".")
    scan = scan_rows(raw, head)
    texts = ("placement", "target", "kind", "marker", "label")
    cells = read_columns(raw, head, scan, {i: "text" if h in texts else "number" for h, i in col.items()})
    n = scan.n_rows
    kind, target, placement = (cells[col[h]] for h in ("kind", "target", "placement"))
    marker = cells[col["marker"]] if "marker" in col else [model.marker_names[0]] * n
    q = np.column_stack([cells[col[j]] for j in model.joint_names])
    sigma = cells[col["sigma"]] if "sigma" in col else np.full(n, facts.sigma)
    if not (set(kind) <= set(CONTACT_KINDS) and set(marker) <= set(model.marker_names)
            and np.all(np.abs(q) <= MAX_MAGNITUDE) and np.all((sigma > 0) & (sigma <= MAX_MAGNITUDE))):
        raise Unfit  # a cell the row reader refuses, naming it
    if "sigma" in col:
        if "length" not in facts.units:
            raise Unfit
        sigma = sigma * facts.units["length"]
    lines = [f"line {first_line + 1 + k}" for k in range(n)]
    labels = [label or line for label, line in zip(cells[col["label"]], lines)] if "label" in col else lines
    return _contacts(q, marker, kind, target, placement, sigma, labels, model, facts, source, digest)


def _columns(header, model: RobotModel, facts: _Facts, source: str) -> dict:
    col = {h: i for i, h in enumerate(header)}
    known = REQUIRED + model.joint_names + ("marker", "sigma", "label")
    unknown = [h for h in header if h not in known]
    for name in REQUIRED + model.joint_names:
        if name not in col:
            close = difflib.get_close_matches(name, unknown, n=1)
            hint = f"; is {close[0]!r} it?" if close else ""
            raise InputError(f"column {name!r} is missing (columns: {', '.join(header)}){hint}", source=source,
                             where="header")
    if unknown:
        raise InputError(f"unknown column {unknown[0]!r}{suggest(unknown[0], known)}", source=source, where="header")
    if "marker" not in col and len(model.marker_names) != 1:
        raise InputError("column 'marker' is missing and the model has several markers", source=source, where="header")
    if "sigma" not in col and facts.sigma is None:
        raise InputError("neither a 'sigma' column nor a '# sigma:' directive states the contacts' deviation",
                         source=source, where="header")
    return col


def _rows(rows, header, first_line, model: RobotModel, facts: _Facts, source: str, digest: str) -> Contacts:
    col = _columns(header, model, facts, source)
    q, marker, kind, target, placement, sigma, labels = [], [], [], [], [], [], []
    for k, row in enumerate(rows):
        line = first_line + 1 + k
        where = f"line {line}"
        if not row or not any(c.strip() for c in row):
            continue
        if len(row) != len(header):
            raise InputError(f"{len(row)} fields for {len(header)} columns", source=source, where=where)
        cell = {h: row[i].strip() for h, i in col.items()}
        if cell["kind"] not in CONTACT_KINDS:
            raise InputError(f"kind {cell['kind']!r} is not one of {', '.join(CONTACT_KINDS)}", source=source,
                             where=f"{where}, column 'kind'")
        m = cell.get("marker", model.marker_names[0])
        if m not in model.marker_names:
            raise InputError(f"marker {m!r} is not in the model", source=source, where=f"{where}, column 'marker'")
        q.append([_float(cell[j], f"joint {j}", source, f"{where}, column {j!r}") for j in model.joint_names])
        s = facts.sigma if "sigma" not in col else \
            _Facts._positive(cell["sigma"], "sigma", facts._length_unit(source, where), source,
                             f"{where}, column 'sigma'")
        marker.append(m)
        kind.append(cell["kind"])
        target.append(cell["target"])
        placement.append(cell["placement"])
        sigma.append(s)
        labels.append(cell.get("label") or where)
    if not q:
        raise InputError("no contact rows", source=source)
    return _contacts(np.array(q), marker, kind, target, placement, np.array(sigma), labels, model, facts, source,
                     digest)


def _contacts(q: np.ndarray, marker, kind, target, placement, sigma: np.ndarray, labels, model: RobotModel,
              facts: _Facts, source: str, digest: str) -> Contacts:
    """The record both readers make of the rows read (``q`` in the file's units, ``sigma`` SI)."""
    scale = np.array([facts.units.get("angle", 1.0) if k == "angle" else facts.units["length"]
                      for k in model.reading_quantities])
    groups = len(set(zip(placement, target)))
    if groups > MAX_GROUPS:  # each group adds unknowns to the fit: its cost grows with their square
        raise InputError(f"{groups:,} groups (placement, target); a contact file holds up to {MAX_GROUPS:,} "
                         "(docs/formats.md)", source=source)
    _known_targets(facts, kind, target, source)
    return Contacts(q=q * scale, marker=tuple(marker), kind=tuple(kind), target=tuple(target),
                    placement=tuple(placement), sigma=sigma, distances=tuple(facts.distances),
                    planes=tuple(facts.planes), bars=facts.bars, joint_names=model.joint_names,
                    labels=tuple(labels), source=source, sha256=digest)


def _known_targets(facts: _Facts, kind, target, source: str) -> None:
    """Every directive names something the rows touch."""
    touched = {k: {t for kk, t in zip(kind, target) if kk == k} for k in CONTACT_KINDS}
    for d in facts.distances:
        for s in (d.a, d.b):
            if s not in touched["socket"]:
                raise InputError(f"the distance {d.a}-{d.b} names socket {s!r}, which no socket row touches",
                                 source=source)
    for name in facts.bars:
        if name not in touched["bar"]:
            raise InputError(f"ball bar {name!r} is stated but no bar row uses it", source=source)
    for p in facts.planes:
        if p.name not in touched["plane"]:
            raise InputError(f"plane {p.name!r} is stated but no plane row touches it", source=source)


@accepts(contacts=is_a(Contacts), model=is_a(RobotModel), units=UNIT_SYSTEM)
def contacts_to_csv(contacts: Contacts, model: RobotModel, *, units: str = "mm-deg") -> str:
    """The text of a contact file holding ``contacts`` (SI) in ``units`` ("length-angle").

    Parameters
    ----------
    {contacts, model, units}

    Returns
    -------
    str
        The CSV text.
    """
    from .._base.units import unit_factors

    f = unit_factors(units)
    length, angle = units.split("-")
    scale = np.array([f[k] for k in model.reading_quantities])
    out = ["# robocal contacts", f"# units: length={length} angle={angle}"]
    out += [f"# distance: {d.a} {d.b} {d.length / f['length']:.6f} sigma={d.sigma / f['length']:.6g}"
            for d in contacts.distances]
    out += [f"# bar: {n} {v / f['length']:.6f} sigma={s / f['length']:.6g}" for n, (v, s) in contacts.bars.items()]
    out += [f"# plane: {p.name} normal={','.join(f'{v:.12g}' for v in p.normal)} offset={p.offset / f['length']:.9g}"
            for p in contacts.planes]
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["placement", "target", "kind", "marker", *model.joint_names, "sigma"])
    for i in range(contacts.n_rows):
        w.writerow([contacts.placement[i], contacts.target[i], contacts.kind[i], contacts.marker[i],
                    *(f"{v:.9f}" for v in contacts.q[i] / scale), f"{contacts.sigma[i] / f['length']:.6g}"])
    return "\n".join(out) + "\n" + buf.getvalue()


@accepts(contacts=is_a(Contacts), path=PATH, model=is_a(RobotModel), units=UNIT_SYSTEM, force=FLAG)
def write_contacts(contacts: Contacts, path, model: RobotModel, *, units: str = "mm-deg", force: bool = False) -> None:
    """Write ``contacts`` as a contact file (refuses to overwrite unless ``force``).

    Parameters
    ----------
    {contacts, path, model, units, force}

    Returns
    -------
    None
    """
    from .text import write_texts

    write_texts({path: contacts_to_csv(contacts, model, units=units)}, force=force)
