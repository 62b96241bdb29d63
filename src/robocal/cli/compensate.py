"""``robocal compensate``: joint commands that put the calibrated robot on the nominal controller's targets."""

from __future__ import annotations

import sys
from pathlib import Path

from .._base.errors import InputError
from . import common

EXAMPLE = """examples:
  robocal compensate examples/th8/model.yaml runs/th8/calibrated.yaml examples/th8/targets.csv --out commands.csv
  robocal compensate examples/th8/model.yaml runs/th8/calibrated.yaml examples/th8/program.mod \\
      --out program-compensated.mod

A robot program (ABB RAPID .mod/.prg/.sys, KUKA KRL .src/.dat, URScript .script; or --dialect)
is written back with only its targets' numbers changed; a target out of reach, not converged or
beyond a joint limit is left unchanged and flagged in a comment (docs/formats.md, "Robot programs").

TARGETS.csv has the measurement-file layout: joint columns (the readings the nominal controller
would command) and, optionally, marker columns. A row with a marker position (and orientation) is a
Cartesian target in the measurement frame, its readings the starting guess; a row without one asks
for the pose the nominal model reaches at its readings."""


def register(sub) -> None:
    p = common.command(sub, "compensate", summary="corrected joint commands for the calibrated robot",
                       description="Joint commands that put the calibrated robot where the nominal controller "
                                   "was asked to go, with the residual of each and a flag where a target is out "
                                   "of reach, not converged or beyond a joint limit.",
                       example=EXAMPLE,
                       inputs=[("nominal", "NOMINAL", "the model the controller holds (YAML)"),
                               ("calibrated", "CALIBRATED", "the calibrated model (YAML)"),
                               ("targets", "TARGETS", "targets: a CSV of joint readings or positions/poses in W, "
                                                      "or a robot program")])
    p.add_argument("--out", required=True, metavar="FILE",
                   help="corrected commands (.csv) or the compensated program (its dialect's extension); a name of "
                        "another kind is refused")
    g = p.add_argument_group("robot program")
    g.add_argument("--dialect", choices=("rapid", "krl", "urscript"),
                   help="the program's language (default: from its extension)")
    g.add_argument("--tool", metavar="NAME", help="a tool the program declares (tooldata, FRAME or TOOL_DATA[n], "
                                                  "a pose variable), on the frame of the model's tool point")
    g.add_argument("--wobj", metavar="NAME", help="a work object the program declares (wobjdata, FRAME or "
                                                  "BASE_DATA[n], a pose variable) that its Cartesian targets are in")
    g.add_argument("--include", metavar="FILE", action="append", default=[],
                   help="another file of the program, in its dialect, whose tools and work objects it uses (a KRL "
                        "$config.dat, a RAPID module of tooldata); repeatable. A KRL .src's .dat and a .dat's "
                        ".src (same name, same folder) are read with it without asking")
    p.add_argument("--marker", help="the marker to place (default the file's first marker, else the model's)")
    p.add_argument("--position-only", action="store_true",
                   help="match the marker's position only, even with six joints or more")
    p.add_argument("--tol-mm", type=common.noise_mm, default=0.001,
                   help="position residual above which a target counts as not reached (default 0.001)")
    p.add_argument("--tol-deg", type=common.noise_deg, default=1e-4,
                   help="orientation residual above which a target counts as not reached (default 1e-4)")
    p.add_argument("--out-units", type=common.units, default="mm-deg",
                   help="units of the written file (default mm-deg)")
    p.add_argument("--force", action="store_true", help="overwrite an existing file")
    common.csv_options(p)
    p.set_defaults(func=run)


def _marker(args, model, data) -> tuple[int, int | None]:
    """The marker's index in the model and in the targets file (None when the file has no columns of it)."""
    name = args.marker or (data.marker_names[0] if data.marker_names else model.marker_names[0])
    if name not in model.marker_names:
        raise InputError(f"no marker {name!r}; the model has {', '.join(model.marker_names)}", where="--marker")
    return model.marker_names.index(name), (data.marker_names.index(name) if name in data.marker_names else None)


def _is_program(args) -> bool:
    from .._files.programs import EXTENSIONS

    return args.dialect is not None or Path(args.targets).suffix.lower() in EXTENSIONS


