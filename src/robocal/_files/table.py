"""Delimited text tables as instruments and controllers export them: the layout, not the meaning.

A table is a header and rows of text cells, with the comment lines that came before the header.
This module finds the separator and the decimal mark when they are not given, accepts trailing
separators, renames and drops columns by a column map, and joins two tables on a key column.
What the columns mean (joints, markers, units) is the business of the reader that uses it
(``measurements``); any file layout of rows and named columns can use it the same way.
"""

from __future__ import annotations

import csv
import io
import re
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from .._base.errors import InputError, excerpt

# separators tried when none is given, in order of preference ("," last: decimal-comma files hold
# commas in their numbers); "whitespace" means runs of spaces and tabs
SEPARATORS = (";", "\t", ",", "|")
WHITESPACE = "whitespace"
SEPARATOR_NAMES = {"\\t": "\t", "tab": "\t", "TAB": "\t", " ": WHITESPACE, "space": WHITESPACE,
                   "whitespace": WHITESPACE}
DECIMALS = (".", ",")
UNKNOWN_ACTIONS = ("refuse", "ignore")
# how many data lines the separator must fit, beyond the header
_SAMPLE = 50
_COMMA_NUMBER = re.compile(r"^[+-]?(\d+,\d*|,\d+)([eE][+-]?\d+)?$")
_LINES = re.compile(r"\r\n|\r|\n")
_PLAIN_NUMBER = re.compile(r"^[+-]?(\d+(\.\d*)?|\.\d+)([eE][+-]?\d+)?$")
_DOT_NUMBER = re.compile(r"^[+-]?(\d+\.\d*|\.\d+)([eE][+-]?\d+)?$")


@dataclass(frozen=True)
class Table:
    """A header and its rows of text cells.

    ``rows``: ``(line, cells)`` with ``line`` what messages call the row (``"12"``, or
    ``"12 (joints.csv line 9)"`` after a join). ``comments``: ``(line, text)`` of the comment lines
    before the header. ``notes``: what was decided on the user's behalf (a detected separator,
    ignored columns, unmatched rows of a join), for the summary.
    """

    header: tuple[str, ...]
    rows: tuple[tuple[str, list[str]], ...]
    source: str
    header_line: int = 1
    comments: tuple[tuple[int, str], ...] = ()
    sep: str = ","
    decimal: str = "."
    notes: tuple[str, ...] = ()
    header_given: bool = False
    # {mark: (cells of the first rows that read as numbers with it, the first one's line)}: what the
    # decimal mark was detected from, and what a cell written otherwise is told
    decimals_seen: Mapping[str, tuple[int, str]] = field(default_factory=dict)
    # {name a column map gave: the file's own column (or sum "A+B")}, for messages to name the latter
    renamed: Mapping[str, str] = field(default_factory=dict)

    @property
    def header_where(self) -> str:
        """Where messages place the header: its line, or the names given for a file without one."""
        return "the given column names (header)" if self.header_given else f"line {self.header_line}"

    def cell_where(self, line: str, column: str) -> str:
        """Where messages place the cell of ``column`` on ``line``."""
        return f"line {line}, {column_named(column, self.renamed)}"

    def with_notes(self, *notes: str) -> Table:
        return replace(self, notes=self.notes + tuple(n for n in notes if n))


def column_named(column: str, renamed: Mapping[str, str]) -> str:
    """How messages name ``column``: by the file's own name, the name a column map gave it
    (``renamed``: {that name: the file's}) in parentheses."""
    given = renamed.get(column)
    return f"column {column!r}" if given is None else f"column {given!r} (mapped to {column!r})"


