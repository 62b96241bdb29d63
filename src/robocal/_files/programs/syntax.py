"""What every robot-program dialect shares: a scanner that keeps each token's place in the text,
bracketed aggregates with the exact character span of every number, the record of a program's
targets, and writing a program back with only the targets' numbers replaced.

Numbers are kept as written (file units: mm and deg for RAPID and KRL, m and rad for URScript);
the dialect modules say what they mean and the compensation converts them to SI.
"""

from __future__ import annotations

import math
import re
from array import array
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from ..._base.errors import InputError, excerpt

# a turn or quadrant of the configuration data stays as written while its axis is this close to it
# (rad, about 0.006 deg): a target on the boundary, read back, must not flip its configuration
SLACK = 1e-4
# tokens of one program: a target takes 4 (a URScript move of a literal list) to about 40 (KRL); more
# is not a program. They are counted before any is made: a Token costs about 170 bytes, its place in
# the count 17. Targets are counted as they are read (about 2 kB each): the bounds' cost is measured
# in benchmarks/README.md
MAX_TOKENS = 1_000_000
MAX_TARGETS = 30_000
# nesting of a program's bracketed values: targets need 3 (an array of robtargets); more is a mistake
MAX_DEPTH = 32

_NUMBER = r"(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?"
# a bracketed list of plain numbers, one token (``flat``): most of a long program's text
_SIGNED = rf"[-+]?{_NUMBER}"
_FLAT = rf"(?P<flat>\[[ \t]*{_SIGNED}(?:[ \t]*,[ \t]*{_SIGNED})*[ \t]*\])"
_SIGNED_RE = re.compile(_SIGNED)
# whole numbers in base 16, 8 or 2 (RAPID's 0xFF, 0o377, 0b101): read as a 0 run into a name, but no slip
_PREFIXED = re.compile(r"0[xX][0-9A-Fa-f]+|0[oO][0-7]+|0[bB][01]+")
_INDENT = re.compile(r"[ \t]*")


class Token(NamedTuple):
    """One token: ``kind`` is num, name, str, op or nl (a line break, where a dialect needs them)."""

    kind: str
    text: str
    start: int
    end: int


class Number(NamedTuple):
    """A number as written: its value, its text and its span ``[start, end)`` in the program
    (a sign included)."""

    value: float
    text: str
    start: int
    end: int


@dataclass(frozen=True)
class Aggregate:
    """A bracketed value: ``items`` (Number, Aggregate, Field, or the first Token of anything
    else), the span of its brackets, and a KRL structure type (``{E6POS: ...}``) or ``p`` (a
    URScript pose) when written."""

    items: Sequence
    start: int
    end: int
    label: str = ""


class FlatItems(Sequence):
    """The numbers of a ``flat`` token, read when first asked for (most external axes never are)."""

    def __init__(self, token: Token):
        self.token, self.size = token, token.text.count(",") + 1
        self._items: tuple[Number, ...] | None = None

    def __len__(self) -> int:
        return self.size

    def _numbers(self) -> tuple[Number, ...]:
        if self._items is None:
            t = self.token
            new, at = tuple.__new__, t.start        # a NamedTuple made without its Python-level __new__
            self._items = tuple(new(Number, (float(m.group()), m.group(), at + m.start(), at + m.end()))
                                for m in _SIGNED_RE.finditer(t.text))
        return self._items

    def __getitem__(self, i):
        return self._numbers()[i]

    def __iter__(self):
        return iter(self._numbers())


@dataclass(frozen=True)
class Field:
    """A named member of a KRL structure: ``X 10.5``."""

    name: str
    value: object
    start: int


@dataclass(frozen=True)
class Target:
    """One target of a program.

    ``kind`` is ``joint`` (``joints``: the robot axes) or ``pose`` (``position`` x, y, z,
    ``orientation`` in the dialect's convention, ``configuration`` its configuration data, possibly
    empty). ``name``: the declared name (``name{2}`` for an array's element) or ``line N`` for a
    target written inline; ``line`` and ``column`` where its literal begins; ``skip``: why the target
    is read but never changed (empty when it is compensated). A target written inline in a motion
    holds the ``tool`` and work object ``wobj`` it moves with (names; "" with ``unknown`` saying
    why where the program does not tell); a declared one learns them from the program's ``Use``s.
    """

    name: str
    kind: str
    line: int
    column: int
    joints: Sequence[Number] = ()
    position: Sequence[Number] = ()
    orientation: Sequence[Number] = ()
    configuration: Sequence[Number] = ()
    skip: str = ""
    anchor: int = -1
    tool: str = ""
    wobj: str = ""
    unknown: str = ""


