"""Checks of public functions' arguments, made before any work (as scipy's ``least_squares`` does).

Each check returns the value in the form the function uses, or raises ``InputError`` whose
``where`` is the argument's name and whose message says what is allowed and what was given. A
public function declares its arguments' rules (``accepts``) and the public modules export it
checked (``export_checked``): the rules run once, on the user's call, so no internal error
(numpy's, LAPACK's, a ``TypeError`` or an ``AttributeError``) reaches its caller for a bad
argument, and robocal's own calls between its functions check nothing again.

>>> number(0.5, "tol", low=0.0, high=1.0, low_open=True, high_open=True)
0.5
>>> from robocal.errors import InputError
>>> try:
...     number(2, "tol", low=0.0, high=1.0, low_open=True, high_open=True)
... except InputError as e:
...     print(e.where, "|", e)
tol | tol: must be a number in (0, 1), got 2
"""

from __future__ import annotations

import functools
import inspect
import math
import numbers
from collections.abc import Iterable

import numpy as np

from .errors import InputError, excerpt, suggest
from .glossary import expand


def _interval(low: float | None, high: float | None, low_open: bool, high_open: bool) -> str:
    lo = "(-inf" if low is None else ("(" if low_open else "[") + f"{low:g}"
    hi = "inf)" if high is None else f"{high:g}" + (")" if high_open else "]")
    return f"{lo}, {hi}"


def number(value, name: str, *, low: float | None = None, high: float | None = None, low_open: bool = False,
           high_open: bool = False) -> float:
    """A finite real number within the interval from ``low`` to ``high`` (open ends where said)."""
    ok = isinstance(value, numbers.Real) and not isinstance(value, bool) and math.isfinite(value)
    if ok and low is not None:
        ok = value > low if low_open else value >= low
    if ok and high is not None:
        ok = value < high if high_open else value <= high
    if not ok:
        raise InputError(f"must be a number in {_interval(low, high, low_open, high_open)}, got {excerpt(value)}",
                         where=name)
    return float(value)


def positive(value, name: str, *, high: float | None = None) -> float:
    """A finite number > 0 (and <= ``high`` when given)."""
    return number(value, name, low=0.0, low_open=True, high=high)


def integer(value, name: str, *, low: int | None = None, high: int | None = None) -> int:
    """A whole number (not a bool, not a float) within [``low``, ``high``]."""
    ok = isinstance(value, numbers.Integral) and not isinstance(value, (bool, np.bool_))
    if ok and ((low is not None and value < low) or (high is not None and value > high)):
        ok = False
    if not ok:
        lo = "-inf" if low is None else str(low)
        hi = "inf" if high is None else str(high)
        raise InputError(f"must be a whole number in [{lo}, {hi}], got {excerpt(value)}", where=name)
    return int(value)


def flag(value, name: str) -> bool:
    """True or False."""
    if not isinstance(value, (bool, np.bool_)):
        raise InputError(f"must be True or False, got {excerpt(value)}", where=name)
    return bool(value)


def text(value, name: str) -> str:
    """A string."""
    if not isinstance(value, str):
        raise InputError(f"must be text, got {excerpt(value)}", where=name)
    return value


def choice(value, options, name: str) -> str:
    """One of ``options`` (an option table declared once in ``_options``)."""
    if isinstance(value, str) and value in options:
        return value
    raise InputError(f"must be one of {', '.join(map(str, options))}, got {excerpt(value)}", where=name)


def _short(value) -> bool:
    return isinstance(value, (str, numbers.Number, type(None)))


def names(value, name: str) -> tuple[str, ...]:
    """One name or an iterable of names (families, parameter names, patterns) as a tuple of strings."""
    if isinstance(value, str):
        return (value,)
    if isinstance(value, Iterable) and not isinstance(value, (bytes, dict)):
        items = tuple(value)
        if all(isinstance(v, str) for v in items):
            return items
    raise InputError(f"must be a name or a sequence of names (text), got {excerpt(value)}", where=name)


# what the arguments named by a letter hold, for messages that name them
MEANING = {"J": "the Jacobian (a row per equation, a column per parameter)",
           "q": "the joint readings (a row per pose, a column per joint)"}


