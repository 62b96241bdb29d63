"""``robocal identifiability``: which parameters can be identified, and what absorbs the others."""

from __future__ import annotations

from .._base.errors import DegenerateDataError
from . import common

EXAMPLE = """examples:
  robocal identifiability examples/th8/model.yaml --parameters geometric,compliance
  robocal identifiability examples/th8/model.yaml examples/th8/measurements.csv"""

def register(sub) -> None:
    p = common.command(sub, "identifiability",
                       summary="which parameters can be identified, and what absorbs the others",
                       description="Identifiability of the parameters at the poses of CSV that calibrate fits "
                                   "(without the rows its 'set' column marks validation), or at --poses random "
                                   "poses within the joint limits.",
                       example=EXAMPLE,
                       inputs=[("model", "MODEL", "model file (YAML)"),
                               ("csv", "CSV", "measurement file (its poses); default random poses", "?")])
    common.parameter_options(p)
    common.mass_options(p)
    p.add_argument("--poses", type=common.poses, default=200, metavar="N",
                   help="random poses without CSV (default 200)")
    p.add_argument("--seed", type=common.seed, default=0, help="seed of the random poses (default 0)")
    common.csv_options(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from .._files.measurements import split_sets
    from .._files.model import read_model

    model = common.masses_as_asked(args, read_model(args.model))
    # the poses calibrate would fit: rows a `set` column holds out are not part of the identification
    data, held = split_sets(common.read_data(args, model, args.csv)) if args.csv else (None, None)
    # imported once the inputs are read: refusing them needs none of the analysis (a second of imports)
    from .._identification.identifiability import identifiability
    from .._presentation.text import identifiability_summary

    res = identifiability(model, data, parameters=args.parameters or ("geometric",), known=args.known, tol=args.tol,
                          n_random=args.poses, rng=args.seed)
    if not res.identified:
        raise DegenerateDataError(f"no parameter is identifiable at tolerance {args.tol:g}; the condition number is "
                                  "undefined")
    where = f"{args.poses} random poses (seed {args.seed}) within the joint limits" if data is None else \
        f"the {data.n_poses} poses of {args.csv}" if held is None else \
        f"the {data.n_poses} poses of {args.csv} that calibrate fits (column 'set'; the {held.n_poses} validation " \
        "rows left out)"
    print(identifiability_summary(model, res, where))
    from .._model.parameters import matched_by_pattern

    orientation = data is not None and data.has_orientation
    for pattern, names in matched_by_pattern(model, args.parameters or (), orientation=orientation):
        print(f"note: parameters {pattern!r} matched: {', '.join(names)}")
    return 0
