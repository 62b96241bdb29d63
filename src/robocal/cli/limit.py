"""``robocal limit``: the limit of absolute accuracy of a robot model (docs/method.md section 5).

Parses units at the edge (deg, rad, mm, m), calls the library in SI, writes JSON atomically.
"""

from __future__ import annotations

import math
import re
import sys

from .._base.errors import InputError
from .._base.options import LIMIT_CHUNK as DEFAULT_CHUNK
from .._base.options import LIMIT_MARKER_MODES as MARKER_MODES
from .._base.options import MAX_CHUNK, MAX_SAMPLES
from .._base.units import LENGTH_UNITS, UNITS, unit_kind
from . import common

PROG = "robocal limit"
_ENTRY = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([a-z]+)\s*$")
# the coarsest step a joint encoder reads, SI: 360 counts a turn, or a millimetre a count, is coarser
# than any robot's; beyond it a value is a slip of unit (0.1m for 0.1mm)
COARSEST = {"angle": (math.radians(1.0), "1 degree"), "length": (1e-3, "1 mm")}


def _quantum(kind: str, per_si: float):
    """The argparse type of the round-off of a controller's stored lengths or angles: no coarser than
    the step its encoders count in (a 5 mm quantum moves the tool by centimetres); beyond it a value
    is a slip of unit (10 typed for 10 um)."""
    coarsest, said = COARSEST[kind]
    return common.number_in(lambda v: 0.0 <= v <= coarsest * per_si,
                            f"a number from 0 to {said} (no controller stores its {kind}s coarser; is the unit right?)")


length_quantum_mm = _quantum("length", 1e3)
angle_quantum_deg = _quantum("angle", 180.0 / math.pi)


EXAMPLE = """example:
  robocal limit examples/th8/model.yaml --repeatability-csv examples/th8/repeatability.csv \\
      --encoder-resolution 0.01deg,0.1mm,0.12mm,0.005deg,0.002deg,0.002deg \\
      --length-quantum-mm 0.1 --angle-quantum-deg 0.001 --out limit.json

'robocal calibrate --limit-mm limit.json' then judges a calibration against the figure."""

def register(sub) -> None:
    """Add the ``limit`` subcommand to an argparse subparsers object (``run`` is set as ``func``)."""
    p = common.command(sub, "limit", summary="limit of absolute accuracy: repeatability + geometric-control precision",
                       description="Limit of absolute accuracy = ISO 9283 repeatability RP + the mean tool deviation "
                                   "caused by encoder resolution and parameter round-off (Monte Carlo).",
                       example=EXAMPLE, inputs=[("model", "MODEL", "robot model file")])
    rep = p.add_mutually_exclusive_group(required=True)
    rep.add_argument("--repeatability-csv", metavar="FILE",
                     help="repeated measurements, columns pose, cycle, x_mm, y_mm, z_mm (or x_m...)")
    rep.add_argument("--repeatability-mm", metavar="X", type=common.length_mm, help="pose repeatability RP in mm")
    p.add_argument("--csv-units", choices=tuple(LENGTH_UNITS),
                   help="units of plain x, y, z columns (not needed when they are named x_mm... or x_m...)")
    p.add_argument("--encoder-resolution", required=True, metavar="LIST",
                   help='one per joint with its unit, e.g. "0.01deg,0.01deg,0.1mm" (deg, rad, mm, m); '
                        'each above 0 and up to 1 degree or 1 mm (no robot\'s encoder reads coarser)')
    p.add_argument("--length-quantum-mm", required=True, type=length_quantum_mm, metavar="X",
                   help=f"round-off quantum of stored lengths, mm, from 0 (exact) to {COARSEST['length'][1]}")
    p.add_argument("--angle-quantum-deg", required=True, type=angle_quantum_deg, metavar="X",
                   help=f"round-off quantum of stored angles, degrees, from 0 (exact) to {COARSEST['angle'][1]}")
    p.add_argument("--samples", type=common.integer(1, MAX_SAMPLES), default=100_000, metavar="N",
                   help="Monte Carlo samples (default 100000)")
    p.add_argument("--seed", type=common.seed, default=0, metavar="S", help="random seed (default 0)")
    p.add_argument("--chunk-size", type=common.integer(1, MAX_CHUNK), default=DEFAULT_CHUNK, metavar="N",
                   help=f"configurations per vectorised chunk (default {DEFAULT_CHUNK})")
    p.add_argument("--markers", choices=MARKER_MODES, default="first",
                   help="deviation of the first marker (default), or the worst over all markers")
    p.add_argument("--out", required=True, metavar="FILE.json", help="where to write the result")
    p.add_argument("--force", action="store_true", help="overwrite --out if it exists")
    p.set_defaults(func=run)


