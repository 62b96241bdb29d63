"""A folder of seatings (docs/formats.md): a sphere-in-socket campaign as it is recorded, one
headerless joint file per socket and one folder per placement of the plate, the joint order and the
units stated once in a small manifest:

    campaign/
        seatings.yaml          units, joint order, marker, deviation, the plate's spacings
        P1/hole_0.csv          one row per seating of the ball in socket hole_0 at placement P1
        P1/hole_1.csv
        P2/hole_0.csv
        ...

It reads into the same :class:`Contacts` as a contact file: the rows of one socket file are one
socket group, named by the placement's folder and the file's name.
"""

from __future__ import annotations

import fnmatch
import hashlib
import math
import os
import re
from pathlib import Path

import numpy as np

from .._base.errors import InputError, excerpt, suggest
from .._base.options import MAX_CONTACTS, MAX_GROUPS, MAX_MODEL_BYTES
from .._base.units import UNITS, parse_units
from .._model.contacts import Contacts, KnownDistance
from .._model.robot import RobotModel
from .measurements import MAX_MAGNITUDE
from .text import MAX_FILE_BYTES, decode, load_yaml, read_bytes

MANIFEST = "seatings.yaml"
MANIFEST_KEYS = ("units", "joints", "marker", "sigma", "distances", "sockets")
REQUIRED_KEYS = ("units", "joints", "sigma")
# a placement's folder and a socket's file: letters, digits, '_', '-' (a placement also '.' and '+')
PLACEMENT_NAME = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9_.+-]{0,63}")
SOCKET_FILE = re.compile(r"(?P<socket>[A-Za-z0-9_-]{1,64})\.csv")
# bounds of a campaign (docs/formats.md), those of a contact file: socket files (each a socket group,
# three unknowns of the fit) and seatings (rows) over all files; and entries looked at in one folder,
# bytes over all files
MAX_SOCKET_FILES = MAX_GROUPS
MAX_SEATINGS = MAX_CONTACTS
MAX_ENTRIES = 10_000
MAX_CAMPAIGN_BYTES = MAX_FILE_BYTES
# characters of one row: a row of 100 joints written to 30 digits is 3,200
MAX_ROW_CHARS = 10_000
_CELLS = re.compile(r"\s*,\s*|\s+")


def _natural(name: str) -> list:
    """Sort key putting P2 before P10 and hole_2 before hole_10."""
    return [(0, len(t.lstrip("0")), t.lstrip("0")) if t.isdigit() else (1, 0, t) for t in re.split(r"(\d+)", name)
            if t]


def _entries(folder: Path, root: Path) -> list[os.DirEntry]:
    """The entries of ``folder`` (hidden ones left out), bounded, none a link out of ``root``."""
    out: list[os.DirEntry] = []
    try:
        with os.scandir(folder) as it:
            for seen, e in enumerate(it):
                if seen == MAX_ENTRIES:
                    raise InputError(f"more than {MAX_ENTRIES:,} entries; a campaign folder holds up to that many "
                                     "per folder (docs/formats.md)", source=str(folder))
                if e.name.startswith("."):
                    continue
                if e.is_symlink():
                    target = Path(os.path.realpath(e.path))
                    if not target.is_relative_to(root):
                        raise InputError(f"a link out of the campaign folder (to {excerpt(str(target))})",
                                         source=e.path)
                out.append(e)
    except NotADirectoryError:
        raise InputError("is not a folder", source=str(folder)) from None
    except OSError as e:
        raise InputError(f"cannot read the folder: {e.strerror}", source=str(folder)) from None
    return sorted(out, key=lambda e: _natural(e.name))