@dataclass(frozen=True)
class ColumnMap:
    """How a file's columns become robocal's: ``rename`` {file column: robocal column}, ``ignore``
    (file columns to drop), and what to do with columns the reader does not know: ``unknown``
    "refuse" (an error naming the column) or "ignore" (dropped, and said in the notes)."""

    rename: Mapping[str, str] = field(default_factory=dict)
    ignore: frozenset = frozenset()
    unknown: str = "refuse"

    def __post_init__(self) -> None:
        if self.unknown not in UNKNOWN_ACTIONS:
            raise InputError(f"unknown columns must be 'refuse' or 'ignore', got {excerpt(self.unknown)}",
                             where="unknown")
        object.__setattr__(self, "rename", dict(self.rename))
        object.__setattr__(self, "ignore", frozenset(self.ignore))

    def merged(self, other: ColumnMap | None) -> ColumnMap:
        """This map with ``other``'s entries (and its unknown-column action) on top."""
        if other is None:
            return self
        rename = {k: v for k, v in self.rename.items() if k not in other.ignore}
        ignore = frozenset(c for c in self.ignore if c not in other.rename)
        return ColumnMap({**rename, **other.rename}, ignore | other.ignore, other.unknown)


def parse_separator(text: str | None, *, where: str = "sep") -> str | None:
    """A separator as given by a user (``;``, ``\\t`` typed as two characters, ``tab``, ``whitespace``)."""
    if text is None:
        return None
    sep = SEPARATOR_NAMES.get(text, text)
    if sep != WHITESPACE and len(sep) != 1:
        raise InputError(f"a separator is one character, '\\t' or 'whitespace'; got {excerpt(text)}", where=where)
    if sep != WHITESPACE and (sep in DECIMALS[:1] or sep.isalnum() or sep in "\"#"):
        raise InputError(f"{excerpt(text)} cannot separate columns", where=where)
    return sep


def check_decimal(decimal: str | None, sep: str | None) -> None:
    if decimal is not None and decimal not in DECIMALS:
        raise InputError(f"the decimal mark is '.' or ',', got {excerpt(decimal)}", where="decimal")
    if decimal is not None and decimal == sep:
        raise InputError(f"the separator and the decimal mark are both {decimal!r}", where="sep/decimal")


def show_separator(sep: str) -> str:
    return {"\t": "tab", WHITESPACE: "whitespace"}.get(sep, repr(sep))


def read_table(text: str, source: str, *, sep: str | None = None, decimal: str | None = None,
               header: tuple[str, ...] | None = None) -> Table:
    """The table in ``text``: comment lines (``#``) before the header kept, blank lines skipped.

    ``sep``/``decimal``: None to detect them from the header and the first rows (said in the notes).
    ``header``: the column names of a file without a header line (its first line is then data).
    """
    sep = parse_separator(sep)
    check_decimal(decimal, sep)
    lines = _LINES.split(text)  # the csv module's line ends; str.splitlines knows more (\x1e, \u2028...)
    content = [(k + 1, ln) for k, ln in enumerate(lines) if ln.strip() and not ln.lstrip().startswith("#")]
    header = _given_header(header)
    if not content:
        raise InputError("no header line (and no data)" if header is None else "no data rows", source=source)
    data = content[1:] if header is None else content
    notes = []
    if sep is None:
        sep = _sampled_separator(content[0][1], data, header is not None)
        notes.append(f"separator {show_separator(sep)} (detected)")
    header_line = content[0][0]
    cells = _split(text, sep, source)
    names = list(header) if header is not None else _header_names(cells, sep, source, header_line)
    while names and not names[-1]:
        names.pop()  # a separator at the end of every line
    rows = _data_rows(data, cells, source)
    if sep == WHITESPACE and header is None:
        names, note = _spaced_names(lines[header_line - 1], names, rows)
        notes += [note] if note else []
    rows = _trimmed(rows, len(names))
    seen = _decimals_seen(sep, rows)
    if decimal is None:
        decimal = _detect_decimal(seen)
        if decimal != ".":
            notes.append(f"decimal mark {decimal!r} (detected)")
    check_decimal(decimal, sep)
    return Table(header=tuple(names), rows=tuple(rows), source=source, header_line=header_line,
                 comments=_comments(lines, header_line), sep=sep, decimal=decimal, notes=tuple(notes),
                 header_given=header is not None, decimals_seen=seen)


def _sampled_separator(header: str, data: list[tuple[int, str]], given: bool) -> str:
    """The separator detected from the ``header`` line and the first data lines (``given``: the
    header is given, so the first line is data)."""
    sample = [ln for _, ln in data[:_SAMPLE + 1]]
    return _detect_separator(header, sample[1:] if given else sample)


