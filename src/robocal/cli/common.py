"""What every command shares: argument types, common options, and writing outputs all-or-nothing.

Nothing here imports numpy or the numerical core at import time: ``robocal --help`` and argument
errors stay fast. Commands import what they need when they run.
"""

from __future__ import annotations

import argparse
import contextlib
import contextvars
import importlib
import math
import os
import re
import sys
from pathlib import Path

from .._base.errors import DegenerateDataError, InputError, excerpt
from .._base.options import MAX_POSES
from .._base.units import parse_units

MM = 1e3
DEG = 180.0 / math.pi


class MissingExtra(Exception):
    """An optional part of robocal is not installed (exit 1)."""


# every command's --help: the description, the options, then an example laid out as written
Formatter = argparse.RawDescriptionHelpFormatter


def command(sub, name: str, *, summary: str, description: str, example: str, inputs=()) -> argparse.ArgumentParser:
    """A command's parser: its one-line help, its description, its examples below the options, and its
    input files first, each ``(dest, METAVAR, help)`` or ``(dest, METAVAR, help, "?")`` when optional."""
    p = sub.add_parser(name, help=summary, description=description, epilog=example, formatter_class=Formatter)
    for dest, metavar, text, *nargs in inputs:
        p.add_argument(dest, metavar=metavar, help=text, nargs=nargs[0] if nargs else None)
    return p


class Parser(argparse.ArgumentParser):
    """argparse, but a usage error is one line (``robocal CMD: error: ...``), never the usage block,
    and never echoes more than an excerpt of what was typed."""

    def error(self, message):
        message = " ".join(str(message).split())
        if len(message) > 300:
            message = message[:300] + "..."
        self.exit(2, f"{self.prog}: error: {message}\n")


class CommandParser(Parser):
    """A command's parser: its files and options in any order (``MODEL --out DIR CSV`` as well as
    ``MODEL CSV --out DIR``). argparse alone takes the positionals of one run together, so a CSV that
    may be left out, given after an option, would be refused as unrecognized. An argument left over
    is refused by the command's name."""

    _intermixing = False

    def parse_known_args(self, args=None, namespace=None):
        if self._intermixing:             # the intermixed parse's own passes
            return super().parse_known_args(args, namespace)
        self._intermixing = True
        try:
            parsed, extra = self.parse_known_intermixed_args(args, namespace)
        finally:
            self._intermixing = False
        if extra:                           # said by the command, not by ``robocal`` alone
            self.error(f"unrecognized arguments: {' '.join(extra)}")
        return parsed, extra


# -- argument types: each refuses a bad value at parse time with one line naming the option ----------

def floats(n: int, top: float = math.inf, *, ordered: bool = False):
    """An argparse type: ``n`` comma-separated numbers between 0 and ``top``; ``ordered``: LO <= HI."""
    def parse(text: str) -> tuple[float, ...]:
        try:
            vals = tuple(float(v) for v in text.split(","))
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {n} comma-separated numbers, got {excerpt(text)}") from None
        if len(vals) != n or not all(0 <= v <= top for v in vals):
            raise argparse.ArgumentTypeError(f"expected {n} comma-separated numbers from 0 to {top:g}, got "
                                             f"{excerpt(text)}")
        if ordered and list(vals) != sorted(vals):
            raise argparse.ArgumentTypeError(f"expected LO,HI with LO <= HI, got {excerpt(text)}")
        return vals
    return parse


def integer(lo: int, hi: int, what: str | None = None):
    """An argparse type: a whole number from ``lo`` to ``hi`` (``what`` says why the bound, if any)."""
    def parse(text: str) -> int:
        t = text.strip()
        v = int(t) if re.fullmatch(r"[+-]?\d{1,30}", t) else None
        if v is None or not lo <= v <= hi:
            raise argparse.ArgumentTypeError(f"expected a whole number from {lo:,} to {hi:,}"
                                             f"{f' ({what})' if what else ''}, got {excerpt(text)}")
        return v
    return parse


SEED_MAX = 2 ** 32 - 1
seed = integer(0, SEED_MAX)
poses = integer(1, MAX_POSES, "the pose limit of docs/formats.md")


def number_in(ok, what: str):
    """An argparse type: a float that passes ``ok``, else a usage error saying ``what`` was expected."""
    def parse(text: str) -> float:
        try:
            v = float(text) + 0.0   # -0 is 0: numpy refuses a negative zero scale
        except ValueError:
            v = float("nan")
        if not ok(v):
            raise argparse.ArgumentTypeError(f"expected {what}, got {excerpt(text)}")
        return v
    return parse