def parse_resolution(text: str, is_angle) -> list[float]:
    """``"0.01deg,0.1mm"`` -> SI values, one per joint reading; the unit must suit the joint."""
    entries = [e for e in text.split(",")]
    if len(entries) != len(is_angle):
        raise InputError(f"expected one entry per joint ({len(is_angle)} joints), got {len(entries)}",
                         where="--encoder-resolution")
    out = []
    for j, (entry, angle) in enumerate(zip(entries, is_angle)):
        m = _ENTRY.match(entry)
        kind = unit_kind(m.group(2)) if m else None
        if m is None or kind is None:
            raise InputError(f"joint {j + 1}: expected a number with a unit (deg, rad, mm, m), got {entry.strip()!r}",
                             where="--encoder-resolution")
        scale, unit_is_angle = UNITS[kind][m.group(2)], kind == "angle"
        if unit_is_angle != bool(angle):
            kind = "revolute (deg or rad)" if angle else "prismatic (mm or m)"
            raise InputError(f"joint {j + 1} is {kind}, got {entry.strip()!r}", where="--encoder-resolution")
        value = float(m.group(1)) * scale
        coarsest, said = COARSEST[kind]
        if not 0.0 < value <= coarsest:
            raise InputError(f"joint {j + 1}: {entry.strip()!r} is not a resolution: expected above 0 and up to "
                             f"{said} (no robot's encoder reads coarser; is the unit right?)",
                             where="--encoder-resolution")
        out.append(value)
    return out


def _progress_bar():
    """A progress callback for a terminal, or None (stderr is not a terminal)."""
    if not sys.stderr.isatty():
        return None

    def show(done: int, total: int) -> None:
        width = 30
        filled = width * done // total
        sys.stderr.write(f"\r{PROG}: [{'#' * filled}{'.' * (width - filled)}] {done}/{total}")
        if done == total:
            sys.stderr.write("\n")
        sys.stderr.flush()
    return show


def run(args) -> int:
    """Run ``robocal limit``; 0 on success, 2 on bad input (one line on stderr, from ``main``)."""
    from .._accuracy.limit import accuracy_limit, check_work, controller_precision, iso9283_repeatability
    from .._files.model import read_model
    from .._files.repeatability import read_repeatability_csv
    from .._files.result import limit_to_dict, to_json

    common.refuse_existing([args.out], args.force)
    model = read_model(args.model)
    resolution = parse_resolution(args.encoder_resolution, [q == "angle" for q in model.reading_quantities])
    check_work(model, args.samples, args.markers, where="--samples")
    if args.repeatability_csv is not None:
        data = read_repeatability_csv(args.repeatability_csv, units=args.csv_units)
        repeatability = iso9283_repeatability(data.pose_ids, data.points)
    else:
        repeatability = args.repeatability_mm * 1e-3
    long_run = args.samples > args.chunk_size
    precision = controller_precision(
        model, encoder_resolution=resolution, length_quantum=args.length_quantum_mm * 1e-3,
        angle_quantum=math.radians(args.angle_quantum_deg), n_samples=args.samples,
        chunk_size=args.chunk_size, rng=args.seed, markers=args.markers,
        progress=_progress_bar() if long_run else None)
    limit = accuracy_limit(repeatability, precision)
    common.require_finite("the limit of absolute accuracy", {"limit": limit.limit, "limit_p95": limit.limit_p95})
    out = limit_to_dict(limit)
    out["run"] = {"model": str(args.model), "seed": args.seed,
                  "repeatability_source": args.repeatability_csv or "--repeatability-mm"}
    common.write_outputs({args.out: to_json(out)}, force=args.force)
    print(f"limit of absolute accuracy {limit.limit * 1e3:.4f} mm = repeatability {limit.repeatability * 1e3:.4f} mm"
          f" + geometric control {limit.precision * 1e3:.4f} mm (mean; 95th percentile "
          f"{limit.precision_p95 * 1e3:.4f} mm) -> {args.out}")
    return 0