class _Manifest:
    """What seatings.yaml states, SI."""

    def __init__(self, d, model: RobotModel, source: str) -> None:
        def error(where, message):
            return InputError(message, source=source, where=where)

        if not isinstance(d, dict):
            raise error(None, "expected a mapping (key: value) at the top, with keys " + ", ".join(REQUIRED_KEYS))
        for k in d:
            if k not in MANIFEST_KEYS:
                raise error(str(k), f"unknown key {excerpt(k)}{suggest(str(k), MANIFEST_KEYS)}")
        for k in REQUIRED_KEYS:
            if k not in d:
                raise error(k, f"missing; {MANIFEST} states {', '.join(REQUIRED_KEYS)} (docs/formats.md)")
        length, angle = parse_units(d["units"], source=source, where="units")
        self.length = UNITS["length"][length]
        self.scale = np.array([self.length if k == "length" else UNITS["angle"][angle]
                               for k in model.reading_quantities])
        self.order = self._joints(d["joints"], model, error)
        self.columns = np.array([self.order.index(j) for j in model.joint_names])
        marker = d.get("marker")
        if marker is None and len(model.marker_names) != 1:
            raise error("marker", f"missing; the model has several markers ({', '.join(model.marker_names)})")
        if marker is not None and marker not in model.marker_names:
            raise error("marker", f"{excerpt(marker)} is not a marker of the model"
                                  f"{suggest(str(marker), model.marker_names)}")
        self.marker = model.marker_names[0] if marker is None else marker
        self.sigma = self._length(d["sigma"], "sigma", error)
        spacings = d.get("distances") or []
        if not isinstance(spacings, list):
            raise error("distances", f"expected a list of {{sockets: [A, B], length: L, sigma: S}}, got "
                                     f"{excerpt(spacings)}")
        self.distances = tuple(self._distance(e, f"distances[{i}]", error) for i, e in enumerate(spacings))
        self.sockets = self._pattern(d.get("sockets", "*.csv"), error)

    @staticmethod
    def _pattern(value, error) -> str:
        """The names of a placement's socket files: a pattern of ``*``, ``?`` and ``[...]``, ending in .csv."""
        if not isinstance(value, str) or not value.lower().endswith(".csv") or "/" in value or len(value) > 64:
            raise error("sockets", f"expected a file name pattern ending in .csv (hole_?.csv, *.csv), got "
                                   f"{excerpt(value)}")
        return value

    @staticmethod
    def _joints(joints, model: RobotModel, error) -> tuple[str, ...]:
        """The joint of each column of the joint files (every joint of the model once)."""
        if not isinstance(joints, list) or not all(isinstance(j, str) for j in joints):
            raise error("joints", f"expected the list of the model's joint names in the files' column order, got "
                                  f"{excerpt(joints)}")
        for i, j in enumerate(joints):
            if j not in model.joint_names:
                raise error(f"joints[{i}]", f"{excerpt(j)} is not a joint of the model"
                                            f"{suggest(j, model.joint_names)}")
            if j in joints[:i]:
                raise error(f"joints[{i}]", f"joint {j!r} given twice")
        missing = [j for j in model.joint_names if j not in joints]
        if missing:
            raise error("joints", f"joint {missing[0]!r} is missing; every joint of the model is one column")
        return tuple(joints)

    def _length(self, value, where, error) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value <= MAX_MAGNITUDE:
            raise error(where, f"expected a positive number (in the length unit), got {excerpt(value)}")
        return float(value) * self.length

    def _distance(self, entry, where, error) -> KnownDistance:
        keys = ("sockets", "length", "sigma")
        if not isinstance(entry, dict) or set(entry) != set(keys):
            raise error(where, f"expected {{sockets: [A, B], length: L, sigma: S}}, got {excerpt(entry)}")
        pair = entry["sockets"]
        if not (isinstance(pair, list) and len(pair) == 2 and all(isinstance(s, str) for s in pair)
                and pair[0] != pair[1]):
            raise error(f"{where}.sockets", f"expected two different socket names, got {excerpt(pair)}")
        return KnownDistance(pair[0], pair[1], self._length(entry["length"], f"{where}.length", error),
                             self._length(entry["sigma"], f"{where}.sigma", error))