def _comments(lines: list[str], header_line: int) -> tuple[tuple[int, str], ...]:
    """(line, text) of the comment lines before the header."""
    return tuple((k + 1, ln) for k, ln in enumerate(lines[:header_line - 1]) if ln.lstrip().startswith("#"))


def _data_rows(data: list[tuple[int, str]], cells: dict[int, list[str]], source: str) -> list:
    """(line, cells) of each data line."""
    try:
        return [(str(line), cells[line]) for line, _ in data]
    except KeyError as e:
        raise _quote_not_closed(e.args[0], source) from None


def _given_header(header) -> tuple[str, ...] | None:
    """The column names given for a file without a header line (stripped, distinct), or None."""
    if header is None:
        return None
    header = tuple(str(c).strip() for c in header)
    if not header or not all(header) or len(set(header)) < len(header):
        raise InputError(f"expected distinct column names, got {excerpt(','.join(header))}", where="header")
    return header


def _header_names(cells: dict[int, list[str]], sep: str, source: str, line: int) -> list[str]:
    """The column names on the header ``line``; refused where they look like another separator's or data."""
    if line not in cells:
        raise _quote_not_closed(line, source)
    names = [c.strip() for c in cells[line]]
    _refuse_other_separator(names, sep, source, line)
    _refuse_numbers(names, source, line)
    return names


def _quote_not_closed(line: int, source: str) -> InputError:
    """The error of a ``line`` swallowed by a quoted cell begun on an earlier one."""
    return InputError("a quoted cell runs over several lines (a quote not closed?)", source=source,
                      where=f"line {line}")


def _spaced_names(text: str, names: list[str], rows: list) -> tuple[list[str], str]:
    """A whitespace-separated header ``text`` with more names than the rows have cells: its names told
    apart by tabs or two or more spaces where that gives one per cell (and the note saying so)."""
    if not rows or len(names) <= len(rows[0][1]):
        return names, ""
    spaced = [c for c in re.split(r"\t|\s{2,}", text.strip()) if c]
    if len(spaced) == len(rows[0][1]):  # names holding single spaces, columns apart by more
        return spaced, "header names hold spaces: columns told apart by tabs or two or more spaces"
    return names, ""


def _trimmed(rows: list, width: int) -> list:
    """``rows`` without the empty cells past ``width`` (a separator at the end of a line)."""
    return [(line, row[:width] if len(row) > width and not any(c.strip() for c in row[width:]) else row)
            for line, row in rows]


def _split(text: str, sep: str, source: str) -> dict[int, list[str]]:
    """The cells of every line, by line number (comments and blank lines included, unused)."""
    if sep == WHITESPACE:
        return {k + 1: ln.split() for k, ln in enumerate(_LINES.split(text))}
    reader = csv.reader(io.StringIO(text, newline=""), delimiter=sep)
    out = {}
    try:
        start = 1
        for row in reader:
            out[start] = row
            start = reader.line_num + 1
    except csv.Error as e:
        raise InputError(f"not readable as CSV: {e}", source=source, where=f"line {reader.line_num}") from None
    return out


def _detect_separator(header: str, sample: list[str]) -> str:
    counts = {s: header.count(s) for s in SEPARATORS if header.count(s)}
    consistent = [s for s in counts if all(ln.count(s) == counts[s] for ln in sample)]
    if consistent:
        return consistent[0]
    if counts:
        return max(counts, key=lambda s: counts[s])
    return WHITESPACE if len(header.split()) > 1 else ","


def _decimals_seen(sep: str, rows) -> dict[str, tuple[int, str]]:
    """{mark: (how many cells of the first rows read as numbers with it, the first one's line)};
    a comma is no decimal mark where it separates the columns (a quoted cell holds it)."""
    seen: dict[str, tuple[int, str]] = {}
    for line, row in rows[:_SAMPLE]:
        for c in row:
            c = c.strip()
            for mark, pattern in ((",", _COMMA_NUMBER), (".", _DOT_NUMBER)):
                if pattern.match(c) and not (mark == "," and sep == ","):
                    n, first = seen.get(mark, (0, line))
                    seen[mark] = (n + 1, first)
    return seen