def limit_mm(text: str) -> float:
    """The limit of absolute accuracy in mm: a number, or the JSON file ``robocal limit --out`` writes."""
    try:
        v = float(text)
    except ValueError:
        return _limit_from_file(text)
    if not 0.0 < v <= 1e3:
        raise argparse.ArgumentTypeError(f"expected a positive number of mm (up to 1000) or a limit file, got "
                                         f"{excerpt(text)}")
    return v


LIMIT_WRITER = "'robocal limit --out' writes one"


def _limit_from_file(path: str) -> float:
    from .._files.text import load_json, read_text, refuse_other_form

    try:
        found = Path(path).exists()
    except OSError:     # a name longer than the system takes
        found = False
    if not found:
        raise argparse.ArgumentTypeError(f"{excerpt(path)}: no such file (expected mm or a limit file)")
    try:
        text = read_text(path)[0]
        refuse_other_form(text, path, f"a limit file ({LIMIT_WRITER})", ("limit", "json"))
        doc = load_json(text, path)  # bounded and checked like every robocal file
        if not str(doc["schema"]).startswith("robocal.limit/") or doc["unit"] != "m":
            raise KeyError("schema")
        value = doc["limit"]
    except InputError as e:
        raise argparse.ArgumentTypeError(str(e)) from None
    except (KeyError, TypeError):
        raise argparse.ArgumentTypeError(f"{path}: not a limit file ({LIMIT_WRITER})") from None
    if not isinstance(value, (int, float)) or isinstance(value, bool) or not 0.0 < value <= 1.0:
        raise argparse.ArgumentTypeError(f"{path}: limit: expected a positive number of metres (up to 1)")
    return value * MM


fraction = number_in(lambda v: 0.0 < v < 1.0, "a fraction between 0 and 1")
positive = number_in(lambda v: 0.0 < v < math.inf, "a positive number")
# lengths in mm a user may type for noise, repeatability: beyond a metre they are not what the option means
length_mm = number_in(lambda v: 0.0 <= v <= 1e3, "a number from 0 to 1000 (mm)")
tolerance = number_in(lambda v: 0.0 < v < 1.0, "a tolerance between 0 and 1 (exclusive)")
# noise of an instrument, mm and degrees: beyond a metre or half a turn it is not a measurement,
# below a nanometre or a nanodegree no instrument's (the checks' ratios to it overflow)
noise_mm = number_in(lambda v: 1e-6 <= v <= 1e3, "a number from 0.000001 to 1000 (mm)")
noise_deg = number_in(lambda v: 1e-9 <= v <= 180.0, "a number from 0.000000001 to 180 (degrees)")


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
    out = tuple(s.strip() for s in text.split(",") if s.strip())
    if not out or any(len(s) > 100 for s in out):
        raise argparse.ArgumentTypeError(f"expected comma-separated names, got {excerpt(text)}")
    return out


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


def _parse_separator(text: str):
    from .._files.table import parse_separator

    return parse_separator(text)


def column_pairs(text: str) -> dict[str, str]:
    """``FILE=ROBOCAL,...`` -> {file column: robocal column}."""
    out = {}
    for item in (t.strip() for t in text.split(",")):
        file_column, eq, name = (s.strip() for s in item.partition("="))
        if not eq or not name:  # an empty FILE_COLUMN is a header cell without a name (a pandas index)
            raise argparse.ArgumentTypeError(f"expected FILE_COLUMN=ROBOCAL_COLUMN[,...], got {excerpt(item)}")
        out[file_column] = name
    return out


units = checked_by(parse_units)
orientation = checked_by(_parse_orientation)
separator = checked_by(_parse_separator)


# -- options shared by several commands ------------------------------------------------------------