@dataclass(frozen=True)
class Use:
    """A motion's use of a declared target: its ``name`` as the motion writes it (an array's
    element ``p{2}``, ``p{*}`` for one chosen at run time), the ``line``, the ``tool`` and work
    object ``wobj`` the motion moves with ("" where the program does not say, ``unknown`` then
    saying why), and the expression the target goes through (``how``: "" for the target itself,
    else the function or operator, e.g. ``Offs``)."""

    name: str
    line: int
    tool: str = ""
    wobj: str = ""
    how: str = ""
    unknown: str = ""


@dataclass(frozen=True)
class NamedFrame:
    """A tool or work object declared in a program: its pose ``X`` (4x4, SI) relative to the
    flange (tool) or the robot base (work object); or ``alias``, the name of the frame it stands
    for (a KRL FDAT's ``F.TOOL_NO`` for ``TOOL_DATA[n]``)."""

    name: str
    kind: str
    X: np.ndarray = field(repr=False)
    alias: str = ""


@dataclass(frozen=True)
class Program:
    """A robot program as read: its text, dialect, targets in source order, named frames, the
    motions' uses of declared targets and its relative motions (instruction, line: KRL's
    ``LIN_REL``), which move by an offset from wherever the robot is and have no target of their own."""

    source: str
    dialect: str
    text: str
    targets: tuple[Target, ...]
    frames: tuple[NamedFrame, ...] = ()
    uses: tuple[Use, ...] = ()
    relative: tuple[tuple[str, int], ...] = ()


class Scanner:
    """Tokens of a program's text with their places; errors name the file, line and column."""

    def __init__(self, text: str, source: str, *, comment: str, quotes: str = '"', newlines: bool = False,
                 names: str = r"[A-Za-z_][A-Za-z0-9_]*", flat: bool = True):
        self.text, self.source = text, source
        self.line_starts = _line_starts(text)
        q = "".join(re.escape(c) for c in quotes)
        strings = "|".join(f"{re.escape(c)}[^{re.escape(c)}\\r\\n]*{re.escape(c)}" for c in quotes)
        parts = [r"(?P<nl>\r\n|\r|\n)", r"(?P<ws>[ \t\f\v]+)", rf"(?P<comment>{re.escape(comment)}[^\r\n]*)",
                 rf"(?P<str>{strings})", rf"(?P<open>[{q}])", rf"(?P<num>{_NUMBER})", rf"(?P<name>{names})",
                 *([_FLAT] if flat else []),
                 r"(?P<op>:=|==|<=|>=|<>|!=|\S)"]
        self.pattern = re.compile("|".join(parts))
        self.newlines = newlines
        self.n_targets = 0

    def where(self, offset: int) -> str:
        return "line {}, column {}".format(*self.line_col(offset))

    def line_col(self, offset: int) -> tuple[int, int]:
        line = int(np.searchsorted(self.line_starts, offset, side="right"))
        return line, offset - int(self.line_starts[line - 1]) + 1

    def target_at(self, offset: int) -> tuple[int, int]:
        """The line and column of one more target, refused beyond ``MAX_TARGETS``."""
        self.n_targets += 1
        if self.n_targets > MAX_TARGETS:
            raise self.error(offset, f"more than {MAX_TARGETS:,} targets; robocal compensates up to {MAX_TARGETS:,} "
                                     "per program")
        return self.line_col(offset)

    def error(self, offset: int, message: str) -> InputError:
        return InputError(message, source=self.source, where=self.where(offset))

    def tokens(self) -> Tokens:
        keep = ("num", "name", "op", "str", "flat") + (("nl",) if self.newlines else ())
        code = {k: i for i, k in enumerate(keep)}
        kinds, starts, ends = bytearray(), array("q"), array("q")
        for m in self.pattern.finditer(self.text):
            kind = m.lastgroup
            if kind in code:
                kinds.append(code[kind])
                starts.append(m.start())
                ends.append(m.end())
                if len(kinds) > MAX_TOKENS:
                    raise self.error(m.start(), f"more than {MAX_TOKENS:,} tokens: not a robot program robocal reads")
            elif kind == "open":
                raise self.error(m.start(), f"a string opened with {m.group()} is not closed on its line")
        new, text = tuple.__new__, self.text      # a NamedTuple made without its Python-level __new__
        out = Tokens(new(Token, (keep[k], text[a:b], a, b)) for k, a, b in zip(kinds, starts, ends))
        out.partner = self._pairs(out)
        return out

    def _pairs(self, toks) -> list[int]:
        """Per token, the index of the bracket that closes or opens it (-1 for any other token);
        a bracket closed by another kind, or never, is an error."""
        partner, stack = [-1] * len(toks), []
        for i, t in enumerate(toks):
            if t.kind != "op":
                continue
            if t.text in _PAIRS:
                stack.append(i)
            elif t.text in _CLOSERS:
                if not stack or _PAIRS[toks[stack[-1]].text] != t.text:
                    raise self.error(t.start, f"{t.text} closes nothing opened here")
                j = stack.pop()
                partner[i], partner[j] = j, i
        if stack:
            raise self.error(toks[stack[-1]].start, f"{toks[stack[-1]].text} is never closed")
        return partner