def _detect_decimal(seen: Mapping[str, tuple[int, str]]) -> str:
    """The mark most numbers of the first rows write (a point when as many, or none, write a comma):
    a row of the other is then named where it is read."""
    return "," if seen.get(",", (0,))[0] > seen.get(".", (0,))[0] else "."


def _refuse_other_separator(header: list[str], sep: str, source: str, line: int) -> None:
    """A header read as one column that another separator would split: name the fix."""
    if len([c for c in header if c]) != 1:
        return
    for other in SEPARATORS + (WHITESPACE,):
        parts = header[0].split() if other == WHITESPACE else header[0].split(other)
        if other != sep and len(parts) > 1:
            raise InputError(f"the header is one column {excerpt(header[0])}; it looks separated by "
                             f"{show_separator(other)}: pass sep={other!r} (--sep {_cli(other)}) or leave the "
                             "separator out to have it detected", source=source, where=f"line {line}")


def _refuse_numbers(header: list[str], source: str, line: int) -> None:
    """A first line of numbers is data: the file has no header line; name the fix."""
    cells = [c for c in header if c]
    numbers = sum(bool(_PLAIN_NUMBER.match(c) or _COMMA_NUMBER.match(c)) for c in cells)
    if numbers >= max(2, len(cells) / 2):  # column names are not numbers
        first = excerpt(", ".join(cells[:3]))[1:-1]
        raise InputError(f"the first line holds numbers ({first}...), not column names: the file has no header line;"
                         " name its columns with header=[...] (--header NAME,... or "
                         "'header:' in a profile)", source=source, where=f"line {line}")


def _cli(sep: str) -> str:
    return {"\t": "'\\t'", WHITESPACE: "whitespace"}.get(sep, f"'{sep}'")


def decimal_hint(text: str, table: Table) -> str:
    """'; ...' saying what to do when ``text`` reads as a number with the other decimal mark than
    ``table``'s, else '': correct the cell where the file's other numbers write the table's mark,
    else name the mark that reads it (never the separator)."""
    t = text.strip()
    other = "," if table.decimal == "." else "."
    if not (_COMMA_NUMBER if other == "," else _DOT_NUMBER).match(t):
        return ""
    seen = table.decimals_seen
    if len(seen) == 2:      # both among the first rows: the fewer are the slips, whichever was taken
        fewer = min(DECIMALS, key=lambda m: (seen[m][0], m == table.decimal))
        both = ", ".join(f"{seen[m][0]} with {m!r} from line {seen[m][1]}" for m in DECIMALS)
        return (f"; the file writes both decimal marks (numbers of its first rows: {both}): a file holds one; "
                f"correct the ones with {fewer!r}, from line {seen[fewer][1]}")
    if table.decimal in seen:
        n, first = seen[table.decimal]
        return (f"; the file's other numbers write {table.decimal!r} ({n} in its first rows, from line {first}): a "
                "file holds one decimal mark; correct this cell")
    if other == table.sep:
        return "; a decimal comma cannot be read where commas separate the columns: write the number with a " \
               "decimal point"
    detected = table.decimals_seen.get(other, (0,))[0] > 0     # so the mark was given, not detected
    return (f"; it looks like a decimal {'comma' if other == ',' else 'point'}: pass decimal={other!r} "
            f"(--decimal {other})" + (" or leave the decimal mark out to have it detected" if detected else ""))


def map_columns(table: Table, columns: ColumnMap | None) -> Table:
    """``table`` with its columns renamed and the ignored ones dropped (said in the notes).

    A map entry ``"A+B"`` (file columns joined by ``+``) makes one column of their sum, cell by
    cell, in place of ``A`` (``B`` dropped): a measured position stored as a target and a deviation.
    """
    if columns is None or (not columns.rename and not columns.ignore):
        return table
    table = _sum_columns(table, {k: v for k, v in columns.rename.items() if "+" in k and k not in table.header})
    where = table.header_where
    keep = [k for k, c in enumerate(table.header) if c not in columns.ignore]
    header = [columns.rename.get(table.header[k], table.header[k]) for k in keep]
    for k, c in zip(keep, header):
        if header.count(c) > 1:
            raise InputError(f"column {table.header[k]!r} is mapped to {c!r}, which another column also is "
                             "or already was", source=table.source, where=where)
    dropped = [c for c in table.header if c in columns.ignore]
    rows = tuple((line, [row[k] if k < len(row) else "" for k in keep] if len(row) == len(table.header) else row)
                 for line, row in table.rows)
    note = f"columns ignored as asked: {', '.join(dropped)}" if dropped else ""
    return replace(table, header=tuple(header), rows=rows, renamed=_renamed(table, columns)).with_notes(note)


