"""How values are shown to people: the one table of display units, and formatting.

Results hold SI; every summary, table and plot converts here: lengths in mm, angles in degrees,
compliances in deg/(kN m), ratios (a gear's scale error) in %.
"""

from __future__ import annotations

import math
from html.entities import html5

from .._base.arguments import (
    FLAG,
    REAL,
    accepts,
    one_of,
    optional,
)
from .._model.parameters import SI_UNITS

# SI unit -> (display unit, factor from SI, decimals)
DISPLAY_UNITS = {
    "m": ("mm", 1e3, 4),
    "rad": ("deg", 180.0 / math.pi, 5),
    "rad/(N m)": ("deg/(kN m)", 180.0 / math.pi * 1e3, 4),
    "1": ("%", 100.0, 5),
}
# "lengths in mm, angles in deg, compliances in deg/(kN m), ratios in %"
UNITS_SENTENCE = ", ".join(f"{q}s in {DISPLAY_UNITS[u][0]}" for q, u in SI_UNITS.items())
MM = DISPLAY_UNITS["m"][1]
DEG = DISPLAY_UNITS["rad"][1]


def finite(v) -> float | None:
    """A finite float, or None for None/NaN/infinite (result files store NaN as null)."""
    if v is None or isinstance(v, bool):
        return None
    v = float(v)
    return v if math.isfinite(v) else None


def display_unit(unit: str) -> tuple[str, float, int | None]:
    """(display unit, factor from SI, decimals) of an SI unit; unknown units are shown as they are."""
    return DISPLAY_UNITS.get(unit, (unit, 1.0, None))


@accepts(value=optional(REAL), unit=one_of(tuple(DISPLAY_UNITS)), sign=FLAG)
def fmt(value, unit: str = "m", *, sign: bool = False) -> str:
    """``value`` (SI, in ``unit``) as display text without the unit; an en dash when absent.

    Parameters
    ----------
    {value, unit, sign}

    Returns
    -------
    str
        The value as text, without the unit; an en dash when absent.

    >>> fmt(0.0012345), fmt(math.pi / 2, "rad"), fmt(-1e-6, "rad/(N m)", sign=True), fmt(None)
    ('1.2345', '90.00000', '-0.0573', '–')
    """
    v = finite(value)
    if v is None:
        return "–"
    _, k, dec = display_unit(unit)
    spec = ("+" if sign else "") + (f".{dec}f" if dec is not None else ".6g")
    text = format(v * k, spec)
    return text.lstrip("+-") if float(text) == 0 else text  # no signed zeros


def symbol(kind: str) -> str:
    """The HTML symbol of a parameter kind: Greek letters by their entity, a qualified kind with its
    qualifier as a subscript (compliances as K).

    >>> symbol("theta"), symbol("d"), symbol("k_beta"), symbol("backlash_r")
    ('&theta;', 'd', 'K<sub>&beta;</sub>', 'backlash<sub>r</sub>')
    """
    head, _, sub = kind.partition("_")
    if sub:
        return f"{'K' if head == 'k' else head}<sub>{symbol(sub)}</sub>"
    return f"&{kind};" if f"{kind};" in html5 else kind


def with_unit(value, unit: str, *, sign: bool = False) -> str:
    """``fmt`` followed by the display unit: ``'+0.1234 mm'``."""
    return f"{fmt(value, unit, sign=sign)} {display_unit(unit)[0]}"


def absorption_coefficient(coefficient: float, unit: str, absorber_unit: str) -> float:
    """An absorption ``d(name) = c d(absorber)`` (SI units) with both sides in display units.

    A change of 1 display unit of ``name`` is ``1 / k_name`` SI, moving the tool as ``c / k_name``
    SI of the absorber, that is ``c k_absorber / k_name`` of its display unit.

    >>> round(absorption_coefficient(0.5, "rad", "m"), 6)   # 0.5 m per rad -> mm per degree
    8.726646
    """
    return coefficient * display_unit(absorber_unit)[1] / display_unit(unit)[1]


def absorption_text(unit: str, absorbers, units: dict) -> str:
    """An absorption in display units: ``'1 deg = +2.865 mm tool.y -1.146 mm tool.x'``.

    ``unit``: the SI unit of the eliminated parameter; ``absorbers``: (name, SI coefficient) pairs;
    ``units``: SI unit of each absorber's name.

    >>> absorption_text("rad", [("tool.y", 0.05)], {"tool.y": "m"})
    '1 deg = +0.8727 mm tool.y'
    """
    terms = " ".join(f"{absorption_coefficient(c, unit, units.get(n, '')):+.4g} {display_unit(units.get(n, ''))[0]} {n}"
                     for n, c in absorbers)
    return f"1 {display_unit(unit)[0]} = {terms}"