def float_array(value, name: str, shape: tuple[int | None, ...], *, finite: bool = True) -> np.ndarray:
    """A float array of ``shape`` (None: any length on that axis); finite unless said otherwise."""
    what = f"{MEANING[name]} " if name in MEANING else ""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{what}must be an array of numbers of shape {_shape(shape)}, got {excerpt(value)}",
                         where=name) from None
    if a.ndim != len(shape) or any(n is not None and n != m for n, m in zip(shape, a.shape)):
        raise InputError(f"{what}must have shape {_shape(shape)}, got {a.shape}", where=name)
    if finite and not np.all(np.isfinite(a)):
        raise InputError(f"{what}must hold finite numbers only (no NaN or inf)", where=name)
    return a


def _shape(shape: tuple[int | None, ...]) -> str:
    return "(" + ", ".join("n" if n is None else str(n) for n in shape) + ("," if len(shape) == 1 else "") + ")"


def readings(q, n_joints: int, name: str = "q") -> np.ndarray:
    """Joint readings (n_poses, n_joints), finite; one pose may be given as (n_joints,)."""
    what = f"joint readings: a row per pose, a column for each of the model's {n_joints} joints"
    try:
        a = np.asarray(q, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"expected {what}; got {excerpt(q)}", where=name) from None
    if a.ndim == 1:
        a = a[None, :]
    if a.ndim != 2 or a.shape[1] != n_joints or a.shape[0] == 0:
        got = "no pose" if a.ndim == 2 and a.shape[1] == n_joints else f"{a.shape[-1] if a.ndim else 0} column(s)"
        raise InputError(f"expected {what} (at least one pose); got {got}, shape {np.shape(q)}", where=name)
    if not np.all(np.isfinite(a)):
        raise InputError("joint readings must be finite numbers (no NaN or inf)", where=name)
    return a


def seed(value, name: str = "rng") -> np.random.Generator:
    """A random generator from None, a non-negative whole number, a SeedSequence or a Generator."""
    if isinstance(value, (bool, np.bool_)) or not (
            value is None or isinstance(value, (numbers.Integral, np.random.SeedSequence, np.random.Generator,
                                                np.random.BitGenerator))):
        raise InputError(f"must be None, a non-negative whole number or a numpy Generator, got {excerpt(value)}",
                         where=name)
    if isinstance(value, numbers.Integral) and value < 0:
        raise InputError(f"must be None, a non-negative whole number or a numpy Generator, got {value}", where=name)
    return np.random.default_rng(int(value) if isinstance(value, numbers.Integral) else value)


def pair(value, name: str, *, low: float = 0.0, ordered: bool = True) -> tuple[float, float]:
    """Two numbers (lo, hi) >= ``low`` with lo <= hi when ``ordered``."""
    try:
        lo, hi = value
    except (TypeError, ValueError):
        raise InputError(f"must be two numbers (lo, hi), got {excerpt(value)}", where=name) from None
    lo, hi = number(lo, name, low=low), number(hi, name, low=low)
    if ordered and lo > hi:
        raise InputError(f"must be (lo, hi) with lo <= hi, got ({lo:g}, {hi:g})", where=name)
    return lo, hi


def marker(value, n_markers: int, name: str = "marker") -> int:
    """A marker's index in the model (0 <= marker < n_markers)."""
    return integer(value, name, low=0, high=n_markers - 1)


def path(value, name: str = "path"):
    """A file path: text or an ``os.PathLike``."""
    import os

    if not isinstance(value, (str, os.PathLike)) or (isinstance(value, str) and not value):
        raise InputError(f"must be a file path (text or a Path), got {excerpt(value)}", where=name)
    return value


def mapping(value, name: str) -> dict:
    """A dict (parsed YAML or JSON)."""
    if not isinstance(value, dict):
        raise InputError(f"must be a mapping (a dict), got {excerpt(value) if _short(value) else type(value).__name__}",
                         where=name)
    return value


# -- rules: the checks above declared per argument, applied at the public face ----------------------

# a function that declares what it accepts -> its checked form, the one the public modules export
_CHECKED: dict = {}


