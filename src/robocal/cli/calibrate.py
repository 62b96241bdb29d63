"""``robocal calibrate``: identify the parameters from measurements, write the model and the result."""

from __future__ import annotations

import logging
from pathlib import Path

from .._base.errors import DegenerateDataError, InputError
from .._base.options import BACKLASH_SIDES, INSTRUMENT_NOISE, LOSSES, OUTLIER_ACTIONS, WEAK_ACTIONS
from . import common, record

# the identifications --compare writes a result of, each by the family it adds
COMPARED = ("geometric", "compliance", "backlash", "transmission")

# exit code of a calibration whose checks failed (docs/cli.md)
FAILED = 3


EXAMPLE = """examples:
  robocal calibrate examples/th8/model.yaml examples/th8/measurements.csv --out runs/compare --compare --known markers
  robocal calibrate examples/th8/model.yaml examples/th8/measurements.csv --out runs/geo --limit-mm runs/th8/limit.json

(runs/th8/limit.json: the limit of absolute accuracy 'make demo' writes, or 'robocal limit --out'.)

Exit code 3 when a check fails (docs/checks.md): result.json is written, calibrated.yaml only
with --write-failed."""

def register(sub) -> None:
    p = common.command(sub, "calibrate", summary="identify the parameters from measurements",
                       description="Identify the robot's parameters from measured marker positions and/or contacts "
                                   "(--contacts); write OUT/calibrated.yaml and OUT/result.json.",
                       example=EXAMPLE,
                       inputs=[("model", "MODEL", "model file (YAML)"),
                               ("csv", "CSV", "measurement file (may be left out with --contacts)", "?")])
    p.add_argument("--contacts", metavar="FILE", help="contact file, or folder of seatings: joint-only recordings of "
                   "sockets, planes and ball bars (docs/formats.md), fitted alone or with CSV")
    p.add_argument("--holdout-placement", type=common.names, metavar="NAMES",
                   help="with --contacts: hold out these placements (comma-separated) to judge the result on")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (created)")
    v = p.add_mutually_exclusive_group()
    v.add_argument("--validation", "--validate", metavar="CSV", dest="validation",
                   help="held-out measurements to judge the result on (without: cross-validation, --folds)")
    v.add_argument("--holdout", type=common.fraction, metavar="FRACTION", help="hold out this fraction of the poses")
    common.parameter_options(p)
    p.add_argument("--compare", action="store_true",
                   help="fit geometric and geometric+compliance on the same data, then transmission terms on the "
                        "one kept, and keep what helps in use, where measured and over the range of use")
    p.add_argument("--no-transmission", dest="transmission", action="store_false",
                   help="with --compare: leave the transmission terms out")
    p.add_argument("--backlash", action="store_true",
                   help="with --compare: a third identification, backlash added to the one kept")
    p.add_argument("--backlash-side", choices=BACKLASH_SIDES, default=None,
                   help="where each joint rests in its lost motion in this campaign: on the side its gravity load "
                        "pushes it to, or behind its last move (default: the model file's backlash.side)")
    p.add_argument("--loss", default="linear", choices=LOSSES,
                   help="least-squares loss: linear (default) or a robust one that bends for outliers")
    p.add_argument("--register-base", action="store_true",
                   help="start the base pose from a rigid registration of the nominal robot on the data")
    p.add_argument("--limit-mm", type=common.limit_mm, metavar="X|LIMIT.json",
                   help="limit of absolute accuracy to judge against: mm, or the file 'robocal limit --out' wrote")
    p.add_argument("--folds", type=common.integer(2, 1000), default=5, metavar="K",
                   help="folds of the cross-validation that estimates the accuracy in use without --validation "
                        "(default 5): the file's series where it has a series column (K unused), else K blocks of "
                        "consecutive poses where consecutive poses are neighbours, else K folds drawn at random "
                        "(the same draw every run)")
    p.add_argument("--register-validation", action="store_true",
                   help="with --validation from another set-up: register base and tool on it before judging")
    p.add_argument("--seed", type=common.seed, default=0, help="seed of the --holdout split (default 0)")
    p.add_argument("--out-units", type=common.units, default="mm-deg", help="units of calibrated.yaml (default mm-deg)")
    p.add_argument("--force", action="store_true",
                   help="overwrite existing output files; an earlier run's files this run does not write are removed")
    p.add_argument("--report", action="store_true", help="also write OUT/report.html (needs robocal[report])")
    g = p.add_argument_group("checks (docs/checks.md)")
    g.add_argument("--instrument", choices=tuple(INSTRUMENT_NOISE), default="tracker",
                   help="instrument class whose noise the checks expect where the data state none (default tracker)")
    g.add_argument("--noise-mm", type=common.noise_mm, metavar="X",
                   help="expected measurement noise, mm per axis (overrides the instrument's)")
    g.add_argument("--noise-deg", type=common.noise_deg, metavar="X",
                   help="expected rotation noise of 6D measurements, degrees (overrides the instrument's)")
    g.add_argument("--on-outliers", choices=OUTLIER_ACTIONS, default="refit",
                   help="refit: set aside measured points that stand out alone (blunders) and fit again without "
                        "them, kept when that lowers the cross-validated error (default; linear loss); flag: only "
                        "name them, kept in the fit (the outliers check warns); docs/checks.md")
    g.add_argument("--weak", choices=WEAK_ACTIONS, default="eliminate",
                   help="hold weakly identifiable parameters at nominal (default), or keep them and warn")
    g.add_argument("--nonnegative-compliance", action="store_true", help="keep identified compliances >= 0")
    common.mass_options(p)
    g.add_argument("--diagnose", action="store_true",
                   help="print the diagnosis in full: every hypothesis tested, those refitted, those these data cannot "
                        "tell (every calibration is diagnosed; a cause it names is printed first; docs/diagnosis.md)")
    g.add_argument("--write-failed", action="store_true",
                   help="write calibrated.yaml even when a check fails (it then carries the verdict)")
    common.csv_options(p)
    record.record_options(p.add_argument_group("store of calibrations (docs/store.md)"), robot=True)
    p.set_defaults(func=run)