_PAIRS, _CLOSERS = {"[": "]", "{": "}", "(": ")"}, {"]", "}", ")"}


def _line_starts(text: str) -> np.ndarray:
    """The offset of every line's first character (lines end at \\r\\n, \\r or \\n), as an array: a
    file of line breaks alone would make a list of tens of millions of numbers."""
    ends = re.finditer(r"\r\n|\r|\n", text)
    return np.concatenate([[0], np.fromiter((m.end() for m in ends), dtype=np.int64)])


class Tokens(list):
    """A list of tokens and ``partner``: per token, the index of its matching bracket (-1 if none)."""

    partner: list[int]

    def part(self, a: int, b: int) -> Tokens:
        """Tokens ``a`` to ``b`` with their partners renumbered (a bracket whose partner is outside: -1)."""
        out = Tokens(self[a:b])
        out.partner = [p - a if a <= p < b else -1 for p in self.partner[a:b]]
        return out


def closing(tokens: Tokens, i: int, scanner: Scanner) -> int:
    """Index of the bracket closing the one at ``tokens[i]``."""
    j = tokens.partner[i]
    if j < 0:
        raise scanner.error(tokens[i].start, f"{tokens[i].text} is not closed here")
    return j


def aggregate(tokens: Tokens, i: int, scanner: Scanner, depth: int = 0, name: str = "") -> tuple[Aggregate, int]:
    """The aggregate whose opening bracket is ``tokens[i]`` and the index after its closing one;
    ``name``: the declaration it is the value of, which a malformed number's message names."""
    if depth > MAX_DEPTH:
        raise scanner.error(tokens[i].start, f"values nested more than {MAX_DEPTH} levels deep")
    if tokens[i].kind == "flat":
        return Aggregate(FlatItems(tokens[i]), tokens[i].start, tokens[i].end), i + 1
    end = closing(tokens, i, scanner)
    items, label, j = [], "", i + 1
    if j + 1 < end and tokens[j].kind == "name" and tokens[j + 1].text == ":":   # KRL {E6POS: ...}
        label, j = tokens[j].text, j + 2
    while j < end:
        k, item = _item(tokens, j, end, scanner, depth, name)
        items.append(item)
        if k < end and tokens[k].text != ",":
            item_end = k
            while item_end < end and tokens[item_end].text != ",":
                item_end = closing(tokens, item_end, scanner) + 1 if tokens[item_end].text in "[{(" else item_end + 1
            _refuse_run_together(tokens, j, item_end, scanner, name)
            items[-1] = tokens[j]            # something else than a value (an expression): kept as a token
            k = item_end
        j = k + 1
        if k < end and j == end:
            raise scanner.error(tokens[k].start, "a value is missing after the last ','")
    return Aggregate(tuple(items), tokens[i].start, tokens[end].end, label), end + 1


def _refuse_run_together(tokens, a: int, b: int, scanner: Scanner, name: str) -> None:
    """An InputError at a number run into letters or into another number among ``tokens[a:b]``
    (``962.752x``, ``1.2.3``): a malformed number, which no dialect reads as an expression (an
    expression, ``x0 + 10`` or ``Offs(p, 0, 0, 10)``, separates its numbers from what follows)."""
    for k in range(a, b - 1):
        t = tokens[k]
        if t.kind != "num" or tokens[k + 1].start != t.end or tokens[k + 1].kind not in ("num", "name"):
            continue
        last = k + 1
        while last + 1 < b and tokens[last + 1].start == tokens[last].end and tokens[last + 1].kind in ("num", "name"):
            last += 1
        text = scanner.text[t.start:tokens[last].end]
        if not _PREFIXED.fullmatch(text):
            raise scanner.error(t.start, f"{name + ': ' if name else ''}{excerpt(text)} is not a number")


