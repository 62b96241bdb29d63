"""Instrument profiles: how one instrument's or controller's exports are laid out, written once.

A profile is a small YAML file (docs/formats.md) holding what would otherwise be options on every
run: the separator and decimal mark, the units and orientation convention of columns without a
suffix, the column map (renames and ignored columns), what to do with unknown columns, and the key
column that joins a joint-readings file to the instrument's.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from .._base.arguments import (
    PATH,
    TEXT,
    accepts,
)
from .._base.errors import InputError, excerpt, suggest
from .._base.options import MAX_MODEL_BYTES
from .._base.units import parse_units
from .table import ColumnMap, check_decimal, parse_separator
from .text import load_yaml, read_text, refuse_other_form

PROFILE_VERSION = 1
PROFILE_KEYS = ("robocal_profile", "name", "sep", "decimal", "units", "orientation", "columns", "ignore",
                "unknown", "key", "header")
# a column mapped to one of these is dropped
IGNORE_WORDS = (None, "ignore")


@dataclass(frozen=True)
class Profile:
    """What a profile file says; None where it says nothing (the reader's defaults then apply)."""

    name: str = ""
    sep: str | None = None
    decimal: str | None = None
    units: str | None = None
    orientation: str | None = None
    columns: ColumnMap = field(default_factory=ColumnMap)
    key: str | None = None
    header: tuple[str, ...] | None = None

    def options(self, *, units=None, sep=None, decimal=None, orientation=None, columns=None, unknown=None,
                key=None, header=None) -> dict:
        """The reading options: those given here over the profile's."""
        given = column_map(columns) if columns is not None else None
        cmap = self.columns.merged(given)
        if unknown is not None:
            cmap = ColumnMap(cmap.rename, cmap.ignore, unknown)
        pick = {"units": (units, self.units), "sep": (sep, self.sep), "decimal": (decimal, self.decimal),
                "orientation": (orientation, self.orientation), "key": (key, self.key),
                "header": (tuple(header) if header is not None else None, self.header)}
        out = {k: a if a is not None else b for k, (a, b) in pick.items()}
        out["columns"] = cmap
        return out


def column_map(columns, *, unknown: str | None = None) -> ColumnMap:
    """A ColumnMap from a ColumnMap or a mapping {file column: robocal column, or None/"ignore"}."""
    if isinstance(columns, ColumnMap):
        return columns if unknown is None else ColumnMap(columns.rename, columns.ignore, unknown)
    if not isinstance(columns, dict):
        raise InputError(f"expected a mapping of file column to robocal column, got {excerpt(columns)}",
                         where="columns")
    rename, ignore = {}, set()
    for k, v in columns.items():
        if v in IGNORE_WORDS:
            ignore.add(str(k))
        elif isinstance(v, str) and v.strip():
            rename[str(k)] = v.strip()
        else:
            raise InputError(f"expected a column name or 'ignore', got {excerpt(v)}", where=f"columns.{k}")
    return ColumnMap(rename, frozenset(ignore), unknown or "refuse")


@accepts(source=TEXT)
def profile_from_dict(d, *, source: str = "<dict>") -> Profile:
    """A Profile from the parsed profile file ``d``.

    Parameters
    ----------
    d : dict
        A profile as its YAML file holds it.
    {source}

    Returns
    -------
    Profile
        The profile.
    """
    if not isinstance(d, dict):
        raise InputError("expected a mapping (key: value) at the top", source=source, where=None)
    for k in d:
        if k not in PROFILE_KEYS:
            raise InputError(f"unknown key {k!r}{suggest(str(k), PROFILE_KEYS)}", source=source, where=str(k))
    if d.get("robocal_profile") != PROFILE_VERSION:
        raise InputError(f"expected robocal_profile: {PROFILE_VERSION}, got {excerpt(d.get('robocal_profile'))}",
                         source=source, where="robocal_profile")
    texts = _texts(d, source)
    try:
        sep = parse_separator(texts["sep"])
        check_decimal(texts["decimal"], sep)
        if texts["units"] is not None:
            parse_units(texts["units"])
        cmap = column_map(d.get("columns") or {}, unknown=d.get("unknown") or "refuse")
    except InputError as e:
        raise InputError(e.detail, source=source, where=e.where) from None
    cmap = _with_ignored(cmap, d.get("ignore") or [], source)
    return Profile(name=texts["name"] or "", sep=sep, decimal=texts["decimal"], units=texts["units"],
                   orientation=texts["orientation"], columns=cmap, key=texts["key"],
                   header=_header(d.get("header"), source))


def _texts(d: dict, source: str) -> dict:
    """The profile's text values (None where it gives none)."""
    texts = {}
    for k in ("name", "sep", "decimal", "units", "orientation", "key"):
        v = d.get(k)
        if v is not None and not isinstance(v, str):
            raise InputError(f"expected text, got {excerpt(v)}", source=source, where=k)
        texts[k] = v
    return texts


def _with_ignored(cmap: ColumnMap, ignore, source: str) -> ColumnMap:
    """``cmap`` with the profile's ``ignore`` list of columns added to its ignored ones (its unknown-column
    action is checked where ``column_map`` makes it)."""
    if not isinstance(ignore, list) or not all(isinstance(c, str) for c in ignore):
        raise InputError(f"expected a list of column names, got {excerpt(ignore)}", source=source, where="ignore")
    return ColumnMap(cmap.rename, cmap.ignore | frozenset(ignore), cmap.unknown)


def _header(header, source: str) -> tuple[str, ...] | None:
    """The column names of a file without a header line, or None."""
    if header is None:
        return None
    if not isinstance(header, list) or not header or not all(isinstance(c, str) and c.strip() for c in header):
        raise InputError(f"expected a list of column names (a file without a header line), got {excerpt(header)}",
                         source=source, where="header")
    return tuple(c.strip() for c in header)


@accepts(path=PATH)
def read_profile(path) -> Profile:
    """Read an instrument profile file (docs/formats.md).

    Parameters
    ----------
    {path}

    Returns
    -------
    Profile
        The profile.
    """
    source = str(path)
    text = read_text(path, limit=MAX_MODEL_BYTES)[0]
    refuse_other_form(text, source, "an instrument profile", ("json",))     # a profile may be JSON too
    return profile_from_dict(load_yaml(text, source), source=source)