def _refuse_misnamed(args) -> None:
    """A program compensated is written as that program, a CSV of targets as a CSV of commands: an
    ``--out`` named as another kind of file (another dialect's program too) is refused."""
    from .._files.programs import dialect_of

    if not _is_program(args):
        common.refuse_misnamed(args.out, "CSV", "a CSV of targets compensated",
                               " (a program's targets are compensated from the program itself)")
        return
    if Path(args.out).suffix.lower() != Path(args.targets).suffix.lower():     # the program's own name stands
        dialect = dialect_of(args.targets, args.dialect)
        common.refuse_misnamed(args.out, f"{dialect} program", f"a {dialect} program compensated")


def _read_targets(args, nominal):
    """The CSV of targets; a file refused as one that reads as a robot program under a name no
    dialect claims (``program.txt``) is refused saying which dialect to give."""
    from .._files.programs import dialect_in

    try:
        return common.read_data(args, nominal, args.targets, targets=True)
    except InputError as err:
        dialect = dialect_in(args.targets)
        if dialect is None:
            raise
        raise InputError(f"reads as a {dialect} program, not a CSV of targets, but its extension is no program's: "
                         f"give --dialect {dialect}", source=str(args.targets)) from err


def _run_program(args, nominal, calibrated, ranges) -> int:
    """Compensate a robot program; a line per target (mm, deg), the flagged ones also on stderr."""
    from .._files.programs import read_program
    from .._files.programs.compensation import compensate_program

    program = read_program(args.targets, dialect=args.dialect)
    name = args.marker or nominal.marker_names[0]
    if name not in nominal.marker_names:
        raise InputError(f"no marker {name!r}; the model has {', '.join(nominal.marker_names)}", where="--marker")
    m = nominal.marker_names.index(name)
    companions = [read_program(path, dialect=program.dialect) for path in _companions(args, program)]
    if not any(p.targets for p in [program] + companions):     # an empty file, or a program of another kind
        raise InputError(f"no target in this {program.dialect} program (docs/formats.md says which declarations "
                         "and motion instructions are read): nothing to compensate", source=str(args.targets))
    result = compensate_program(program, nominal, calibrated, marker=m, tool=args.tool, wobj=args.wobj,
                                companions=companions, tol=args.tol_mm / common.MM, tol_rot=args.tol_deg / common.DEG,
                                ranges=ranges)
    common.write_outputs({args.out: result.text}, force=args.force)
    if companions:
        print(f"read with {', '.join(c.source for c in companions)}")
    for r in result.targets:
        print(_summary(r))
    for note in result.notes:
        print(f"note: {note}")
    for r in result.flagged:
        print(f"robocal: warning: {args.targets}: {_named(r)}: {r.status}; left unchanged", file=sys.stderr)
    beyond = _beyond(args, calibrated, ranges, {_named(r): r.outside for r in result.targets if r.outside})
    done = sum(r.status == "ok" for r in result.targets)
    through = sum(r.status.startswith("not compensated") for r in result.targets)
    print(f"compensated {done} of {len(result.targets)} targets of {args.targets} ({program.dialect}) for "
          f"{calibrated.name}: {len(result.flagged)} flagged"
          f"{f', {through} reached only through expressions' if through else ''}"
          f"{f', {beyond} beyond the calibrated ranges' if beyond else ''}; wrote {args.out}")
    return 0


def _named(r) -> str:
    """A program's target as the messages name it: its name, and its line where the name is not that."""
    return r.name if r.name == f"line {r.line}" else f"{r.name} (line {r.line})"


def _companions(args, program) -> list[str]:
    """The files read with the program: ``--include``, and a KRL file's other half beside it."""
    paths = list(args.include)
    if program.dialect == "krl":
        path = Path(args.targets)
        other = {".src": ".dat", ".dat": ".src"}.get(path.suffix.lower())
        sibling = next((p for p in path.parent.glob(f"{path.stem}.*") if p.suffix.lower() == other), None) \
            if other else None
        if sibling is not None and str(sibling) not in paths:
            paths.append(str(sibling))
    return paths


def _summary(r) -> str:
    """A target's line: its frames and how far it moved, or why it was not compensated."""
    frames = f"; tool {r.tool}, work object {r.wobj}" if r.tool else ""
    through = f"; also through {r.through}" if r.through and r.status == "ok" else ""
    where = "" if r.name == f"line {r.line}" else f"line {r.line}, "     # an unnamed target is named by its line
    head = f"{r.name} ({where}{r.kind}{frames})"
    if r.status != "ok":
        return f"{head}: {r.status}"
    linear = f", {r.length_change * common.MM:.4f} mm" if r.length_change else ""
    beyond = f"; beyond the calibrated range of {', '.join(r.outside)}" if r.outside else ""
    return (f"{head}: moved {r.moved * common.MM:.4f} mm, turned {r.turned * common.DEG:.5f} deg; joints by up to "
            f"{r.angle_change * common.DEG:.5f} deg{linear}{through}{beyond}")


