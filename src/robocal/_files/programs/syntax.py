"""What every robot-program dialect shares: a scanner that keeps each token's place in the text,
bracketed aggregates with the exact character span of every number, the record of a program's
targets, and writing a program back with only the targets' numbers replaced.

Numbers are kept as written (file units: mm and deg for RAPID and KRL, m and rad for URScript);
the dialect modules say what they mean and the compensation converts them to SI.
"""

from __future__ import annotations

import bisect
import re
from dataclasses import dataclass, field

import numpy as np

from ..._errors import InputError, excerpt

# a turn or quadrant of the configuration data stays as written while its axis is this close to it
# (rad, about 0.006 deg): a target on the boundary, read back, must not flip its configuration
SLACK = 1e-4

_NUMBER = r"(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?"


@dataclass(frozen=True)
class Token:
    """One token: ``kind`` is num, name, str, op or nl (a line break, where a dialect needs them)."""

    kind: str
    text: str
    start: int
    end: int


@dataclass(frozen=True)
class Number:
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

    items: tuple
    start: int
    end: int
    label: str = ""


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
    is read but never changed (empty when it is compensated).
    """

    name: str
    kind: str
    line: int
    column: int
    joints: tuple[Number, ...] = ()
    position: tuple[Number, ...] = ()
    orientation: tuple[Number, ...] = ()
    configuration: tuple[Number, ...] = ()
    skip: str = ""


@dataclass(frozen=True)
class NamedFrame:
    """A tool or work object declared in a program: its pose ``X`` (4x4, SI) relative to the
    flange (tool) or the robot base (work object)."""

    name: str
    kind: str
    X: np.ndarray = field(repr=False)


@dataclass(frozen=True)
class Program:
    """A robot program as read: its text, dialect, targets in source order and named frames."""

    source: str
    dialect: str
    text: str
    targets: tuple[Target, ...]
    frames: tuple[NamedFrame, ...] = ()


class Scanner:
    """Tokens of a program's text with their places; errors name the file, line and column."""

    def __init__(self, text: str, source: str, *, comment: str, quotes: str = '"', newlines: bool = False,
                 names: str = r"[A-Za-z_][A-Za-z0-9_]*"):
        self.text, self.source = text, source
        self.line_starts = [0] + [m.end() for m in re.finditer(r"\r\n|\r|\n", text)]
        parts = [r"(?P<nl>\r\n|\r|\n)", r"(?P<ws>[ \t\f\v]+)", rf"(?P<comment>{re.escape(comment)}[^\r\n]*)",
                 rf"(?P<num>{_NUMBER})", rf"(?P<name>{names})", r"(?P<op>:=|==|<=|>=|<>|!=|[^\s\w])"]
        self.pattern = re.compile("|".join(parts))
        self.quotes, self.newlines = quotes, newlines

    def where(self, offset: int) -> str:
        line = bisect.bisect_right(self.line_starts, offset)
        return f"line {line}, column {offset - self.line_starts[line - 1] + 1}"

    def line_col(self, offset: int) -> tuple[int, int]:
        line = bisect.bisect_right(self.line_starts, offset)
        return line, offset - self.line_starts[line - 1] + 1

    def error(self, offset: int, message: str) -> InputError:
        return InputError(message, source=self.source, where=self.where(offset))

    def tokens(self) -> list[Token]:
        out, text, i, n = [], self.text, 0, len(self.text)
        while i < n:
            if text[i] in self.quotes:
                j = i + 1
                while j < n and text[j] != text[i] and text[j] not in "\r\n":
                    j += 1
                if j >= n or text[j] != text[i]:
                    raise self.error(i, f"a string opened with {text[i]} is not closed on its line")
                out.append(Token("str", text[i:j + 1], i, j + 1))
                i = j + 1
                continue
            m = self.pattern.match(text, i)
            if m is None:  # cannot happen: the op group takes any other character
                raise self.error(i, f"unexpected character {excerpt(text[i])}")
            kind = m.lastgroup
            if kind == "nl" and self.newlines or kind in ("num", "name", "op"):
                out.append(Token(kind or "op", m.group(), m.start(), m.end()))
            i = m.end()
        return out


def closing(tokens: list[Token], i: int, scanner: Scanner) -> int:
    """Index of the bracket closing the one at ``tokens[i]``; an unbalanced bracket is an error."""
    pairs = {"[": "]", "{": "}", "(": ")"}
    stack = []
    for j in range(i, len(tokens)):
        t = tokens[j].text
        if t in pairs:
            stack.append(j)
        elif t in (")", "]", "}"):
            if not stack or pairs[tokens[stack[-1]].text] != t:
                raise scanner.error(tokens[j].start, f"{t} closes nothing opened here")
            stack.pop()
            if not stack:
                return j
    raise scanner.error(tokens[i].start, f"{tokens[i].text} is never closed")