def _inputs(args):
    """The model, the fitted data (or None with contacts alone), the held-out data (or None) and
    the contacts (or None) the options name; with contacts, the held-out set is their placements."""
    from .._files.measurements import split_sets
    from .._files.model import read_model

    model = common.masses_as_asked(args, read_model(args.model))
    if args.backlash_side is not None:
        model = model.replace(backlash_side=args.backlash_side)
    contacts = validation = data = None
    if args.contacts:
        contacts = _contacts(args, model)
        held = args.holdout_placement or (_drawn_placements(contacts, args) if args.holdout else None)
        if held:
            contacts, validation = contacts.split_placements(held)
            if not contacts.n_rows:
                raise InputError(f"holds out every placement ({', '.join(held)}); keep one to fit on",
                                 source=args.contacts, where="--holdout-placement")
        elif args.validation:       # measured points held out
            validation = common.read_data(args, model, args.validation)
        if args.csv is not None:
            data, held = split_sets(common.read_data(args, model, args.csv))
            if held is not None:
                raise InputError("the file marks validation rows (column 'set'); with --contacts the held-out set is "
                                 "their placements (--holdout-placement)", source=args.csv)
        return model, data, validation, contacts
    data, validation = split_sets(common.read_data(args, model, args.csv))
    if validation is not None and (args.validation or args.holdout):
        raise InputError("the file marks validation rows (column 'set') and --validation/--holdout was given; "
                         "use one", source=args.csv)
    if args.validation:
        validation = common.read_data(args, model, args.validation)
    elif args.holdout:
        data, validation = data.split(args.holdout, rng=args.seed)
        if not data.n_poses or not validation.n_poses:
            n = data.n_poses + validation.n_poses
            raise InputError(f"{args.holdout:g} of {n} poses holds out {validation.n_poses}: give a fraction that "
                             f"holds out at least one pose and keeps one to fit on (1/{n} to {n - 1}/{n})",
                             source=args.csv, where="--holdout")
    return model, data, validation, contacts


def _contacts(args, model):
    """The contact file or folder of seatings, its placements checked against --holdout-placement."""
    from .._files.contacts import read_contacts

    contacts = read_contacts(args.contacts, model)
    missing = [p for p in args.holdout_placement or () if p not in contacts.placements()]
    if missing:
        raise InputError(f"no placement {missing[0]!r} (placements: {', '.join(contacts.placements())})",
                         source=args.contacts, where="--holdout-placement")
    return contacts


