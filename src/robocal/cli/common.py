"""What every command shares: argument types, common options, and writing outputs all-or-nothing.

Nothing here imports numpy or the numerical core at import time: ``robocal --help`` and argument
errors stay fast. Commands import what they need when they run.
"""

from __future__ import annotations

import argparse
import importlib
import math
from pathlib import Path

from .._errors import InputError, excerpt
from .._units import parse_units

MM = 1e3
DEG = 180.0 / math.pi


class MissingExtra(Exception):
    """An optional part of robocal is not installed (exit 1)."""


# every command's --help: the description, the options, then an example laid out as written
Formatter = argparse.RawDescriptionHelpFormatter


# -- argument types: each refuses a bad value at parse time with one line naming the option ----------

def floats(n: int):
    def parse(text: str) -> tuple[float, ...]:
        try:
            vals = tuple(float(v) for v in text.split(","))
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {n} comma-separated numbers, got {excerpt(text)}") from None
        if len(vals) != n or not all(map(math.isfinite, vals)) or min(vals) < 0:
            raise argparse.ArgumentTypeError(f"expected {n} non-negative comma-separated numbers, got "
                                             f"{excerpt(text)}")
        return vals
    return parse


def number_in(ok, what: str):
    """An argparse type: a float that passes ``ok``, else a usage error saying ``what`` was expected."""
    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            v = float("nan")
        if not ok(v):
            raise argparse.ArgumentTypeError(f"expected {what}, got {excerpt(text)}")
        return v
    return parse


def count(text: str) -> int:
    """A whole number of at least 1."""
    try:
        v = int(text)
    except ValueError:
        v = 0
    if v < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number of at least 1, got {excerpt(text)}")
    return v


def limit_mm(text: str) -> float:
    """The limit of absolute accuracy in mm: a number, or the JSON file ``robocal limit --out`` writes."""
    try:
        v = float(text)
    except ValueError:
        return _limit_from_file(text)
    if not 0.0 < v < math.inf:
        raise argparse.ArgumentTypeError(f"expected a positive number of mm or a limit file, got {excerpt(text)}")
    return v


def _limit_from_file(path: str) -> float:
    import json

    try:
        with open(path, encoding="utf-8") as fh:
            doc = json.load(fh)
        if not str(doc["schema"]).startswith("robocal.limit/") or doc["unit"] != "m":
            raise KeyError("schema")
        value = doc["limit"]
    except FileNotFoundError:
        raise argparse.ArgumentTypeError(f"{path}: no such file (expected mm or a limit file)") from None
    except (OSError, ValueError, KeyError, TypeError):
        raise argparse.ArgumentTypeError(f"{path}: not a limit file ('robocal limit --out' writes one)") from None
    if not isinstance(value, (int, float)) or not 0.0 < value < math.inf:
        raise argparse.ArgumentTypeError(f"{path}: limit: expected a positive number of metres")
    return value * MM


fraction = number_in(lambda v: 0.0 < v < 1.0, "a fraction between 0 and 1")
positive = number_in(lambda v: 0.0 < v < math.inf, "a positive number")
non_negative = number_in(lambda v: 0.0 <= v < math.inf, "a number of at least 0")


def marker_mm(text: str) -> tuple[str, tuple[float, float, float]]:
    parts = [t.strip() for t in text.split(",")]
    try:
        xyz = tuple(float(v) / MM for v in parts[1:])
    except ValueError:
        xyz = ()
    if len(parts) != 4 or not parts[0] or len(xyz) != 3 or not all(map(math.isfinite, xyz)):
        raise argparse.ArgumentTypeError(f"expected NAME,X,Y,Z with X, Y, Z in mm, got {excerpt(text)}")
    return parts[0], xyz


def names(text: str) -> tuple[str, ...]:
    return tuple(s.strip() for s in text.split(",") if s.strip())


def checked_by(check):
    """An argparse type that keeps the text once ``check`` (a library parser) accepts it."""
    def parse(text: str) -> str:
        try:
            check(text)
        except InputError as e:
            raise argparse.ArgumentTypeError(e.detail) from None
        return text
    return parse


def _parse_orientation(text: str):
    from .._files.measurements import parse_orientation

    return parse_orientation(text)


def separator(text: str) -> str:
    """One character; ``\\t`` or ``tab`` for a tab, as a shell passes ``--sep '\\t'``."""
    sep = "\t" if text in ("\\t", "tab", "TAB") else text
    if len(sep) != 1:
        raise argparse.ArgumentTypeError(f"expected one character (or '\\t' for a tab), got {excerpt(text)}")
    return sep


units = checked_by(parse_units)
orientation = checked_by(_parse_orientation)


# -- options shared by several commands ------------------------------------------------------------

def csv_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("measurement file")
    g.add_argument("--units", type=units, help="units of CSV columns without a unit suffix, e.g. mm-deg or m-rad "
                                               "(never guessed: a suffix, a '# units:' line or this option)")
    g.add_argument("--sep", type=separator, default=",",
                   help="column separator (default ','; ';' for decimal-comma files; '\\t' for tabs)")
    g.add_argument("--decimal", default=".", choices=(".", ","), help="decimal mark (default '.')")
    g.add_argument("--orientation", type=orientation,
                   help="convention of 6D pose columns: quat_xyzw, quat_wxyz, rpy, euler:ZYX (scipy sequences)")


def parameter_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--parameters", type=names,
                   help="comma-separated families (geometric, compliance, base, markers, frames) or names "
                        "like j2.alpha (default geometric)")
    p.add_argument("--known", type=names, default=(), help="families or names held at the model's values, "
                                                           "e.g. base,markers")
    p.add_argument("--tol", type=positive, default=1e-6, help="identifiability tolerance (default 1e-6)")


def read_data(args, model, path, *, targets: bool = False):
    from .._files.measurements import read_measurements

    return read_measurements(path, model, units=args.units, sep=args.sep, decimal=args.decimal,
                             orientation=args.orientation, targets=targets)


# -- outputs ----------------------------------------------------------------------------------------

def report_module():
    """The report writer, or MissingExtra when its plotting library is missing; checked before any work."""
    try:
        importlib.import_module("matplotlib")
        return importlib.import_module("robocal._presentation.html")
    except ImportError:
        raise MissingExtra("report extra not installed (pip install 'robocal[report]')") from None


def refuse_existing(paths, force: bool) -> None:
    """Fail before the work, not after it, when outputs exist."""
    if not force:
        for p in paths:
            if Path(p).exists():
                raise InputError("exists; pass --force to overwrite", source=str(p))


def write_outputs(files: dict, *, force: bool, report=None) -> None:
    """Write ``files`` ({path: text}) all-or-nothing; ``report`` = (module, result, path) too.

    The report is rendered first, so a failure there leaves nothing behind.
    """
    from .._files.text import write_texts

    files = dict(files)
    if report is not None:
        module, result, path = report
        files[Path(path)] = module.render_report(result)
    parents = {Path(f).parent for f in files}
    made = [p for p in sorted(parents) if not p.exists()]
    for p in made:
        p.mkdir(parents=True, exist_ok=True)
    try:
        write_texts(files, force=force)
    except BaseException:
        for p in reversed(made):
            if p.exists() and not any(p.iterdir()):
                p.rmdir()
        raise