def accepts(**rules):
    """Declare what a public function accepts: a rule for each argument named in ``rules``.

    The function is returned as it is: robocal's own code calls it without checks, for its
    arguments are robocal's own. The public modules export its checked form (``checked``), which
    runs the rules before each call, so a user's arguments are checked once, where they come in.
    Its docstring's ``{name, ...}`` lines become those arguments' entries (``_glossary``). A rule is
    called as ``rule(value, name, arguments)`` (``arguments``: every argument of the call by name,
    defaults applied, so a rule can read another argument, e.g. the model's joint count).
    """
    def declare(fn):
        signature = inspect.signature(fn)
        missing = set(rules) - set(signature.parameters)
        if missing:
            raise TypeError(f"{fn.__name__} has no argument {', '.join(sorted(missing))}")
        fn.__doc__ = expand(fn.__doc__)          # the shared entries of its Parameters section

        @functools.wraps(fn)
        def call(*args, **kwargs):
            bound = signature.bind(*args, **kwargs)
            bound.apply_defaults()
            for name, rule in rules.items():
                rule(bound.arguments[name], name, bound.arguments)
            return fn(*args, **kwargs)

        _CHECKED[fn] = call
        return fn

    return declare


def checked(fn):
    """``fn``'s checked form: the rules it declares (``accepts``) run before each call."""
    return _CHECKED[fn]


def export_checked(namespace: dict) -> None:
    """Give a public module's functions their checked form: each function in ``namespace`` (the
    module's ``globals()``) that declares what it accepts is replaced there by ``checked(function)``."""
    for name, value in list(namespace.items()):
        if inspect.isfunction(value) and value in _CHECKED:
            namespace[name] = checked(value)


def is_a(*classes: type):
    """The value is an instance of one of ``classes`` (records such as ``RobotModel``)."""
    def rule(value, name, _):
        if not isinstance(value, classes):
            what = " or ".join(c.__name__ for c in classes)
            got = excerpt(value) if _short(value) else f"a {type(value).__name__}"
            raise InputError(f"must be a {what}, got {got}", where=name)
    return rule


def optional(inner):
    """None, or what ``inner`` allows."""
    def rule(value, name, args):
        if value is not None:
            inner(value, name, args)
    return rule


def in_range(low: float | None = None, high: float | None = None, *, low_open: bool = False,
             high_open: bool = False):
    """A finite number in the interval (open ends where said)."""
    return lambda value, name, _: number(value, name, low=low, high=high, low_open=low_open, high_open=high_open)


POSITIVE = in_range(0.0, low_open=True)
NON_NEGATIVE = in_range(0.0)
FRACTION = in_range(0.0, 1.0, low_open=True, high_open=True)


def whole(low: int | None = None, high: int | None = None):
    """A whole number in [low, high]."""
    return lambda value, name, _: integer(value, name, low=low, high=high)


def one_of(options):
    """One of ``options``."""
    return lambda value, name, _: choice(value, options, name)


FLAG = lambda value, name, _: flag(value, name)  # noqa: E731
TEXT = lambda value, name, _: text(value, name)  # noqa: E731
NAMES = lambda value, name, _: names(value, name)  # noqa: E731
SEED = lambda value, name, _: seed(value, name)  # noqa: E731
PATH = lambda value, name, _: path(value, name)  # noqa: E731
MAPPING = lambda value, name, _: mapping(value, name)  # noqa: E731
PAIR = lambda value, name, _: pair(value, name)  # noqa: E731


def shaped(*shape: int | None, finite: bool = True):
    """A float array of ``shape`` (None: any length on that axis)."""
    return lambda value, name, _: float_array(value, name, shape, finite=finite)


def readings_of(model: str = "model"):
    """Joint readings (n_poses, n_joints) of the model passed as argument ``model``."""
    return lambda value, name, args: readings(value, args[model].n_joints, name)


def marker_of(model: str = "model"):
    """A marker index of the model passed as argument ``model``."""
    return lambda value, name, args: marker(value, len(args[model].markers), name)


def per_joint(model: str = "model", *, low: float = 0.0):
    """One finite number >= ``low`` for every joint, or one per joint reading of the model passed as
    argument ``model``."""
    def rule(value, name, args):
        n = args[model].n_joints
        if isinstance(value, numbers.Number):
            number(value, name, low=low)
            return
        a = float_array(value, name, (n,))
        if np.any(a < low):
            raise InputError(f"must be {n} numbers >= {low:g}, got {excerpt(value)}", where=name)
    return rule