def _item(tokens, j, end, scanner, depth, name=""):
    t = tokens[j]
    if t.text in ("-", "+") and j + 1 < end and tokens[j + 1].kind == "num":
        n = tokens[j + 1]
        return j + 2, Number(float(t.text + n.text), scanner.text[t.start:n.end], t.start, n.end)
    if t.kind == "num":
        return j + 1, Number(float(t.text), t.text, t.start, t.end)
    if t.text in ("[", "{") or t.kind == "flat":
        return aggregate(tokens, j, scanner, depth + 1, name)[::-1]
    if t.kind == "name" and j + 1 < end and tokens[j + 1].text[:1] == "[" and t.text == "p":  # URScript pose
        agg, k = aggregate(tokens, j + 1, scanner, depth + 1, name)
        return k, Aggregate(agg.items, t.start, agg.end, "p")
    if t.kind == "name" and j + 1 < end and tokens[j + 1].text not in (",", "(", "[", ".") \
            and tokens[j + 1].kind != "flat":  # KRL field
        k, value = _item(tokens, j + 1, end, scanner, depth + 1, name)
        return k, Field(t.text, value, t.start)
    return j + 1, t


def numbers(agg, n: int | None = None) -> Sequence[Number] | None:
    """The aggregate's items when they are all numbers (exactly ``n`` of them if given), else None."""
    if not isinstance(agg, Aggregate) or agg.label not in ("", "p"):
        return None
    if isinstance(agg.items, FlatItems):
        return agg.items if n is None or len(agg.items) == n else None
    if not all(isinstance(x, Number) for x in agg.items) or (n is not None and len(agg.items) != n):
        return None
    return agg.items


def check_finite(values, scanner: Scanner, name: str) -> None:
    """Every number of a target finite (a value like 1e999 reads as infinity)."""
    for n in values:
        if not math.isfinite(n.value):
            raise scanner.error(n.start, f"{name}: {excerpt(n.text)} is not a finite number")


# -- writing back -----------------------------------------------------------------------------------

def decimals(text: str) -> int:
    """Digits after the decimal point of a number as written (0 for an integer)."""
    dot = text.find(".")
    if dot < 0:
        return 0
    end = text.find("e")
    end = text.find("E") if end < 0 else end
    return max((len(text) if end < 0 else end) - dot - 1, 0)


def format_number(value: float, old: Number, *, digits: int, keep: float) -> str:
    """``old``'s text where ``value`` is within ``keep`` of it, else ``value`` with at least as many
    decimals as ``old`` and up to ``digits`` (trailing zeros beyond ``old``'s dropped)."""
    if abs(value - old.value) <= keep:
        return old.text
    was = old.text
    least = decimals(was)
    text = f"{value:.{digits if digits > least else least}f}"
    if digits > least:
        text = text.rstrip("0")
        short = least - (len(text) - text.find(".") - 1)
        if short > 0:
            text += "0" * short
    if text[-1] == "." and "." not in was:
        text = text[:-1]
    if text[0] == "-" and not text.strip("-0."):         # no "-0.000"
        text = text[1:]
    return "+" + text if was[0] == "+" and text[0] != "-" else text


def edited(text: str, replacements, comments, *, comment: str) -> str:
    """``text`` with ``replacements`` [(start, end, new text)] made and each of ``comments``
    [(offset, message)] inserted as a comment line before the line holding ``offset``, indented
    as it is; every other character stays as it was."""
    line_starts = _line_starts(text)
    newline = m.group() if (m := re.search(r"\r\n|\r|\n", text)) else "\n"
    edits = list(replacements)
    for offset, message in comments:
        start = int(line_starts[np.searchsorted(line_starts, offset, side="right") - 1])
        m = _INDENT.match(text, start)
        indent = m.group() if m else ""
        edits.append((start, start, f"{indent}{comment} robocal: {message}{newline}"))
    out, at = [], 0
    for start, end, new in sorted(edits, key=lambda e: (e[0], e[1])):
        out.append(text[at:start])
        out.append(new)
        at = end
    out.append(text[at:])
    return "".join(out)
