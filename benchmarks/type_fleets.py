"""The type comparison judged on the published grids: fleets of one robot's random subsets.

Run: python benchmarks/type_fleets.py [--robot WAM] [--size 120] [--fleets 12] [--seed 0] [--robots 6]
                                     [--sizes LO,HI]

Each fleet is ``--robots`` random subsets of ``--size`` poses (``--sizes``: of LO to HI - 1 poses,
each drawn) of one published grid (tests/data/real), each calibrated as a robot of one type with
default options and compared with ``rc.compare_type``.
Every robot is the same robot, so any robot named is a false alarm. Three kinds of fleet:

* alike: all six calibrated geometric;
* gear terms: the first calibrated with gear scales as well (the UR5 also with first harmonics);
* changed: all geometric, the last one's measurements moved by what ``--change`` (a parameter and
  an offset in SI units) does at its poses, the robot that should be named.

``--kinds`` runs some of them only (comma-separated: alike, gear, changed).

Printed: per kind, the fleets naming a robot (for "changed": naming the changed one, and naming
another), and the robots named in each fleet.
"""

from __future__ import annotations

import argparse
import os
import sys
import warnings
from dataclasses import replace

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tests"))
from real_campaigns import campaign, nominal  # noqa: E402

import robocal as rc  # noqa: E402


def fleet(robot: str, size: int, seed: int, first=("geometric",), changed=None, robots: int = 6, sizes=None):
    model = nominal(robot)
    grid = campaign(robot, "grid", model)
    rng = np.random.default_rng(seed)
    cals = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for i in range(robots):
            n = size if sizes is None else int(rng.integers(*sizes))
            sub = grid.subset(np.sort(rng.choice(grid.n_poses, n, replace=False)))
            if changed is not None and i == robots - 1:
                moved = rc.forward_kinematics(changed, sub.q).positions - rc.forward_kinematics(model, sub.q).positions
                sub = replace(sub, positions=sub.positions + moved.reshape(sub.positions.shape))
            res = rc.calibrate(model, sub, parameters=first if i == 0 else ("geometric",))
            cals.append(replace(rc.stored_calibration(res, f"R{i}", at="2026-01-01"), id=i + 1))
    return rc.compare_type(robot, cals)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default="WAM", choices=("UR5", "WAM"))
    ap.add_argument("--size", type=int, default=120)
    ap.add_argument("--fleets", type=int, default=12)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--change", nargs=2, default=None, metavar=("NAME", "OFFSET"),
                    help="default: the third frame's d, 5 mm")
    ap.add_argument("--robots", type=int, default=6)
    ap.add_argument("--sizes", default=None, help="LO,HI: each robot's poses drawn from LO to HI - 1")
    ap.add_argument("--kinds", default="alike,gear,changed")
    args = ap.parse_args(argv)
    sizes = None if args.sizes is None else tuple(int(v) for v in args.sizes.split(","))
    last = f"R{args.robots - 1}"
    model = nominal(args.robot)
    terms = ("gear_scale",) if args.robot == "WAM" else ("gear_scale", "gear_cos1", "gear_sin1")
    gear = ("geometric",) + tuple(n for n in rc.parameter_names(model) if n.split(".")[-1] in terms)
    args.change = args.change or (f"{model.frames[2].name}.d", "5e-3")
    p = rc.parameter_vector(model)
    p[rc.parameter_names(model).index(args.change[0])] += float(args.change[1])
    changed = rc.model_from_vector(model, p)
    what = f"{args.size}-pose" if sizes is None else f"{sizes[0]}- to {sizes[1] - 1}-pose"
    print(f"# {args.robot} grid, fleets of {args.robots} {what} subsets, seeds {args.seed} to "
          f"{args.seed + args.fleets - 1}")
    kinds = (("alike", "alike", ("geometric",), None), ("gear", "gear terms", gear, None),
             ("changed", f"changed ({args.change[0]} {args.change[1]})", ("geometric",), changed))
    for key, kind, first, moved in kinds:
        if key not in args.kinds.split(","):
            continue
        named = other = 0
        for k in range(args.fleets):
            t = fleet(args.robot, args.size, args.seed + k, first, moved, args.robots, sizes)
            robots = {o.robot for o in t.outliers}
            named += (last in robots) if moved is not None else bool(robots)
            other += bool(robots - {last}) if moved is not None else 0
            shown = ", ".join(f"{o.robot} {o.name} {o.z:+.1f}" for o in t.outliers[:3]) or "none"
            print(f"  {kind}, seed {args.seed + k}: {shown}")
        tail = f", another robot named in {other}" if moved is not None else ""
        print(f"{kind}: {'the changed robot named' if moved is not None else 'a robot named'} in {named} of "
              f"{args.fleets} fleets{tail}")


if __name__ == "__main__":
    main()