def _renamed(table: Table, columns: ColumnMap) -> dict[str, str]:
    """``table.renamed`` with the names ``columns`` gives the table's columns."""
    return {**table.renamed, **{new: old for old, new in columns.rename.items() if old in table.header}}


def _sum_columns(table: Table, sums: dict) -> Table:
    """``table`` with each ``"A+B"`` of ``sums`` made one column (named ``"A+B"``, where A was)."""
    if not sums:
        return table
    header, rows = list(table.header), [(line, list(row)) for line, row in table.rows]
    for key in sums:
        parts = [p.strip() for p in key.split("+")]
        missing = [p for p in parts if p not in header]
        if missing or len(parts) < 2:
            raise InputError(f"column {missing[0]!r} of the sum {key!r} is not in the file" if missing else
                             f"a sum of columns is A+B, got {key!r}", source=table.source, where=table.header_where)
        ks = [header.index(p) for p in parts]
        for line, row in rows:
            if len(row) == len(header):
                row[ks[0]] = _sum_cells([row[k] for k in ks], parts, table, line)
        for _, row in rows:
            if len(row) == len(header):
                for k in sorted(ks[1:], reverse=True):
                    del row[k]
        header[ks[0]] = key
        for k in sorted(ks[1:], reverse=True):
            del header[k]
    return replace(table, header=tuple(header), rows=tuple((line, row) for line, row in rows)).with_notes(
        *(f"column {v!r} is the sum {k}" for k, v in sums.items()))


def _sum_cells(cells: list[str], names: list[str], table: Table, line: str) -> str:
    """The sum of a row's ``cells`` in the file's decimal mark; all empty: empty; some empty: an error."""
    texts = [c.strip() for c in cells]
    if not any(texts):
        return ""
    total = 0.0
    for t, name in zip(texts, names):
        where = f"line {line}, column {name!r}"
        if not t:
            raise InputError(f"empty cell while the other columns of the sum {'+'.join(names)} are filled",
                             source=table.source, where=where)
        number = t.replace(table.decimal, ".") if table.decimal != "." and "." not in t else t
        if not _PLAIN_NUMBER.match(number):
            raise InputError(f"expected a number, got {excerpt(t)}{decimal_hint(t, table)}",
                             source=table.source, where=where)
        total += float(number)
    return repr(total).replace(".", table.decimal)


def join_tables(points: Table, readings: Table, key: str) -> Table:
    """The rows of ``points`` and ``readings`` that share a value of column ``key``, side by side.

    Rows without a partner are left out and named in the notes (``readings``' own notes are not
    carried: they name its file); no match at all, a repeated key or a column both tables hold
    (other than the key) is an InputError.
    """
    for t in (points, readings):
        if key not in t.header:
            raise InputError(f"no key column {key!r} to join on; the columns are {', '.join(t.header)}",
                             source=t.source, where=t.header_where)
    both = [c for c in readings.header if c in points.header and c != key]
    if both:
        raise InputError(f"column {both[0]!r} is in both {points.source} and {readings.source}; map or "
                         "ignore it in one of them", source=readings.source, where=readings.header_where)
    kp, kr = points.header.index(key), readings.header.index(key)
    by_key = _keyed(readings, kr)
    seen = _keyed(points, kp)
    rows = []
    for value, (line, row) in seen.items():
        if value in by_key:
            rline, rrow = by_key[value]
            rows.append((f"{line} ({readings.source} line {rline})",
                         list(row) + [c for k, c in enumerate(rrow) if k != kr]))
    if not rows:
        raise InputError(f"no {key} value is in both files ({_few(seen)} in {points.source}; {_few(by_key)} "
                         f"in {readings.source})", source=points.source, where=f"column {key!r}")
    lost = [[v for v in mine if v not in other] for mine, other in ((seen, by_key), (by_key, seen))]
    header = points.header + tuple(c for k, c in enumerate(readings.header) if k != kr)
    return replace(points, header=header, rows=tuple(rows), renamed={**readings.renamed, **points.renamed}).with_notes(
        *join_notes(points, readings, key, len(rows), *lost))