def csv_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("measurement file")
    g.add_argument("--units", type=units, help="units of CSV columns without a unit suffix, e.g. mm-deg or m-rad "
                                               "(never guessed: a suffix, a '# units:' line or this option)")
    g.add_argument("--sep", type=separator, help="column separator: ',', ';', '\\t' or whitespace "
                                                 "(default: detected and said in the summary)")
    g.add_argument("--decimal", choices=(".", ","), help="decimal mark (default: detected)")
    g.add_argument("--orientation", type=orientation,
                   help="convention of 6D pose columns: quat_xyzw, quat_wxyz, rpy, euler:ZYX (scipy sequences)")
    g.add_argument("--map", type=column_pairs, action="append", default=[], metavar="FILE=NAME,...",
                   help="rename the file's columns to robocal's, e.g. 'X=tool_x_mm,Y=tool_y_mm,Z=tool_z_mm'; "
                        "'=pose' names a header cell without a name; 'x_t+x_dif=tool_x_mm' adds two columns")
    g.add_argument("--header", type=names, metavar="NAME,...",
                   help="the column names of a file without a header line (its first line is data)")
    g.add_argument("--ignore", type=names, action="append", default=[], metavar="COLUMN,...",
                   help="columns of the file to ignore")
    g.add_argument("--unknown", choices=("refuse", "ignore"),
                   help="columns robocal does not know: refuse (default) or ignore them, listed in the summary")
    g.add_argument("--profile", metavar="YAML", help="instrument profile: separator, units, column map... "
                                                     "(docs/formats.md); options given here win over it")
    g.add_argument("--joints", metavar="CSV", help="joint readings in a file of their own, joined to the "
                                                   "measurements on the pose column (--key)")
    g.add_argument("--key", metavar="COLUMN", help="the column that joins --joints to the measurements "
                                                   "(default pose)")


def imported_model_options(p: argparse.ArgumentParser) -> None:
    """--out, --units and --force of a command that writes a model file it imported."""
    p.add_argument("--out", required=True, metavar="MODEL.yaml", help="model file to write")
    p.add_argument("--units", type=units, default="mm-deg", help="units of the written file (default mm-deg)")
    p.add_argument("--force", action="store_true", help="overwrite an existing file")


def write_imported_model(args, model, what: str, source: str | None = None) -> None:
    """Write the imported ``model`` to ``args.out`` and say what it holds (``what``: frames, ...);
    ``source``: the imported file, named when the model would not read back."""
    from .._files.checked import check_model_text
    from .._files.model import model_to_yaml

    text = model_to_yaml(model, units=args.units)
    # never a model file robocal would refuse, or another model
    check_model_text(model, text, source=source or args.out)
    write_outputs({args.out: text}, force=args.force)
    print(f"{model.name}: {model.n_joints} joints ({', '.join(model.joint_names)}), {what}markers "
          f"{', '.join(model.marker_names)}: wrote {args.out}")


def parameter_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--parameters", type=names,
                   help="comma-separated families (geometric, compliance, backlash, transmission, base, markers, "
                        "frames), names "
                        "like j2.alpha or patterns like '*.theta' and 'j2.*' (default geometric)")
    p.add_argument("--known", type=names, default=(), help="families, names or patterns held at the model's "
                                                           "values, e.g. base,markers")
    p.add_argument("--tol", type=tolerance, default=1e-6, help="identifiability tolerance, between 0 and 1 "
                                                                "(default 1e-6)")


def mass_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--assume-masses", action="store_true",
                   help="link masses from the geometry (docs/conventions.md) instead of the model's, for compliance "
                        "without CAD masses; compliances are then relative unless --total-mass is given")
    p.add_argument("--total-mass", type=positive, metavar="KG",
                   help="the arm's mass without payloads, spread over the links as --assume-masses does")


def masses_as_asked(args, model):
    """``model``, or with --assume-masses/--total-mass the model with masses from its geometry."""
    if not args.assume_masses and args.total_mass is None:
        return model
    from .._model.robot import default_masses

    return default_masses(model, args.total_mass)


def read_data(args, model, path, *, targets: bool = False):
    from .._files.measurements import read_measurements
    from .._files.seatings import MANIFEST

    if os.path.isdir(path) and os.path.exists(os.path.join(path, MANIFEST)):
        raise InputError("is a folder of seatings, not a measurement file: give it as --contacts FOLDER",
                         source=str(path))
    if os.path.basename(path) == MANIFEST and os.path.isfile(path):
        raise InputError("is the manifest of a folder of seatings, not a measurement file: give it (or its folder) "
                         "as --contacts", source=str(path))
    columns = {k: v for m in args.map for k, v in m.items()}
    columns.update({c: None for group in args.ignore for c in group})
    return read_measurements(path, model, units=args.units, sep=args.sep, decimal=args.decimal,
                             orientation=args.orientation, columns=columns or None, targets=targets,
                             unknown=args.unknown,
                             profile=args.profile, joints=args.joints, key=args.key, header=args.header)


# -- outputs ----------------------------------------------------------------------------------------

def report_module():
    """The report writer, or MissingExtra when its plotting library is missing; checked before any work."""
    try:
        importlib.import_module("matplotlib")
        return importlib.import_module("robocal._presentation.html")
    except ImportError:
        raise MissingExtra("report extra not installed (pip install 'robocal[report]')") from None


# the files the running command reads (``input_files``), which no output of it may replace
INPUTS: contextvars.ContextVar[tuple[str, ...]] = contextvars.ContextVar("inputs", default=())


