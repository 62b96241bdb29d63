"""``robocal compensate``: joint commands that put the calibrated robot on the nominal controller's targets."""

from __future__ import annotations

import sys

from .._errors import InputError
from . import common

EXAMPLE = """example:
  robocal compensate examples/th8/model.yaml runs/th8/calibrated.yaml examples/th8/targets.csv --out commands.csv

TARGETS.csv has the measurement-file layout: joint columns (the readings the nominal controller
would command) and, optionally, marker columns. A row with a marker position (and orientation) is a
Cartesian target in the measurement frame, its readings the starting guess; a row without one asks
for the pose the nominal model reaches at its readings."""


def register(sub) -> None:
    p = common.command(sub, "compensate", summary="corrected joint commands for the calibrated robot",
                       description="Joint commands that put the calibrated robot where the nominal controller "
                                   "was asked to go, with the residual of each and a flag where a target is out "
                                   "of reach or beyond a joint limit.",
                       example=EXAMPLE,
                       inputs=[("nominal", "NOMINAL", "the model the controller holds (YAML)"),
                               ("calibrated", "CALIBRATED", "the calibrated model (YAML)"),
                               ("targets", "TARGETS.csv", "targets: joint readings, or positions/poses in W")])
    p.add_argument("--out", required=True, metavar="CSV", help="corrected commands to write")
    p.add_argument("--marker", help="the marker to place (default the file's first marker, else the model's)")
    p.add_argument("--position-only", action="store_true",
                   help="match the marker's position only, even with six joints or more")
    p.add_argument("--tol-mm", type=common.noise_mm, default=0.001,
                   help="position residual above which a target counts as out of reach (default 0.001)")
    p.add_argument("--tol-deg", type=common.noise_deg, default=1e-4,
                   help="orientation residual above which a target counts as out of reach (default 1e-4)")
    p.add_argument("--out-units", type=common.units, default="mm-deg", help="units of the written file (default mm-deg)")
    p.add_argument("--force", action="store_true", help="overwrite an existing file")
    common.csv_options(p)
    p.set_defaults(func=run)


def _marker(args, model, data) -> tuple[int, int | None]:
    """The marker's index in the model and in the targets file (None when the file has no columns of it)."""
    name = args.marker or (data.marker_names[0] if data.marker_names else model.marker_names[0])
    if name not in model.marker_names:
        raise InputError(f"no marker {name!r}; the model has {', '.join(model.marker_names)}", where="--marker")
    return model.marker_names.index(name), (data.marker_names.index(name) if name in data.marker_names else None)


def run(args) -> int:
    from .._compensation import compensate
    from .._files.checked import within_limits
    from .._files.commands import BEYOND_LIMITS, REACHED, command_status, commands_to_csv
    from .._files.model import read_model

    common.refuse_existing([args.out], args.force)
    nominal = read_model(args.nominal)
    calibrated = read_model(args.calibrated)
    if calibrated.joint_names != nominal.joint_names:
        raise InputError(f"joints {', '.join(calibrated.joint_names)} differ from the nominal model's "
                         f"({', '.join(nominal.joint_names)})", source=args.calibrated)
    data = common.read_data(args, nominal, args.targets, targets=True)
    m, col = _marker(args, nominal, data)
    comp = compensate(calibrated, data.q, nominal=nominal, marker=m,
                      positions=None if col is None else data.positions[:, col],
                      rotations=None if col is None or data.rotations is None else data.rotations[:, col],
                      orientation=False if args.position_only else None)
    status = command_status(comp, args.tol_mm / common.MM, args.tol_deg / common.DEG)
    # the controller holds the nominal model: a command beyond its limits is flagged too
    status = [BEYOND_LIMITS if s == REACHED and not ok else s
              for s, ok in zip(status, within_limits(nominal, comp.q))]
    common.write_outputs({args.out: commands_to_csv(calibrated, data.labels, comp, status, units=args.out_units)},
                         force=args.force)
    flagged = [(lab, s) for lab, s in zip(data.labels, status) if s != "ok"]
    for lab, s in flagged:
        print(f"robocal: warning: {args.targets}: {lab}: {s}", file=sys.stderr)
    print(f"compensated {data.n_poses} targets for {calibrated.name} ({'position' if not comp.oriented.any() else 'pose'} "
          f"of marker {nominal.marker_names[m]}): {data.n_poses - len(flagged)} reached, {len(flagged)} flagged; "
          f"worst residual {comp.residual.max() * common.MM:.3g} mm: wrote {args.out}")
    return 0