def aggregate(tokens: list[Token], i: int, scanner: Scanner) -> tuple[Aggregate, int]:
    """The aggregate whose opening bracket is ``tokens[i]`` and the index after its closing one."""
    end = closing(tokens, i, scanner)
    items, label, j = [], "", i + 1
    if j + 1 < end and tokens[j].kind == "name" and tokens[j + 1].text == ":":   # KRL {E6POS: ...}
        label, j = tokens[j].text, j + 2
    while j < end:
        k, item = _item(tokens, j, end, scanner)
        items.append(item)
        if k < end and tokens[k].text != ",":
            item_end = k
            while item_end < end and tokens[item_end].text != ",":
                item_end = closing(tokens, item_end, scanner) + 1 if tokens[item_end].text in "[{(" else item_end + 1
            items[-1] = tokens[j]            # something else than a value: kept as a token
            k = item_end
        j = k + 1
        if k < end and j == end:
            raise scanner.error(tokens[k].start, "a value is missing after the last ','")
    return Aggregate(tuple(items), tokens[i].start, tokens[end].end, label), end + 1


def _item(tokens, j, end, scanner):
    t = tokens[j]
    if t.text in ("-", "+") and j + 1 < end and tokens[j + 1].kind == "num":
        n = tokens[j + 1]
        return j + 2, Number(float(t.text + n.text), scanner.text[t.start:n.end], t.start, n.end)
    if t.kind == "num":
        return j + 1, Number(float(t.text), t.text, t.start, t.end)
    if t.text in ("[", "{"):
        return aggregate(tokens, j, scanner)[::-1]
    if t.kind == "name" and j + 1 < end and tokens[j + 1].text == "[" and t.text == "p":  # URScript pose
        agg, k = aggregate(tokens, j + 1, scanner)
        return k, Aggregate(agg.items, t.start, agg.end, "p")
    if t.kind == "name" and j + 1 < end and tokens[j + 1].text not in (",", "(", "[", "."):  # KRL field
        k, value = _item(tokens, j + 1, end, scanner)
        return k, Field(t.text, value, t.start)
    return j + 1, t


def numbers(agg, n: int | None = None) -> tuple[Number, ...] | None:
    """The aggregate's items when they are all numbers (exactly ``n`` of them if given), else None."""
    if not isinstance(agg, Aggregate) or agg.label not in ("", "p"):
        return None
    if not all(isinstance(x, Number) for x in agg.items) or (n is not None and len(agg.items) != n):
        return None
    return agg.items


# -- writing back -----------------------------------------------------------------------------------

def decimals(text: str) -> int:
    """Digits after the decimal point of a number as written (0 for an integer)."""
    mantissa = re.split(r"[eE]", text)[0]
    return len(mantissa.split(".")[1]) if "." in mantissa else 0


def format_number(value: float, old: Number, *, digits: int, keep: float) -> str:
    """``old``'s text where ``value`` is within ``keep`` of it, else ``value`` with at least as many
    decimals as ``old`` and up to ``digits`` (trailing zeros beyond ``old``'s dropped)."""
    if abs(value - old.value) <= keep:
        return old.text
    d = max(decimals(old.text), digits)
    text = f"{value:.{d}f}"
    least = decimals(old.text)
    while "." in text and decimals(text) > least and text.endswith("0"):
        text = text[:-1]
    text = text[:-1] if text.endswith(".") and "." not in old.text else text
    if text in ("-0", "-0.0") or re.fullmatch(r"-0\.0*", text):
        text = text[1:]
    return ("+" + text) if old.text.startswith("+") and not text.startswith("-") else text


def edited(text: str, replacements, comments, *, comment: str) -> str:
    """``text`` with ``replacements`` [(start, end, new text)] made and each of ``comments``
    [(offset, message)] inserted as a comment line before the line holding ``offset``, indented
    as it is; every other character stays as it was."""
    line_starts = [0] + [m.end() for m in re.finditer(r"\r\n|\r|\n", text)]
    newline = m.group() if (m := re.search(r"\r\n|\r|\n", text)) else "\n"
    edits = list(replacements)
    for offset, message in comments:
        start = line_starts[bisect.bisect_right(line_starts, offset) - 1]
        indent = re.match(r"[ \t]*", text[start:]).group()
        edits.append((start, start, f"{indent}{comment} robocal: {message}{newline}"))
    out, at = [], 0
    for start, end, new in sorted(edits, key=lambda e: (e[0], e[1])):
        out.append(text[at:start])
        out.append(new)
        at = end
    out.append(text[at:])
    return "".join(out)