def join_notes(points: Table, readings: Table, key: str, n: int, lost_points, lost_readings) -> tuple[str, ...]:
    """What a join of ``n`` poses says: the file joined, and the keys of each file's rows left out."""
    notes = [f"joined with {readings.source} on column {key!r}: {n} poses"]
    for t, lost, what in ((points, lost_points, "joint readings"), (readings, lost_readings, "measurement")):
        if len(lost):
            notes.append(f"{len(lost)} row(s) of {t.source} have no {what} in the other file and are left out "
                         f"({key} {_few(lost)})")
    return tuple(notes)


def joined_header(points: Table, readings: Table, key: str) -> tuple[tuple[str, ...], int]:
    """The header :func:`join_tables` gives and the key's column in ``readings``; ``Unfit`` where it
    would stop with an error (it names the fault)."""
    if key not in points.header or key not in readings.header or any(
            c in points.header and c != key for c in readings.header):
        raise Unfit
    kr = readings.header.index(key)
    return points.header + tuple(c for k, c in enumerate(readings.header) if k != kr), kr


def join_rows(keys_points: list, keys_readings: list) -> tuple[np.ndarray, np.ndarray, list, list]:
    """The rows of two files' key columns that :func:`join_tables` pairs (indices into each, in the
    order of ``keys_points``) and the keys of each file left out; ``Unfit`` where it would stop
    with an error (an empty or repeated key, no key in both)."""
    at = {v: i for i, v in enumerate(keys_readings)}
    if len(at) != len(keys_readings) or "" in at or len(set(keys_points)) != len(keys_points) or "" in keys_points:
        raise Unfit
    found = np.fromiter((at.get(v, -1) for v in keys_points), dtype=np.int64, count=len(keys_points))
    paired = found >= 0
    if not paired.any():
        raise Unfit
    rows_points, rows_readings = np.nonzero(paired)[0], found[paired]
    taken = np.zeros(len(keys_readings), dtype=bool)
    taken[rows_readings] = True
    lost_points = [v for v, ok in zip(keys_points, paired.tolist()) if not ok]
    lost_readings = [v for v, ok in zip(keys_readings, taken.tolist()) if not ok]
    return rows_points, rows_readings, lost_points, lost_readings


def _keyed(table: Table, k: int) -> dict:
    out: dict = {}
    for line, row in table.rows:
        value = row[k].strip() if k < len(row) else ""
        if not value:
            raise InputError("empty key cell", source=table.source, where=table.cell_where(line, table.header[k]))
        if value in out:
            raise InputError(f"{table.header[k]} {value!r} appears twice (also line {out[value][0]})",
                             source=table.source, where=f"line {line}")
        out[value] = (line, row)
    return out


def _few(values, n: int = 5) -> str:
    values = list(values)
    return ", ".join(values[:n]) + (f" and {len(values) - n} more" if len(values) > n else "")


# -- the same tables read by numpy's compiled text parser ----------------------------------------

# what numpy's parser would read differently from read_table, found in the bytes before it runs: a
# quote, a comment line among the rows, a carriage return that does not end a line (a blank line or
# a row of another width shows in the count of rows and separators, NaN and infinite text in the
# parsed numbers)
_COMMENT_LINE = re.compile(rb"(^|\n)[ \t]*#")
# an empty cell as numpy's parser is given it: text it reads as NaN in a number column
_EMPTY = b"nan"
# a decimal comma read as a point, and a point made a comma, which no number then parses
_SWAP_DECIMAL = bytes.maketrans(b".,", b",.")
_SWAP_BACK = str.maketrans(".,", ",.")


