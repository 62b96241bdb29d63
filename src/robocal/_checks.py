"""Checks on a calibration: each names what it looked at, says pass, warn or fail with the figures
behind it and, where one exists, the likely cause and the fix (docs/checks.md).

A result that fails a check cannot be mistaken for a good one: its verdict is "fail".
"""

from __future__ import annotations

from dataclasses import dataclass

STATUSES = ("pass", "warn", "fail")


@dataclass(frozen=True)
class Check:
    """One check of a result. ``items`` names what it found (parameters, pose labels and markers)."""

    name: str
    status: str
    summary: str
    cause: str = ""
    fix: str = ""
    items: tuple[str, ...] = ()


def verdict(checks) -> str:
    """The worst status among ``checks`` ("pass" when there are none)."""
    return max((c.status for c in checks), key=STATUSES.index, default="pass")
