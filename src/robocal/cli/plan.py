"""``robocal plan``: which poses to measure, and what that campaign will give, before the robot is booked."""

from __future__ import annotations

import sys

from .._base.errors import DegenerateDataError, InputError
from .._base.options import INSTRUMENT_NOISE, POSE_CRITERIA
from . import common

EXAMPLE = """examples:
  robocal plan examples/th8/model.yaml --poses 50 --out poses.csv
  robocal plan examples/th8/model.yaml --poses 30 --candidates examples/th8/measurements.csv --out poses-30.csv

The poses are written in the measurement-file layout with empty marker columns: measure them,
fill the columns in, and run 'robocal calibrate'. The predictions assume the instrument's noise
(--noise-mm or --instrument) and a robot that the model describes up to its parameters."""


def register(sub) -> None:
    p = common.command(sub, "plan", summary="choose the poses to measure and predict what they will give",
                       description="Choose N poses (D- or I-optimal) from random configurations within the joint "
                                   "limits or from a candidate file, write them ready to be measured, and print the "
                                   "identifiable parameters, their predicted standard deviations and the predicted "
                                   "position error after calibration.",
                       example=EXAMPLE, inputs=[("model", "MODEL", "nominal model file (YAML)")])
    p.add_argument("--poses", type=common.poses, required=True, metavar="N", help="number of poses to choose")
    p.add_argument("--out", required=True, metavar="CSV", help="poses to write (measurement-file layout)")
    p.add_argument("--candidates", metavar="CSV", help="choose among these joint readings (e.g. collision-free "
                                                       "poses; measurement-file layout, marker columns optional)")
    p.add_argument("--n-candidates", type=common.poses, default=10000, metavar="M",
                   help="random candidates without --candidates (default 10000)")
    p.add_argument("--criterion", choices=POSE_CRITERIA, default="I",
                   help="I: lowest average prediction variance (held-out error), D: largest det (default I)")
    common.parameter_options(p)
    p.add_argument("--instrument", choices=tuple(INSTRUMENT_NOISE), default="tracker",
                   help="instrument class whose noise the predictions assume (default tracker)")
    p.add_argument("--noise-mm", type=common.noise_mm, metavar="X", help="measurement noise, mm per axis "
                                                                       "(overrides the instrument's)")
    p.add_argument("--seed", type=common.seed, default=0, help="random seed (default 0)")
    p.add_argument("--out-units", type=common.units, default="mm-deg",
                   help="units of the written file (default mm-deg)")
    p.add_argument("--force", action="store_true", help="overwrite an existing file")
    common.csv_options(p)
    p.set_defaults(func=run)


def run(args) -> int:
    import numpy as np

    from .._files.checked import within_limits
    from .._files.measurements import measurements_to_csv
    from .._files.model import read_model
    from .._model.measurements import Measurements, Noise
    from .._presentation.text import plan_summary
    from .._simulation.poses import predict_campaign, select_poses

    common.refuse_existing([args.out], args.force)
    model = read_model(args.model)
    given = common.read_data(args, model, args.candidates, targets=True) if args.candidates else None
    candidates, names = (None, ()) if given is None else (given.q, given.labels)
    if candidates is not None:  # a plan never asks for a pose beyond the joint limits
        inside = within_limits(model, candidates)
        if not inside.all():
            print(f"robocal: warning: {args.candidates}: {int((~inside).sum())} of {len(inside)} candidate poses "
                  "are beyond the joint limits and left out", file=sys.stderr)
        # a pose given twice is one candidate: choosing it twice measures nothing new
        _, first = np.unique(candidates[inside], axis=0, return_index=True)
        keep = np.flatnonzero(inside)[np.sort(first)]
        if len(keep) < inside.sum():
            print(f"robocal: warning: {args.candidates}: {int(inside.sum()) - len(keep)} candidate poses repeat "
                  "others and are left out", file=sys.stderr)
        candidates, names = candidates[keep], tuple(names[i] for i in keep) if len(names) == len(inside) else ()
    n_cand = len(candidates) if candidates is not None else args.n_candidates
    if args.poses > n_cand:
        distinct = " distinct" if candidates is not None else ""
        raise InputError(f"cannot choose {args.poses} poses from {n_cand}{distinct} candidates", where="--poses")
    parameters = args.parameters or ("geometric",)
    sel = select_poses(model, args.poses, candidates=candidates, n_candidates=args.n_candidates,
                       parameters=parameters, known=args.known, criterion=args.criterion, rng=args.seed)
    noise = Noise.of(args.instrument, position=None if args.noise_mm is None else args.noise_mm / common.MM)
    pred = predict_campaign(model, sel.q, parameters=parameters, known=args.known, noise=noise.position,
                            tol=args.tol, rng=args.seed)
    if not within_limits(model, sel.q).all():
        raise DegenerateDataError("the chosen poses are beyond the joint limits; nothing written")
    n, m = len(sel.q), len(model.marker_names)
    # chosen among given poses, each keeps its name there: the plan says which of them to measure
    labels = tuple(f"P{i + 1:02d}" for i in range(n)) if candidates is None or len(names) != len(candidates) else \
        tuple(names[i] for i in sel.indices)
    poses = Measurements(q=sel.q, positions=np.full((n, m, 3), np.nan), marker_names=model.marker_names,
                         joint_names=model.joint_names, labels=labels)
    common.write_outputs({args.out: measurements_to_csv(poses, model=model, units=args.out_units)}, force=args.force)
    print(plan_summary(model, sel, pred, n_candidates=n_cand,
                       source=f"poses of {args.candidates}" if args.candidates else "random configurations"))
    print(f"wrote {args.out}")
    return 0