def input_files(args) -> tuple[str, ...]:
    """The existing files among a command's arguments (its outputs, ``--out``, left out)."""
    found = []
    for key, value in vars(args).items():
        if key == "out" or key.startswith("_"):
            continue
        for v in value if isinstance(value, (list, tuple)) else (value,):
            if isinstance(v, (str, os.PathLike)) and os.path.isfile(v):
                found.append(os.fspath(v))
    return tuple(found)


def refuse_existing(paths, force: bool) -> None:
    """Fail before the work, not after it, when an output exists (without ``force``), is a file the
    command reads (with ``force`` too: it would be gone before anyone saw what replaced it), or
    cannot be written (its folder is read-only, a file, ...)."""
    from .._files.text import check_writable

    given: dict[str, str] = {}
    for p in paths:     # one file for two outputs: the second written would replace the first
        key = os.path.realpath(p)
        if key in given:
            raise InputError(f"given for two outputs (also as {given[key]}): each output needs a file of its own",
                             source=str(p))
        given[key] = str(p)
    for p in paths:
        with contextlib.suppress(OSError):
            read = next((f for f in INPUTS.get() if os.path.exists(p) and os.path.samefile(p, f)), None)
            if read is not None:
                same = "" if os.path.abspath(p) == os.path.abspath(read) else f"the same file as {read}, "
                raise InputError(f"{same}a file this command reads: the output would replace what it is made "
                                 "from; write it elsewhere", source=str(p))
    check_writable(paths, force=force)


def refuse_misnamed(out: str, written: str, by: str, hint: str = "") -> None:
    """Refuse an ``--out`` named as another kind of file than the ``written`` one (``CSV``, ``URDF``,
    ``rapid program``...), ``by`` what writes it: before anything is read, and with ``--force`` too,
    since the next program to open it goes by its name. ``hint``: what else the user may do."""
    from .._files.programs import EXTENSIONS

    kinds = {".csv": "CSV", ".urdf": "URDF", ".yaml": "model", ".yml": "model", ".json": "JSON",
             **{ext: f"{dialect} program" for ext, dialect in EXTENSIONS.items()}}
    suffix = Path(out).suffix.lower()
    if kinds.get(suffix, written) != written:
        names = [ext for ext, kind in kinds.items() if kind == written]
        raise InputError(f"names a {kinds[suffix]} file ({suffix}), but {by} writes a {written} file: give it a "
                         f"{', '.join(names[:-1]) + ' or ' if len(names) > 1 else ''}{names[-1]} name{hint}",
                         where="--out")


def warn_if_failed(path, record: dict | None, use: str) -> None:
    """A warning on stderr when the model file at ``path`` is a calibration that failed its checks
    (written anyway with --write-failed): ``use`` says what is about to be made with it."""
    if record is not None and record.get("verdict") == "fail":
        failed = ", ".join(record.get("failed") or ()) or "its checks"
        print(f"robocal: warning: {path}: a calibration that failed ({failed}), written with --write-failed: "
              f"{use} a model its calibration said not to use", file=sys.stderr)


def require_finite(what: str, values: dict) -> None:
    """Stop, before anything is written, when a computed value is NaN or infinite: a file holding
    one would be nonsense that looks like a result. ``values``: name -> number or array."""
    import numpy as np

    bad = [name for name, v in values.items() if not np.all(np.isfinite(np.asarray(v, dtype=float)))]
    if bad:
        more = f" and {len(bad) - 3} more" if len(bad) > 3 else ""
        raise DegenerateDataError(f"{what} came out non-finite ({', '.join(bad[:3])}{more}): the input is out of "
                                  "range for this computation; nothing written")


def write_outputs(files: dict, *, force: bool, report=None) -> None:
    """Write ``files`` ({path: text}) all-or-nothing; ``report`` = (module, result, path) too.

    The report is rendered first, so a failure there leaves nothing behind. The temporary files
    of earlier runs that were killed are removed from the output folders first.
    """
    from .._files.text import remove_orphans, write_texts

    files = dict(files)
    if report is not None:
        module, result, path = report
        files[Path(path)] = module.render_report(result)
    parents = {Path(f).parent for f in files}
    made = [p for p in sorted(parents) if not p.exists()]
    for p in made:
        p.mkdir(parents=True, exist_ok=True)
    for p in sorted(parents):  # the command's own folders: temporaries its killed runs left behind
        remove_orphans(p)
    try:
        write_texts(files, force=force)
    except BaseException:
        for p in reversed(made):
            if p.exists() and not any(p.iterdir()):
                p.rmdir()
        raise