def _drawn_placements(contacts, args) -> list[str]:
    """--holdout with contacts: that fraction of the placements (at least one, never all), drawn with --seed."""
    import numpy as np

    names = contacts.placements()
    if len(names) < 2:
        raise InputError(f"holds out placements, and {args.contacts} has {len(names)}", where="--holdout")
    k = min(max(1, round(args.holdout * len(names))), len(names) - 1)
    held = sorted(np.random.default_rng(args.seed).choice(len(names), k, replace=False))
    print(f"held out placement(s) {', '.join(names[i] for i in held)} of {len(names)} (--holdout {args.holdout:g}, "
          f"--seed {args.seed})")
    return [names[i] for i in held]


def _one_held_out_set(args) -> None:
    """With contacts, one held-out set: measured points, or placements (named or drawn)."""
    given = [f for f, v in (("--validation", args.validation), ("--holdout", args.holdout),
                            ("--holdout-placement", args.holdout_placement)) if v]
    if len(given) > 1:
        raise InputError(f"give one held-out set: {' or '.join(given)}", where=given[1])


def _headline(result) -> dict:
    """The numbers of a result that must be finite: estimates, their deviations, the fit's statistics."""
    out = {f"{p.name} estimate": p.estimate for p in result.parameters}
    out.update({f"{p.name} std": p.std for p in result.parameters})
    for key in ("fit_before", "fit_after"):
        s = getattr(result.stats, key)
        out.update({f"{key} {f}": getattr(s, f) for f in ("mean", "rms", "max") if s.n})
    from .._model.parameters import parameter_vector

    out["the calibrated model"] = parameter_vector(result.calibrated_model)
    return out


def _diagnosis(args, best) -> None:
    """With --diagnose, the diagnosis in full: what was tested, refitted and cannot be told here."""
    if not args.diagnose or best.diagnosis is None:
        return
    from .._presentation.text import diagnosis_lines

    print("\n".join(diagnosis_lines(best.diagnosis, full=True)))


def _check_arguments(args) -> None:
    """The options that go together: a measurement file or contacts, one held-out set, --compare
    without --parameters, --backlash and --no-transmission with --compare, --type, --at and --store
    with --record."""
    if args.contacts:
        _one_held_out_set(args)
    elif args.csv is None:
        raise InputError("give a measurement file (CSV) or a contact file (--contacts)", where="calibrate")
    elif args.holdout_placement:
        raise InputError("needs --contacts", where="--holdout-placement")
    if args.compare and args.parameters:
        raise InputError("--compare chooses the parameters itself; drop --parameters", where="--compare")
    if args.backlash and not args.compare:
        raise InputError("--backlash adds a third identification to --compare; for one identification name the "
                         "family: --parameters geometric compliance backlash", where="--backlash")
    unused = [option for option, key in record.RECORD_OPTIONS if getattr(args, key) is not None]
    if unused and not args.record:
        raise InputError("keeps the result in the store of calibrations: needs --record ROBOT", where=unused[0])
    if not args.transmission and not args.compare:
        raise InputError("--no-transmission leaves the transmission terms out of --compare; without --compare "
                         "name the families: --parameters", where="--no-transmission")


def _result_names(args) -> list[str]:
    """The result files that may be written: with --compare each identification's, then the
    chosen one as result.json (what report and compensate take)."""
    kept = [k for k in COMPARED if k not in ("backlash", "transmission") or getattr(args, k)]
    return [f"result-{k}.json" for k in kept] + ["result.json"] if args.compare else ["result.json"]


def _outputs(out: Path) -> list[Path]:
    """Every file a calibration may write in its folder, whatever its options: one run's set, so that
    a run with --force leaves none of an earlier run's beside its own (a model that passed beside a
    result that failed)."""
    from .._files.model import CALIBRATED_MODEL
    from .._files.text import sidecar_path

    names = [f"result-{k}.json" for k in COMPARED] + ["result.json"]
    return [out / CALIBRATED_MODEL] + [out / n for n in names] + [sidecar_path(out / n) for n in names] + \
        [out / "report.html"]


def _remove_stale(out: Path, written) -> None:
    """Remove the files of an earlier run this one did not replace (--force), and say so."""
    stale = [p for p in _outputs(out) if p not in set(written) and (p.exists() or p.is_symlink())]
    for p in stale:
        p.unlink()
    if stale:
        print(f"removed {', '.join(str(p) for p in stale)}: an earlier run's, which this one does not replace")


def _result_file(name: str) -> str:
    """The file of a comparison's identification, by the family it adds: result-compliance.json ..."""
    return f"result-{name.rsplit(' ', 1)[-1]}.json"


