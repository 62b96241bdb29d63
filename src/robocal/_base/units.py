"""Units robocal reads and writes, as factors to SI (metres, radians). The only table of them.

Everything inside is SI; files and the command line may speak mm and degrees, always explicitly
(a units field, a column suffix, an option). Readers and writers convert with these factors.
"""

from __future__ import annotations

import math

from .errors import InputError, excerpt

LENGTH_UNITS = {"m": 1.0, "mm": 1e-3}
ANGLE_UNITS = {"rad": 1.0, "deg": math.pi / 180.0}
UNITS = {"length": LENGTH_UNITS, "angle": ANGLE_UNITS}


def check_unit(unit: str, kind: str, *, source: str | None = None, where: str | None = None) -> str:
    """``unit`` if it is a known ``kind`` ("length" or "angle") unit, else an InputError naming the others."""
    allowed = UNITS[kind]
    if not isinstance(unit, str) or unit not in allowed:
        other = "angle" if kind == "length" else "length"
        hint = f" (that is an {other} unit)" if isinstance(unit, str) and unit in UNITS[other] else ""
        raise InputError(f"unknown {kind} unit {excerpt(unit)}{hint}; use one of {', '.join(allowed)}", source=source,
                         where=where)
    return unit


def parse_units(text: str, *, source: str | None = None, where: str | None = "units") -> tuple[str, str]:
    """``"mm-deg"`` -> ``("mm", "deg")``; an InputError naming the allowed units otherwise.

    >>> parse_units("m-rad")
    ('m', 'rad')
    """
    parts = str(text).strip().split("-")
    if len(parts) != 2:
        raise InputError(f"units must look like 'mm-deg' (length-angle), got {excerpt(text)}", source=source,
                         where=where)
    length, angle = parts
    check_unit(length, "length", source=source, where=where)
    check_unit(angle, "angle", source=source, where=where)
    return length, angle


def unit_factors(units: str) -> dict[str, float]:
    """SI per file unit for each quantity of a ``"length-angle"`` system; compliances stay SI.

    >>> unit_factors("mm-deg")["length"]
    0.001
    """
    length, angle = parse_units(units)
    return {"length": LENGTH_UNITS[length], "angle": ANGLE_UNITS[angle], "compliance": 1.0, "ratio": 1.0}


def unit_kind(unit: str) -> str | None:
    """"length" or "angle" for a known unit, else None."""
    return next((kind for kind, table in UNITS.items() if unit in table), None)
