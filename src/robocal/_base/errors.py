"""Exceptions and warnings users can catch or filter."""

from __future__ import annotations

import difflib
import os
import sys
import types
import warnings

# this package's folder: a warning is attributed to the first frame outside it
_PACKAGE = os.path.dirname(os.path.dirname(os.path.abspath(__file__))) + os.sep     # robocal/, above _base/

# an offending value is quoted in a message at most this long: a huge cell must not flood a terminal
EXCERPT = 60
# and a whole message at most this long
MESSAGE = 500


class RobocalError(Exception):
    """Base class of every error robocal raises on purpose."""


class InputError(RobocalError, ValueError):
    """Bad input: names the source (file or argument) and where in it.

    ``str(err)`` is the single line the CLI prints, e.g.
    ``model.yaml: frames[2].alpha: expected a number, got 'abc'``.
    """

    def __init__(self, message: str, *, source: str | None = None, where: str | None = None):
        if len(message) > MESSAGE:  # a value quoted whole by mistake must not flood the terminal
            message = message[:MESSAGE - 100] + " ... " + message[-95:]
        self.source = source
        self.where = where
        self.detail = message
        parts = [p for p in (source, where) if p]
        super().__init__(": ".join(parts + [message]))


class DegenerateDataError(RobocalError):
    """The data cannot determine what was asked (too few poses, rank loss...)."""


class RobocalWarning(UserWarning):
    """Base class of robocal's warnings."""


class CheckWarning(RobocalWarning):
    """A check of a calibration did not pass (docs/checks.md); the result's verdict says how badly."""


class ConvergenceWarning(CheckWarning):
    """The solver stopped without meeting its convergence test."""


class MisfitWarning(CheckWarning):
    """The fit leaves residuals far larger than the measurement noise, or the orientations do not fit."""


class IdentifiabilityWarning(CheckWarning):
    """Parameters were eliminated or the design is poorly conditioned."""


def excerpt(value) -> str:
    """``repr(value)``, cut to ``EXCERPT`` characters."""
    text = "nothing" if value is None else repr(value)
    return text if len(text) <= EXCERPT else text[:EXCERPT - 5] + "...'" + f" ({len(text)} characters)"


def suggest(word, options) -> str:
    """"; did you mean 'x'?" for the closest option, else the list of options (for messages)."""
    options = [str(o) for o in options]
    close = difflib.get_close_matches(str(word), options, n=1)
    return f"; did you mean {close[0]!r}?" if close else f"; expected one of {', '.join(options)}"


def check_choice(value, options, where: str):
    """``value`` if it is one of ``options`` (an option table declared once), else an InputError."""
    if isinstance(value, str) and value in options:
        return value
    raise InputError(f"must be one of {', '.join(map(str, options))}, got {excerpt(value)}", where=where)


def warn(message: str, category: type[Warning]) -> None:
    """Issue ``message`` as a warning of ``category`` attributed to the user's line: the first
    caller outside robocal, however deep inside robocal (decorators included) it was raised.

    Parameters
    ----------
    message : str
        What the warning says.
    category : type
        A subclass of ``Warning`` (robocal's are ``RobocalWarning``'s).
    """
    frame: types.FrameType | None = sys._getframe(1)
    level = 2                                   # level 2: the frame that called this function
    while frame is not None and frame.f_code.co_filename.startswith(_PACKAGE):
        frame, level = frame.f_back, level + 1
    warnings.warn(message, category, stacklevel=level)