def _calibrate_options(args, validation, contacts) -> dict:
    """The keyword arguments of ``calibrate`` (and ``compare``) the options give, in SI."""
    from .._model.measurements import Noise

    noise = Noise.of(args.instrument, position=None if args.noise_mm is None else args.noise_mm / common.MM,
                     rotation=None if args.noise_deg is None else args.noise_deg / common.DEG)
    return dict(known=args.known, validation=validation, loss=args.loss, tol=args.tol,
                initial_base="register" if args.register_base else "model",
                limit=None if args.limit_mm is None else args.limit_mm / common.MM, noise=noise,
                on_outliers=args.on_outliers, weak=args.weak, nonnegative_compliance=args.nonnegative_compliance,
                folds=args.folds, register_validation=args.register_validation, contacts=contacts)


def _identified(args, model, data, options: dict) -> tuple:
    """The chosen result and every result to write by file name (with --compare each
    identification's, then the chosen one), their summary printed; a failure the data cause names
    the file."""
    import numpy as np

    from .._diagnosis.calibrate import calibrate, compare
    from .._presentation.text import calibration_summary, comparison_summary

    contacts = options["contacts"]
    weighted = contacts is not None or data.sigma is not None or data.has_orientation
    source = args.contacts if contacts is not None else args.csv
    try:
        if args.compare:
            comparison = compare(model, data, backlash=args.backlash, transmission=args.transmission, **options)
            best = comparison.best
            print(comparison_summary(comparison, shown=args.shown_warnings, weighted=weighted))
            named = {_result_file(k): r for k, r in comparison.results.items()}
            return best, {**named, "result.json": best}
        best = calibrate(model, data, parameters=args.parameters or ("geometric",), **options)
        print(calibration_summary(best, shown=args.shown_warnings, weighted=weighted))
        return best, {"result.json": best}
    except DegenerateDataError as e:  # name the file: the data, not the program, fall short
        raise DegenerateDataError(f"{source}: {e}") from None
    except np.linalg.LinAlgError as e:  # what the numbers leave of the fit is singular: the data's to fix
        raise DegenerateDataError(f"{source}: the fit is numerically singular on these data ({e})") from None


def _output_files(args, out: Path, named: dict, best, report) -> dict:
    """The files to write: each result (``named``: file name -> result) with its per-pose file, the
    calibrated model unless the calibration failed (or --write-failed), the report when asked."""
    from .._files.model import CALIBRATED_MODEL, model_to_yaml
    from .._files.result import result_files
    from .._identification.result import calibration_record

    files = {p: f for n, r in named.items() for p, f in result_files(r, out / n).items()}
    if best.verdict != "fail" or args.write_failed:
        files[out / CALIBRATED_MODEL] = model_to_yaml(best.calibrated_model, units=args.out_units,
                                                       calibration=calibration_record(best))
    if report:   # rendered before anything is written: a failure there leaves nothing behind
        files[out / "report.html"] = report.render_report(best)
    return files


def run(args) -> int:
    _check_arguments(args)
    out = Path(args.out)
    report = common.report_module() if args.report else None
    common.refuse_existing(_outputs(out), args.force)
    if args.record:     # a store that cannot take the record fails the command before the work
        record.check_store(args, args.record)
    model, data, validation, contacts = _inputs(args)
    if contacts is None:
        logging.getLogger("robocal").info("read %s: %d poses to fit, %d held out", args.csv, data.n_poses,
                                          0 if validation is None else validation.n_poses)
    options = _calibrate_options(args, validation, contacts)
    best, results = _identified(args, model, data, options)
    for r in results.values():
        common.require_finite("the calibration", _headline(r))
    _diagnosis(args, best)
    files = _output_files(args, out, results, best, report)
    if args.record:     # the files and the record: both or neither
        record.record_result(args, best, args.record, str(out / "result.json"), at=args.at, files=files)
    else:
        common.write_outputs(files, force=args.force)
        print(f"wrote {', '.join(str(p) for p in files)}")
    _remove_stale(out, files)
    if best.verdict == "fail":
        print(f"not written: {out / 'calibrated.yaml'} (the calibration failed its checks; --write-failed writes it "
              "anyway, marked as failed)" if not args.write_failed else
              f"{out / 'calibrated.yaml'} carries the verdict FAIL")
        return FAILED
    return 0