def _number(cell: str, source: str, where: str) -> float:
    try:
        v = float(cell)
    except ValueError:
        raise InputError(f"expected a number, got {excerpt(cell)}", source=source, where=where) from None
    if not math.isfinite(v):
        raise InputError(f"not a finite number: {excerpt(cell)}", source=source, where=where)
    if abs(v) > MAX_MAGNITUDE:
        raise InputError(f"too large: {excerpt(cell)} (magnitude up to {MAX_MAGNITUDE:g})", source=source,
                         where=where)
    return v


def _joint_rows(text: str, source: str, joints: tuple[str, ...], room: int) -> list[tuple[int, list[float]]]:
    """(line number, readings in the file's column order) of each seating; no header, no blank cells."""
    n = len(joints)
    if text.count("\n") > room:
        raise InputError(f"the campaign holds more than {MAX_SEATINGS:,} seatings; a folder of seatings holds "
                         "up to that many (docs/formats.md)", source=source)
    lines = text.split("\n")                # counted before it is split; a '\r' ending is stripped
    out: list[tuple[int, list[float]]] = []
    for k, line in enumerate(lines, start=1):
        if not line.strip():
            continue
        if len(line) > MAX_ROW_CHARS:
            raise InputError(f"a row of {len(line):,} characters; a joint file's rows hold up to {MAX_ROW_CHARS:,}",
                             source=source, where=f"line {k}")
        cells = _CELLS.split(line.strip())
        if not out and not any(_is_number(c) for c in cells):
            raise InputError(f"a header ({excerpt(line.strip())}): joint files have no header; {MANIFEST}'s "
                             "'joints' gives the column order", source=source, where=f"line {k}")
        if len(cells) != n:
            raise InputError(f"{len(cells)} values for {n} joints (the joint order of {MANIFEST})", source=source,
                             where=f"line {k}")
        out.append((k, [_number(c, source, f"line {k}, column {i + 1} ({joints[i]})") for i, c in enumerate(cells)]))
    if not out:
        raise InputError("no seating (an empty file)", source=source)
    return out


