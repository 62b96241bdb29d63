"""Exceptions and warnings users can catch or filter."""

from __future__ import annotations


class RobocalError(Exception):
    """Base class of every error robocal raises on purpose."""


class InputError(RobocalError, ValueError):
    """Bad input: names the source (file or argument) and where in it.

    ``str(err)`` is the single line the CLI prints, e.g.
    ``model.yaml: frames[2].alpha: expected a number, got 'abc'``.
    """

    def __init__(self, message: str, *, source: str | None = None, where: str | None = None):
        self.source = source
        self.where = where
        self.detail = message
        parts = [p for p in (source, where) if p]
        super().__init__(": ".join(parts + [message]))


class DegenerateDataError(RobocalError):
    """The data cannot determine what was asked (too few poses, rank loss...)."""


class RobocalWarning(UserWarning):
    """Base class of robocal's warnings."""


class ConvergenceWarning(RobocalWarning):
    """The solver stopped without meeting its convergence test."""


class MisfitWarning(RobocalWarning):
    """The fit leaves residuals far larger than the stated measurement noise."""


class IdentifiabilityWarning(RobocalWarning):
    """Parameters were eliminated or the design is poorly conditioned."""