class Unfit(Exception):
    """The compiled parser cannot vouch for this file as read_table would read it (quotes, comments
    or blank lines among the rows, a row of another width, text where a number is expected...): the
    caller reads it row by row instead, which either reads it or says exactly what is wrong.
    ``args[0]``, when given, says why in words for the summary."""

    @property
    def why(self) -> str:
        return self.args[0] if self.args else "a cell it cannot vouch for"


@dataclass(frozen=True)
class Scan:
    """Where a file's data rows are in its bytes: ``n_rows`` rows from byte ``start``, the first on
    line ``first_line``, each of ``width`` cells (trailing cells without a column name included)."""

    n_rows: int
    first_line: int
    start: int
    width: int


def read_head(raw: bytes, source: str, *, sep: str | None = None, decimal: str | None = None,
              header: tuple[str, ...] | None = None) -> Table:
    """The table of the file's comments, header and first rows in ``raw`` (enough to detect the
    separator and the decimal mark as :func:`read_table` does on the whole file); ``Unfit`` if it
    cannot be read."""
    end = content = 0
    while content < _SAMPLE + 2 and end < len(raw):
        after = raw.find(b"\n", end) + 1 or len(raw)
        line = raw[end:after]
        content += bool(line.strip()) and not line.lstrip().startswith(b"#")
        end = after
    try:
        return read_table(raw[:end].decode("utf-8-sig"), source, sep=sep, decimal=decimal, header=header)
    except (UnicodeDecodeError, InputError):
        raise Unfit from None


def scan_rows(raw: bytes, head: Table) -> Scan:
    """Where the data rows of ``raw`` are (``head``: :func:`read_head`'s table), once the bytes show
    that each is a plain line of the header's width; ``Unfit`` (saying why) otherwise."""
    if head.sep == WHITESPACE:
        raise Unfit("whitespace as the separator")  # a row's width is not checked by counting separators
    first = head.header_line if head.header_given else head.header_line + 1
    start = header_start = 0
    for _ in range(first - 1):  # the comments and the header: read_head's
        header_start, start = start, raw.find(b"\n", start) + 1
        if start == 0:
            raise Unfit
    end = _end_of_rows(raw, start)
    sep = head.sep.encode()
    width = len(head.header) if head.header_given else raw.count(sep, header_start, start) + 1
    n_rows = raw.count(b"\n", start, end) + 1 if end > start else 0
    if raw.find(b'"', start, end) >= 0:
        raise Unfit("quoted cells")
    if raw.find(b"\r", start, end) >= 0 and raw.count(b"\r", start, end) != raw.count(b"\r\n", start, end):
        raise Unfit("lines ended by a carriage return alone")
    if raw.find(b"#", start, end) >= 0 and _COMMENT_LINE.search(raw, max(start - 1, 0), end):
        raise Unfit("comment lines among the rows")
    if n_rows <= 0 or width < 2 or raw.count(sep, start, end) != n_rows * (width - 1):
        raise Unfit("rows of another width than the header, or blank lines among them")
    if _line_longer_than(raw, start, end, csv.field_size_limit()):
        raise Unfit("a line longer than the row reader's longest cell")  # which it may refuse
    return Scan(n_rows=n_rows, first_line=first, start=start, width=width)


def _line_longer_than(raw: bytes, start: int, end: int, most: int) -> bool:
    """Whether a line of ``raw[start:end]`` (``start`` a line's first byte) is longer than ``most``
    bytes: each step looks for the last line end within ``most`` bytes of the line it is at."""
    at = start
    while end - at > most:
        line_end = raw.rfind(b"\n", at, at + most + 1)
        if line_end < 0:
            return True
        at = line_end + 1
    return False


def _end_of_rows(raw: bytes, start: int) -> int:
    """Where the rows from ``start`` end: before the line ends (blank lines) at the end of ``raw``."""
    end = len(raw)
    while end > start and raw[end - 1] in b"\r\n":
        end -= 1
    return end