def _callable(value, name, _):
    if not callable(value):
        raise InputError(f"must be callable, got {excerpt(value)}", where=name)


CALLABLE = _callable


def _sequence(value, name, _):
    if isinstance(value, (str, bytes, dict)) or not hasattr(value, "__len__") or not hasattr(value, "__iter__"):
        raise InputError(f"must be a sequence (list, tuple or array), got {excerpt(value)}", where=name)


SEQUENCE = _sequence


def wholes(low: int = 1, high: int | None = None):
    """A non-empty sequence of whole numbers in [low, high]."""
    def rule(value, name, args):
        _sequence(value, name, args)
        if not len(value):
            raise InputError("must hold at least one whole number", where=name)
        for v in value:
            integer(v, name, low=low, high=high)
    return rule


def _masses(value, name, _):
    """A mass in kg >= 0, or one per pose."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        a = np.array(np.nan)
    if a.ndim > 1 or not np.all(np.isfinite(a)) or np.any(a < 0):
        raise InputError(f"must be a mass >= 0 (kg) or one per pose, got {excerpt(value)}", where=name)


MASSES = _masses


def _units(value, name, _):
    from .units import parse_units

    text(value, name)
    try:
        parse_units(value)
    except InputError as e:
        raise InputError(e.detail, where=name) from None


UNIT_SYSTEM = _units


def _real(value, name, _):
    if not (isinstance(value, numbers.Real) and not isinstance(value, bool)):
        raise InputError(f"must be a number, got {excerpt(value)}", where=name)


REAL = _real


def each_a(*classes: type):
    """A sequence whose every item is one of ``classes``."""
    inner = is_a(*classes)

    def rule(value, name, args):
        _sequence(value, name, args)
        for v in value:
            inner(v, name, args)
    return rule


def noise_of(noise_class: type, instruments):
    """None (the default instrument), an instrument class's name, or a ``noise_class`` record."""
    def rule(value, name, _):
        if value is None or isinstance(value, noise_class) or (isinstance(value, str) and value in instruments):
            return
        raise InputError(f"must be a Noise or one of {', '.join(instruments)}, got {excerpt(value)}", where=name)
    return rule


def columns_of(matrix: str):
    """One name per column of the array passed as argument ``matrix``."""
    def rule(value, name, args):
        got = names(value, name)
        n = np.shape(args[matrix])[-1]
        if len(got) != n:
            raise InputError(f"must name each of the {n} columns of {matrix}, got {len(got)} names", where=name)
    return rule


def vector_of(size):
    """A finite float vector whose length ``size(arguments)`` gives (e.g. the model's parameter count)."""
    return lambda value, name, args: float_array(value, name, (size(args),))


def names_in(allowed, what: str = "a parameter of the model"):
    """Names (one or a sequence), each among ``allowed(arguments)``."""
    def rule(value, name, args):
        got = names(value, name)
        ok = set(allowed(args))
        bad = next((n for n in got if n not in ok), None)
        if bad is not None:
            raise InputError(f"{excerpt(bad)} is not {what}{suggest(bad, sorted(ok))}", where=name)
    return rule


def _positive_or_inf(value, name, _):
    """A number > 0, inf allowed (no bound)."""
    if not (isinstance(value, numbers.Real) and not isinstance(value, bool) and value > 0):
        raise InputError(f"must be a number in (0, inf], got {excerpt(value)}", where=name)


POSITIVE_OR_INF = _positive_or_inf


def _mapping_like(value, name, _):
    from collections.abc import Mapping

    if not isinstance(value, Mapping):
        raise InputError(f"must be a mapping (a dict or os.environ), got {excerpt(value)}", where=name)


MAPPING_LIKE = _mapping_like


def _n_poses(value) -> int:
    return len(np.atleast_2d(np.asarray(value, dtype=float)))


def masses_for(q: str = "q"):
    """None, a mass in kg >= 0, or one per pose of the readings passed as argument ``q``."""
    def rule(value, name, args):
        if value is None:
            return
        _masses(value, name, args)
        n = _n_poses(args[q])
        if np.ndim(value) == 1 and len(value) != n:
            raise InputError(f"must be one mass or {n} (one per pose), got {len(value)}", where=name)
    return rule