def _is_number(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True


def read_seatings(path, model: RobotModel) -> Contacts:
    """Read a folder of seatings for ``model`` (docs/formats.md); SI out.

    Parameters
    ----------
    path : str or os.PathLike
        The campaign's folder: its ``seatings.yaml`` and one folder per placement holding one joint
        file per socket.
    model : RobotModel
        The robot; its joint and marker names are what the manifest names.

    Returns
    -------
    Contacts
        One socket group per socket file, placements and sockets in natural order (P2 before P10),
        rows in file order.
    """
    folder = Path(path)
    root = Path(os.path.realpath(folder))
    manifest_path = folder / MANIFEST
    if not manifest_path.is_file():
        raise InputError(f"no {MANIFEST}: a folder of seatings states its units and joint order there "
                         "(docs/formats.md)", source=str(folder))
    if not Path(os.path.realpath(manifest_path)).is_relative_to(root):
        raise InputError("a link out of the campaign folder", source=str(manifest_path))
    raw = read_bytes(manifest_path, limit=MAX_MODEL_BYTES)
    digest = hashlib.sha256()
    digest.update(hashlib.sha256(raw).digest())
    manifest = _Manifest(load_yaml(decode(raw, str(manifest_path)), str(manifest_path)), model, str(manifest_path))
    files, skipped = _socket_files(folder, root, manifest.sockets)
    q: list[list[float]] = []
    target: list[str] = []
    placement: list[str] = []
    labels: list[str] = []
    size = sum(os.stat(f).st_size for _, _, f in files)
    if size > MAX_CAMPAIGN_BYTES:
        raise InputError(f"the joint files hold {size:,} bytes; a folder of seatings holds up to "
                         f"{MAX_CAMPAIGN_BYTES:,} (docs/formats.md)", source=str(folder))
    for name, socket, file in files:
        source = str(file)
        data = read_bytes(file)
        digest.update(f"{name}/{file.name}\0".encode() + hashlib.sha256(data).digest())
        rows = _joint_rows(decode(data, source), source, manifest.order, MAX_SEATINGS - len(q))
        q += [r for _, r in rows]
        labels += [f"{name}/{file.name} line {k}" for k, _ in rows]
        target += [socket] * len(rows)
        placement += [name] * len(rows)
    sockets = set(target)
    for i, d in enumerate(manifest.distances):
        for s in (d.a, d.b):
            if s not in sockets:
                raise InputError(f"socket {s!r} has no file in any placement{suggest(s, sorted(sockets))}",
                                 source=str(manifest_path), where=f"distances[{i}].sockets")
    n = len(q)
    return Contacts(q=np.array(q)[:, manifest.columns] * manifest.scale, marker=(manifest.marker,) * n,
                    kind=("socket",) * n, target=tuple(target), placement=tuple(placement),
                    sigma=np.full(n, manifest.sigma), distances=manifest.distances, joint_names=model.joint_names,
                    labels=tuple(labels), source=str(folder), sha256=digest.hexdigest(),
                    notes=_read_notes(files, skipped))


def _read_notes(files, skipped: list[str]) -> tuple[str, ...]:
    """What the reader tells the user: the sockets read per placement, the files it skipped."""
    per: dict[str, list[str]] = {}
    for name, socket, _ in files:
        per.setdefault(name, []).append(socket)
    notes = ["sockets read: " + "; ".join(f"{p} {', '.join(s)}" for p, s in per.items())]
    if skipped:
        shown = ", ".join(skipped[:8]) + (f" and {len(skipped) - 8} more" if len(skipped) > 8 else "")
        notes.append(f"{len(skipped)} file(s) not socket files, skipped: {shown}")
    return tuple(notes)


def _socket_files(folder: Path, root: Path, pattern: str) -> tuple[list[tuple[str, str, Path]], list[str]]:
    """(placement, socket, path) of every socket file (the files of a placement folder whose names match
    ``pattern``), placements and sockets in natural order; and the files of placement folders skipped
    (notes, the robot's own pose files: anything that does not match)."""
    out: list[tuple[str, str, Path]] = []
    skipped: list[str] = []
    placements = 0
    for e in _entries(folder, root):
        if not e.is_dir():
            if e.name.lower().endswith(".csv"):
                raise InputError("a joint file outside a placement folder; the campaign holds one folder per "
                                 "placement, each holding one file per socket (docs/formats.md)", source=e.path)
            continue                                   # seatings.yaml, a README: not seatings
        if not PLACEMENT_NAME.fullmatch(e.name):
            raise InputError("a placement folder's name is letters, digits, '_', '-', '.', '+' (up to 64)",
                             source=e.path)
        placements += 1
        found = _placement_files(e, root, pattern, out, skipped)
        if not found:
            raise InputError(f"no socket file ({pattern}) in this placement folder", source=e.path)
    if not placements:
        raise InputError("no placement folder: a folder of seatings holds one folder per placement, each holding "
                         "one file per socket (docs/formats.md)", source=str(folder))
    return out, skipped


def _placement_files(e: os.DirEntry, root: Path, pattern: str, out: list, skipped: list) -> int:
    """Add a placement folder's socket files to ``out`` and the others to ``skipped``; how many found."""
    found = 0
    for f in _entries(Path(e.path), root):
        if not fnmatch.fnmatchcase(f.name, pattern):
            skipped.append(f"{e.name}/{f.name}")
            continue
        m = SOCKET_FILE.fullmatch(f.name)
        if not m:
            raise InputError("not a socket file: a socket file is named SOCKET.csv (SOCKET of letters, digits, "
                             "'_', '-')", source=f.path)
        if not f.is_file():
            raise InputError("not a regular file (a folder, a FIFO, a device...): a socket's seatings are read from "
                             "a file", source=f.path)
        if len(out) == MAX_SOCKET_FILES:
            raise InputError(f"more than {MAX_SOCKET_FILES:,} socket files; a folder of seatings holds up to "
                             "that many (docs/formats.md)", source=str(e.path))
        out.append((e.name, m["socket"], Path(f.path)))
        found += 1
    return found