def read_columns(raw: bytes, head: Table, scan: Scan, columns: Mapping[int, str]) -> dict:
    """The file's columns ``{index: "number" or "text"}`` over its data rows, parsed by numpy's
    compiled text reader: float arrays (NaN where a cell is empty) or lists of str (stripped);
    ``Unfit`` where a number does not parse or a row is not as the scan found it."""
    numbers = sorted(k for k, kind in columns.items() if kind == "number")
    body, skip, filled, values = _numbers(raw, head, scan, numbers)
    # the texts asked for, the cells beyond the header's names (to be empty) and the last cell (which
    # makes numpy check that every row has the scan's width); every cell when empty ones were filled
    asked = {k for k, kind in columns.items() if kind == "text"} | set(range(len(head.header), scan.width))
    texts = sorted((asked | (set(range(scan.width)) if filled else {scan.width - 1})) - set(numbers))
    cells = _parsed(body, head.sep, skip, texts, object, scan.n_rows)
    if len(values) != scan.n_rows or len(cells) != scan.n_rows:
        raise Unfit("blank lines among the rows")
    empties = cells == _EMPTY.decode() if filled else np.zeros(cells.shape, dtype=bool)
    if np.count_nonzero(np.isnan(values)) + np.count_nonzero(empties) != filled:
        raise Unfit  # NaN text in the file (or a text cell reading "nan"): the row reader names it
    out: dict = {k: values[:, j] for j, k in enumerate(numbers)}
    for j, k in enumerate(texts):
        column = _texts(np.where(empties[:, j], "", cells[:, j]), head.decimal)
        if k >= len(head.header) and any(column):
            raise Unfit  # a cell beyond the header's columns: the row reader names its row
        if k in columns:
            out[k] = column
    return out


def _numbers(raw: bytes, head: Table, scan: Scan, numbers: list[int]) -> tuple[bytes, int, int, np.ndarray]:
    """The bytes the number columns were parsed from (empty cells filled where there are any), the
    lines before the rows in them, how many cells were filled, and the numbers (rows, columns)."""
    body = raw if head.decimal == "." else raw.translate(_SWAP_DECIMAL)
    try:
        return body, scan.first_line - 1, 0, _parsed(body, head.sep, scan.first_line - 1, numbers, float, scan.n_rows)
    except ValueError:  # an empty cell, or text where a number belongs (the row reader names it)
        pass
    body, filled = _filled(body[scan.start:_end_of_rows(body, scan.start)], head.sep.encode())
    try:
        return body, 0, filled, _parsed(body, head.sep, 0, numbers, float, scan.n_rows)
    except ValueError:
        raise Unfit from None


def _parsed(body: bytes, sep: str, skip: int, usecols: list[int], dtype, n_rows: int) -> np.ndarray:
    """(rows, len(usecols)) cells of ``body`` after its first ``skip`` lines, by numpy's parser
    (``n_rows`` empty rows when no column is asked for)."""
    if not usecols:
        return np.empty((n_rows, 0), dtype=dtype)
    return np.loadtxt(io.BytesIO(body), delimiter=sep, skiprows=skip, usecols=usecols, dtype=dtype, comments=None,
                      quotechar=None, encoding="utf-8", ndmin=2)


def _filled(body: bytes, sep: bytes) -> tuple[bytes, int]:
    """``body`` (whole lines) with _EMPTY in every empty cell, and how many there were."""
    filled = body.replace(sep + sep, sep + _EMPTY + sep).replace(sep + sep, sep + _EMPTY + sep)
    filled = filled.replace(b"\n" + sep, b"\n" + _EMPTY + sep).replace(sep + b"\n", sep + _EMPTY + b"\n")
    filled = filled.replace(sep + b"\r", sep + _EMPTY + b"\r")
    if filled.startswith(sep):
        filled = _EMPTY + filled
    if filled.endswith(sep):
        filled += _EMPTY
    return filled, (len(filled) - len(body)) // len(_EMPTY)


def _texts(a: np.ndarray, decimal: str) -> list:
    """The stripped text of an object column (its decimal marks swapped back where the number
    columns were read with them swapped)."""
    column = [c.strip() for c in a.tolist()]
    if decimal != "." and any("." in c or "," in c for c in column):
        return [c.translate(_SWAP_BACK) for c in column]
    return column