def items(value, name: str, item: tuple[int, ...], n: int | None = None, *, finite: bool = True) -> np.ndarray:
    """A float array of ``n`` (None: any number of) items of shape ``item``; one item may be given
    alone. Finite, or with ``finite`` False finite or NaN."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"must be an array of numbers of shape {_shape((n,) + item)}, got {excerpt(value)}",
                         where=name) from None
    a = float_array(a[None] if a.ndim == len(item) else a, name, (n,) + item, finite=finite)
    if not finite and np.any(np.isinf(a)):
        raise InputError("must hold finite numbers or NaN (no inf)", where=name)
    return a


def rows_for(q: str, width, *, finite: bool = True):
    """An array (n_poses, ``width(arguments)``), one row per pose of the argument ``q``; a single
    row may be given flat."""
    return lambda value, name, args: items(value, name, (width(args),), _n_poses(args[q]), finite=finite)


def same_robot_as(other: str):
    """A model with the joints and markers of the model passed as argument ``other``."""
    def rule(value, name, args):
        mine, theirs = value, args[other]
        if (mine.n_joints, mine.marker_names) != (theirs.n_joints, theirs.marker_names):
            raise InputError(f"must have the joints and markers of {other} ({theirs.n_joints} joints, markers "
                             f"{', '.join(theirs.marker_names)}), got {mine.n_joints} joints, markers "
                             f"{', '.join(mine.marker_names)}", where=name)
    return rule


def unobserved(value) -> str | None:
    """What a set of observations (measurements or contacts) lacks to hold one: "pose" or "contact"
    without a row, "measured point" when measurements mask every one of theirs; None when it holds some."""
    measured = hasattr(value, "mask")
    if value.q.shape[0] == 0:
        return "pose" if measured else "contact"
    if measured and not value.mask.any() and (value.rot_mask is None or not value.rot_mask.any()):
        return "measured point"
    return None


def measured_on(model: str = "model"):
    """Measurements of the model passed as argument ``model``: at least one pose, its joint count, its markers."""
    def rule(value, name, args):
        m = args[model]
        if (lack := unobserved(value)) is not None:
            raise InputError(f"holds no {lack}", source=value.source or None, where=name)
        if value.q.shape[1] != m.n_joints:
            raise InputError(f"{value.q.shape[1]} joint columns for a model with {m.n_joints} joints", where=name)
        missing = [n for n in value.marker_names if n not in m.marker_names]
        if missing:
            raise InputError(f"marker(s) {', '.join(missing)} are not in the model (markers: "
                             f"{', '.join(m.marker_names)})", where=name)
    return rule


def both(*rules):
    """Every rule of ``rules``, in order."""
    def rule(value, name, args):
        for r in rules:
            r(value, name, args)
    return rule


def _instant(value, name, _):
    """None, a datetime, or ISO 8601 text."""
    from datetime import datetime

    if value is None or isinstance(value, datetime):
        return
    try:
        datetime.fromisoformat(text(value, name).strip().replace("Z", "+00:00"))
    except ValueError:
        raise InputError(f"must be a datetime or ISO 8601 text, got {excerpt(value)}", where=name) from None


INSTANT = _instant


def parameter_columns(names, *, by_name: bool = False):
    """None, or parameter indices into ``names(arguments)`` (the model's parameter names; with
    ``by_name`` a column may be given by its name too)."""
    def rule(value, name, args):
        if value is None:
            return
        _sequence(value, name, args)
        known = names(args)
        for c in value:
            if by_name and isinstance(c, str):
                if c not in known:
                    raise InputError(f"{excerpt(c)} is not a parameter of the model{suggest(c, known)}", where=name)
            else:
                integer(c, name, low=0, high=len(known) - 1)
    return rule


def _norms(value, name, _):
    """Error norms: numbers >= 0 of any shape, NaN where not measured."""
    try:
        v = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        v = np.array(-1.0)
    if np.any(np.isinf(v)) or np.any(v < 0):
        raise InputError(f"must be error norms: numbers >= 0, NaN where not measured, got {excerpt(value)}",
                         where=name)


NORMS = _norms