def _ranges(args, record):
    """The calibrated model's ranges of readings (its calibration record's ``joint_ranges``), None
    where it has none; a note where a calibration wrote it without them."""
    ranges = None if record is None else record.get("joint_ranges")
    if record is not None and ranges is None:
        print(f"note: {args.calibrated}: its calibration record holds no joint ranges (a file written before "
              "they were recorded, or a calibration from contacts alone): the commands are not checked against "
              "the readings it was calibrated on")
    return ranges


def _beyond(args, model, ranges, outside) -> int:
    """Warn of the targets (``outside``: label -> joints) whose commands lie beyond the calibrated
    ranges, with those ranges once; their number."""
    for label, joints in outside.items():
        print(f"robocal: warning: {args.targets}: {label}: beyond the readings the calibration measured on "
              f"{', '.join(joints)}: the model is extrapolated there", file=sys.stderr)
    named = sorted({j for joints in outside.values() for j in joints}, key=model.joint_names.index)
    if named:
        print("note: the calibration measured " + ", ".join(
            f"{j} over {_reading(model, j, ranges, 0)} to {_reading(model, j, ranges, 1)}" for j in named))
    return len(outside)


def _reading(model, joint: str, ranges, k: int) -> str:
    j = model.joint_names.index(joint)
    length = model.reading_quantities[j] == "length"
    return f"{ranges[j, k] * (common.MM if length else common.DEG):.6g} {'mm' if length else 'deg'}"


def run(args) -> int:
    from .._accuracy.compensation import compensate
    from .._files.checked import within_limits
    from .._files.commands import BEYOND_LIMITS, REACHED, command_status, commands_to_csv
    from .._files.model import read_model, read_model_and_record

    _refuse_misnamed(args)
    common.refuse_existing([args.out], args.force)
    nominal = read_model(args.nominal)
    calibrated, record = read_model_and_record(args.calibrated)
    common.warn_if_failed(args.calibrated, record, "the commands are made with")
    if calibrated.joint_names != nominal.joint_names:
        raise InputError(f"joints {', '.join(calibrated.joint_names)} differ from the nominal model's "
                         f"({', '.join(nominal.joint_names)})", source=args.calibrated)
    ranges = _ranges(args, record)
    if _is_program(args):
        return _run_program(args, nominal, calibrated, ranges)
    data = _read_targets(args, nominal)
    m, col = _marker(args, nominal, data)
    comp = compensate(calibrated, data.q, nominal=nominal, marker=m,
                      positions=None if col is None else data.positions[:, col],
                      rotations=None if col is None or data.rotations is None else data.rotations[:, col],
                      orientation=False if args.position_only else None, approach=data.extra.get("approach"),
                      ranges=ranges)
    status = command_status(comp, args.tol_mm / common.MM, args.tol_deg / common.DEG)
    # the controller holds the nominal model: a command beyond its limits is flagged too
    status = [BEYOND_LIMITS if s == REACHED and not ok else s
              for s, ok in zip(status, within_limits(nominal, comp.q))]
    common.write_outputs({args.out: commands_to_csv(calibrated, data.labels, comp, status, units=args.out_units,
                                                    ranges_known=ranges is not None)}, force=args.force)
    flagged = [(lab, s) for lab, s in zip(data.labels, status) if s != "ok"]
    for lab, s in flagged:
        print(f"robocal: warning: {args.targets}: {lab}: {s}", file=sys.stderr)
    outside = {lab: [j for j, o in zip(calibrated.joint_names, row) if o]
               for lab, row in zip(data.labels, comp.outside) if row.any()}
    beyond = _beyond(args, calibrated, ranges, outside)
    kind = "position" if not comp.oriented.any() else "pose"
    print(f"compensated {data.n_poses} targets for {calibrated.name} ({kind} "
          f"of marker {nominal.marker_names[m]}): {data.n_poses - len(flagged)} reached, {len(flagged)} flagged"
          f"{f', {beyond} beyond the calibrated ranges' if beyond else ''}; "
          f"worst residual {comp.residual.max() * common.MM:.3g} mm: wrote {args.out}")
    return 0
