"""The ``robocal`` command: parse, call the API, write files atomically, print, return an exit code.

Exit codes: 0 success, 1 an optional extra is missing, 2 bad input or usage (one line on stderr,
nothing written). This is the only module that prints or configures logging (docs/cli.md).
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import sys
import warnings
from pathlib import Path

import numpy as np

from .. import __version__
from . import limit as _cli_limit
from .._files.measurements import measurements_to_csv, parse_orientation, read_measurements, split_sets
from .._errors import DegenerateDataError, InputError, RobocalError, RobocalWarning
from .._calibration import calibrate, compare, identifiability
from .._files.model import model_to_yaml, parse_units, read_model, write_texts
from .._parameters import unit_of
from .._files.result import read_result, result_to_json

MM = 1e3
DEG = 180.0 / np.pi
TABLE_KINDS = ("beta", "alpha", "d", "theta", "r", "k_theta", "k_alpha", "k_beta")


class _Extra(Exception):
    """An optional part of robocal is not installed (exit 1)."""


# ------------------------------------------------------------------------------------------------
# argument types

def _floats(n: int):
    def parse(text: str) -> tuple[float, ...]:
        try:
            vals = tuple(float(v) for v in text.split(","))
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {n} comma-separated numbers, got {text!r}") from None
        if len(vals) != n or not all(np.isfinite(vals)) or min(vals) < 0:
            raise argparse.ArgumentTypeError(f"expected {n} non-negative comma-separated numbers, got {text!r}")
        return vals
    return parse


def _number_in(ok, what: str):
    """An argparse type: a float that passes ``ok``, else a usage error saying ``what`` was expected."""
    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            v = float("nan")
        if not ok(v):
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
        return v
    return parse


_fraction = _number_in(lambda v: 0.0 < v < 1.0, "a fraction between 0 and 1")
_positive = _number_in(lambda v: 0.0 < v < np.inf, "a positive number")


def _marker_mm(text: str) -> tuple[str, tuple[float, float, float]]:
    parts = [t.strip() for t in text.split(",")]
    try:
        xyz = tuple(float(v) / MM for v in parts[1:])
    except ValueError:
        xyz = ()
    if len(parts) != 4 or not parts[0] or len(xyz) != 3 or not all(np.isfinite(xyz)):
        raise argparse.ArgumentTypeError(f"expected NAME,X,Y,Z with X, Y, Z in mm, got {text!r}")
    return parts[0], xyz


def _names(text: str) -> tuple[str, ...]:
    return tuple(s.strip() for s in text.split(",") if s.strip())


def _checked_by(check):
    """An argparse type that keeps the text once ``check`` (a library parser) accepts it."""
    def parse(text: str) -> str:
        try:
            check(text)
        except InputError as e:
            raise argparse.ArgumentTypeError(e.detail) from None
        return text
    return parse


_units = _checked_by(parse_units)
_orientation = _checked_by(parse_orientation)


# ------------------------------------------------------------------------------------------------
# parser

def _csv_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("measurement file")
    g.add_argument("--units", type=_units, help="units of CSV columns without a unit suffix, e.g. mm-deg or m-rad "
                                                "(never guessed: a suffix, a '# units:' line or this option)")
    g.add_argument("--sep", default=",", help="column separator (default ','; ';' for decimal-comma files)")
    g.add_argument("--decimal", default=".", choices=(".", ","), help="decimal mark (default '.')")
    g.add_argument("--orientation", type=_orientation,
                   help="convention of 6D pose columns: quat_xyzw, quat_wxyz, rpy, euler:ZYX (scipy sequences)")


def _parameter_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--parameters", type=_names,
                   help="comma-separated families (geometric, compliance, base, markers, frames) or names "
                        "like j2.alpha (default geometric)")
    p.add_argument("--known", type=_names, default=(), help="families or names held at the model's values, "
                                                            "e.g. base,markers")
    p.add_argument("--tol", type=_positive, default=1e-6, help="identifiability tolerance (default 1e-6)")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="robocal", description="Robot calibration: geometric and compliance "
                                     "parameters, identifiability, the limit of absolute accuracy.")
    parser.add_argument("--version", action="version", version=f"robocal {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    p = sub.add_parser("calibrate", help="identify the parameters from measurements",
                       description="Identify the robot's parameters from measured marker positions; write "
                                   "OUT/calibrated.yaml and OUT/result.json.")
    p.add_argument("model", metavar="MODEL", help="model file (YAML)")
    p.add_argument("csv", metavar="CSV", help="measurement file")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (created)")
    v = p.add_mutually_exclusive_group()
    v.add_argument("--validation", metavar="CSV", help="held-out measurements to judge the result on")
    v.add_argument("--holdout", type=_fraction, metavar="FRACTION", help="hold out this fraction of the poses")
    _parameter_options(p)
    p.add_argument("--compare", action="store_true",
                   help="fit geometric and geometric+compliance on the same data and compare them")
    p.add_argument("--loss", default="linear", choices=("linear", "soft_l1", "huber", "cauchy", "arctan"),
                   help="least-squares loss (robust ones bend for outliers)")
    p.add_argument("--register-base", action="store_true",
                   help="start the base pose from a rigid registration of the nominal robot on the data")
    p.add_argument("--limit-mm", type=_positive, metavar="X", help="limit of absolute accuracy to judge against, mm")
    p.add_argument("--seed", type=int, default=0, help="seed of the --holdout split (default 0)")
    p.add_argument("--out-units", type=_units, default="mm-deg", help="units of calibrated.yaml (default mm-deg)")
    p.add_argument("--force", action="store_true", help="overwrite existing output files")
    p.add_argument("--report", action="store_true", help="also write OUT/report.html (needs robocal[report])")
    _csv_options(p)
    p.set_defaults(func=cmd_calibrate)

    p = sub.add_parser("simulate", help="simulate a measurement campaign on a perturbed robot",
                       description="Draw a 'true' robot near MODEL and write noisy measurements of it.")
    p.add_argument("model", metavar="MODEL", help="nominal model file (YAML)")
    p.add_argument("--out", required=True, metavar="CSV", help="measurement file to write")
    p.add_argument("--poses", type=int, required=True, metavar="N", help="number of random poses")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--noise-mm", type=float, default=0.02, help="measurement noise std, mm (default 0.02)")
    p.add_argument("--length-error-mm", type=_floats(2), default=(0.1, 1.0), metavar="LO,HI",
                   help="range of length errors, mm (default 0.1,1)")
    p.add_argument("--angle-error-deg", type=_floats(2), default=(0.01, 0.1), metavar="LO,HI",
                   help="range of angle errors, deg (default 0.01,0.1)")
    p.add_argument("--parameters", type=_names, default=("geometric",), help="families to perturb")
    p.add_argument("--true-model", metavar="OUT.yaml", help="also write the true model")
    p.add_argument("--units", type=_units, default="mm-deg", help="units of the written files (default mm-deg)")
    p.add_argument("--force", action="store_true", help="overwrite existing output files")
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser("identifiability", help="which parameters can be identified, and what absorbs the others",
                       description="Identifiability of the parameters at the poses of CSV, or at --poses random "
                                   "poses within the joint limits.")
    p.add_argument("model", metavar="MODEL", help="model file (YAML)")
    p.add_argument("csv", metavar="CSV", nargs="?", help="measurement file (its poses); default random poses")
    _parameter_options(p)
    p.add_argument("--poses", type=int, default=200, metavar="N", help="random poses without CSV (default 200)")
    p.add_argument("--seed", type=int, default=0, help="seed of the random poses (default 0)")
    _csv_options(p)
    p.set_defaults(func=cmd_identifiability)

    p = sub.add_parser("report", help="write an HTML report of a result.json (needs robocal[report])")
    p.add_argument("result", metavar="RESULT.json")
    p.add_argument("--out", required=True, metavar="FILE.html")
    p.add_argument("--force", action="store_true", help="overwrite an existing file")
    p.set_defaults(func=cmd_report)

    _cli_limit.register(sub)

    p = sub.add_parser("import-urdf", help="write a robocal model file from a URDF serial chain",
                       description="Convert the chain of a URDF file (metres and radians by the URDF rule) "
                                   "into a robocal model file (modified DH with Hayati's beta).")
    p.add_argument("urdf", metavar="URDF", help="URDF file")
    p.add_argument("--out", required=True, metavar="MODEL.yaml", help="model file to write")
    p.add_argument("--base-link", help="first link of the chain (default: the root link)")
    p.add_argument("--tip-link", help="last link of the chain (default: the leaf of an unbranched chain)")
    p.add_argument("--marker-mm", action="append", type=_marker_mm, metavar="NAME,X,Y,Z",
                   help="a measured point in the tip link's frame, mm (repeatable; default one marker "
                        "'tool' at the tip link's origin)")
    p.add_argument("--units", type=_units, default="mm-deg", help="units of the written file (default mm-deg)")
    p.add_argument("--force", action="store_true", help="overwrite an existing file")
    p.set_defaults(func=cmd_import_urdf)
    return parser


# ------------------------------------------------------------------------------------------------
# entry point

def main(argv=None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as e:  # --help, --version, usage errors: argparse has printed
        return e.code if isinstance(e.code, int) else 2
    if getattr(args, "func", None) is None:
        parser.print_help(sys.stderr)
        return 2
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="robocal: %(levelname)s: %(message)s")
    shown: list[str] = []

    def show(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, RobocalWarning):
            shown.append(str(message))
            print(f"robocal: warning: {message}", file=sys.stderr)
        else:
            default_show(message, category, filename, lineno, file, line)

    default_show = warnings.showwarning
    with warnings.catch_warnings():
        warnings.simplefilter("always", RobocalWarning)
        warnings.showwarning = show
        args.shown_warnings = shown
        try:
            return args.func(args)
        except RobocalError as e:
            print(f"robocal {args.command}: error: {e}", file=sys.stderr)
            return 2
        except _Extra as e:
            print(f"robocal {args.command}: {e}", file=sys.stderr)
            return 1
        except OSError as e:  # the output folder cannot be made or written: the user's to fix
            where = f"{e.filename}: " if e.filename else ""
            print(f"robocal {args.command}: error: {where}{e.strerror or e}", file=sys.stderr)
            return 2


def _report_module():
    """``robocal._report`` or _Extra when its plotting library is missing; checked before any work."""
    try:
        importlib.import_module("matplotlib")
        return importlib.import_module("robocal._presentation.html")
    except ImportError:
        raise _Extra("report extra not installed (pip install 'robocal[report]')") from None


def _write_outputs(files: dict, *, force: bool, report=None) -> None:
    """Write ``files`` ({path: text}) all-or-nothing; ``report`` = (module, result dict, path) too.

    The report is drawn to a temporary name first, so a failure there leaves nothing behind.
    """
    tmp = None
    if report is not None:
        module, d, path = report
        path = Path(path)
        if path.exists() and not force:
            raise InputError("exists; pass --force to overwrite", source=str(path))
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    parents = {Path(f).parent for f in files} | ({Path(report[2]).parent} if report else set())
    made = [p for p in parents if not p.exists()]
    for p in made:
        p.mkdir(parents=True, exist_ok=True)
    try:
        if tmp is not None:
            module.write_report(d, tmp)
        write_texts(files, force=force)
        if tmp is not None:
            os.replace(tmp, path)
    except BaseException:
        if tmp is not None and tmp.exists():
            tmp.unlink()
        for p in made:
            if p.exists() and not any(p.iterdir()):
                p.rmdir()
        raise


def _refuse_existing(paths, force: bool) -> None:
    """Fail before the work, not after it, when outputs exist."""
    if not force:
        for p in paths:
            if Path(p).exists():
                raise InputError("exists; pass --force to overwrite", source=str(p))


# ------------------------------------------------------------------------------------------------
# calibrate

def _read_data(args, model, path):
    return read_measurements(path, model, units=args.units, sep=args.sep, decimal=args.decimal,
                             orientation=args.orientation)


def cmd_calibrate(args) -> int:
    if args.compare and args.parameters:
        raise InputError("--compare chooses the parameters itself; drop --parameters", where="--compare")
    out = Path(args.out)
    names = ["result-geometric.json", "result-compliance.json"] if args.compare else ["result.json"]
    outputs = [out / "calibrated.yaml"] + [out / n for n in names]
    report = _report_module() if args.report else None
    _refuse_existing(outputs + ([out / "report.html"] if report else []), args.force)
    model = read_model(args.model)
    data = _read_data(args, model, args.csv)
    data, validation = split_sets(data)
    if validation is not None and (args.validation or args.holdout):
        raise InputError("the file marks validation rows (column 'set') and --validation/--holdout was given; "
                         "use one", source=args.csv)
    if args.validation:
        validation = _read_data(args, model, args.validation)
    elif args.holdout:
        data, validation = data.split(args.holdout, rng=args.seed)
    runs = [("geometric", ("geometric",)), ("compliance", ("geometric", "compliance"))] if args.compare \
        else [(None, args.parameters or ("geometric",))]
    options = dict(known=args.known, validation=validation, loss=args.loss, tol=args.tol,
                   initial_base="register" if args.register_base else "model",
                   limit=None if args.limit_mm is None else args.limit_mm / MM)
    try:
        if args.compare:
            comparison = compare(model, data, **options)
            results = {"geometric": comparison.geometric, "compliance": comparison.combined}
        else:
            results = {None: calibrate(model, data, parameters=runs[0][1], **options)}
    except DegenerateDataError as e:  # name the file: the data, not the program, fall short
        raise DegenerateDataError(f"{args.csv}: {e}") from None
    if args.compare:
        best = _print_comparison(comparison, args.shown_warnings, weighted=data.sigma is not None)
    else:
        best = results[None]
        _print_summary(best, args.shown_warnings, weighted=data.sigma is not None)
    files = {out / "calibrated.yaml": model_to_yaml(best.calibrated_model, units=args.out_units)}
    for name, (label, _) in zip(names, runs):
        files[out / name] = result_to_json(results[label])
    rep = (report, best.to_dict(), out / "report.html") if report else None
    _write_outputs(files, force=args.force, report=rep)
    print(f"wrote {', '.join(str(p) for p in list(files) + ([rep[2]] if rep else []))}")
    return 0


def _fmt_mm(v) -> str:
    return "      -" if v is None else f"{v * MM:7.3f}"


def _print_stats(stats: dict, indent: str = "  ") -> None:
    print(f"{indent}{'error (mm)':<20}{'n':>5}{'mean':>8}{'std':>8}{'RMS':>8}{'max':>8}")
    for key in ("fit_before", "fit_after", "validation_before", "validation_after"):
        s = stats[key]
        if s["n"]:
            label = key.replace("_", ", ")
            print(f"{indent}{label:<20}{s['n']:>5} {_fmt_mm(s['mean'])} {_fmt_mm(s['std'])} {_fmt_mm(s['rms'])} "
                  f"{_fmt_mm(s['max'])}")


def _display(name: str, value: float) -> str:
    """A parameter value in the units people read: mm, deg, rad/(N m)."""
    unit = unit_of(name)
    if unit == "m":
        return f"{value * MM:+.4f} mm"
    if unit == "rad":
        return f"{value * DEG:+.5f} deg"
    return f"{value:+.3e} {unit}"


def _print_eliminated(ident) -> None:
    if not ident.eliminated:
        return
    print(f"eliminated parameters ({len(ident.eliminated)}): held at nominal; their effect is carried by")
    for a in ident.eliminated:
        if a.absorbers:
            terms = " ".join(f"{c:+.3g}*{n}" for n, c in a.absorbers)
            print(f"  {a.name:<16} = {terms}")
        else:
            print(f"  {a.name:<16} {a.reason}")


def _print_notes(result, shown) -> None:
    notes = [n for n in result.notes if n not in shown]
    for n in notes:
        print(f"note: {n}")


def _print_summary(result, shown=(), weighted=False) -> None:
    print(f"calibration of {result.nominal_model.name} on {result.provenance['data']['n_poses']} poses "
          f"({', '.join(result.families)}, loss {result.loss})")
    _print_stats(result.stats)
    print(f"identified parameters ({len(result.parameters)}): change = estimate - nominal")
    for p in result.parameters:
        print(f"  {p.name:<16} change {_display(p.name, p.change):>18}   std {_display(p.name, p.std)[1:]:>16}")
    _print_eliminated(result.identifiability)
    print(f"solver: {'converged' if result.success else 'NOT converged'} (status {result.status}, {result.nfev} "
          f"evaluations): {result.message}")
    if weighted:
        print(f"residual standard deviation: {result.sigma0:.3g} times the stated measurement standard deviations")
    else:
        print(f"residual standard deviation: {result.sigma0 * MM:.4f} mm")
    if result.limit:
        lim = result.limit
        verdict = "reached" if lim["reached"] else "not reached"
        print(f"limit of absolute accuracy {lim['limit_m'] * MM:.3f} mm: {lim['compared'].replace('_', ' ')} mean "
              f"{lim['mean_error_m'] * MM:.3f} mm, {verdict}")
    _print_notes(result, shown)


def _print_comparison(comparison, shown=(), weighted=False):
    geo, comp = comparison.geometric, comparison.combined
    cols = (("geometric", geo), ("geometric+compliance", comp))
    print(f"comparison on {geo.provenance['data']['n_poses']} poses")
    print(f"  {'':<30}" + "".join(f"{name:>24}" for name, _ in cols))
    print(f"  {'parameters identified':<30}" + "".join(f"{len(r.parameters):>24}" for _, r in cols))
    for key in ("fit_before", "fit_after", "validation_before", "validation_after"):
        if not geo.stats[key]["n"]:
            continue
        for q in ("mean", "std", "rms", "max"):
            label = f"{key.replace('_', ', ')} {q} (mm)"
            print(f"  {label:<30}" + "".join(f"{r.stats[key][q] * MM:>24.3f}" for _, r in cols))
    if weighted:
        print(f"  {'residual std (stated stds)':<30}" + "".join(f"{r.sigma0:>24.4g}" for _, r in cols))
    else:
        print(f"  {'residual std (mm)':<30}" + "".join(f"{r.sigma0 * MM:>24.4f}" for _, r in cols))
    print(f"  {'solver':<30}" + "".join(f"{'converged' if r.success else 'NOT converged':>24}" for _, r in cols))
    best = comparison.best
    print(comparison.verdict)
    print(f"calibrated model written: {'geometric+compliance' if best is comp else 'geometric'}")
    for name, r in cols:
        notes = [n for n in r.notes if n not in shown]
        for n in notes:
            print(f"note ({name}): {n}")
    return best


# ------------------------------------------------------------------------------------------------
# simulate, identifiability, report

def cmd_simulate(args) -> int:
    from .._simulation import simulate

    if args.poses < 1:
        raise InputError(f"--poses must be at least 1, got {args.poses}", where="--poses")
    files = [args.out] + ([args.true_model] if args.true_model else [])
    _refuse_existing(files, args.force)
    model = read_model(args.model)
    true, data = simulate(model, args.poses, parameters=args.parameters,
                          length_error=tuple(v / MM for v in args.length_error_mm),
                          angle_error=tuple(v / DEG for v in args.angle_error_deg),
                          noise=args.noise_mm / MM, seed=args.seed)
    texts = {args.out: measurements_to_csv(data, model=model, units=args.units)}
    if args.true_model:
        texts[args.true_model] = model_to_yaml(true, units=args.units)
    _write_outputs(texts, force=args.force)
    print(f"simulated {data.n_poses} poses of {model.name} (noise {args.noise_mm} mm): wrote "
          f"{', '.join(map(str, texts))}")
    return 0


def cmd_identifiability(args) -> int:
    model = read_model(args.model)
    data = _read_data(args, model, args.csv) if args.csv else None
    if data is None and args.poses < 1:
        raise InputError(f"--poses must be at least 1, got {args.poses}", where="--poses")
    res = identifiability(model, data, parameters=args.parameters or ("geometric",), known=args.known, tol=args.tol,
                          n_random=args.poses, rng=args.seed)
    where = f"the {data.n_poses} poses of {args.csv}" if data is not None else \
        f"{args.poses} random poses (seed {args.seed}) within the joint limits"
    print(f"identifiability of {model.name} at {where}, tolerance {args.tol:g}")
    print("I identified, E eliminated, - not considered")
    kinds = [k for k in ("gamma", "b") if any(res.status(f"{f}.{k}") != "-" for f in model.frame_names)]
    kinds += list(TABLE_KINDS)
    print(f"  {'frame':<12}" + "".join(f"{k:>9}" for k in kinds))
    for f in model.frame_names:
        print(f"  {f:<12}" + "".join(f"{res.status(f'{f}.{k}'):>9}" for k in kinds))
    for owner, kinds2 in [("base", ("x", "y", "z", "rx", "ry", "rz"))] + \
            [(m, ("x", "y", "z", "rx", "ry", "rz")) for m in model.marker_names]:
        print(f"  {owner:<12}" + "".join(f"{k}:{res.status(f'{owner}.{k}'):<3}" for k in kinds2))
    print(f"identified {len(res.identified)} of {len(res.candidates)} candidates (rank {res.rank}, "
          f"{res.n_rows} equations)")
    _print_eliminated(res)
    print(f"condition number: {res.condition_number:.4g}")
    print("observability: " + ", ".join(f"{k} {v:.4g}" for k, v in res.observability.items()))
    return 0


def cmd_import_urdf(args) -> int:
    from .._files.urdf import read_urdf

    _refuse_existing([args.out], args.force)
    if not Path(args.urdf).is_file():
        raise InputError("no such file", source=args.urdf)
    model = read_urdf(args.urdf, base_link=args.base_link, tip_link=args.tip_link, markers=args.marker_mm)
    _write_outputs({args.out: model_to_yaml(model, units=args.units)}, force=args.force)
    print(f"{model.name}: {model.n_joints} joints ({', '.join(model.joint_names)}), {len(model.frames)} frames, "
          f"markers {', '.join(model.marker_names)}: wrote {args.out}")
    return 0


def cmd_report(args) -> int:
    report = _report_module()
    _refuse_existing([args.out], args.force)
    d = read_result(args.result)
    _write_outputs({}, force=args.force, report=(report, d, args.out))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
