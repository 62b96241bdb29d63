"""What the diagnosis costs against the calibration it screens, in the same run (docs/diagnosis.md).

Run: python benchmarks/bench_diagnosis.py [--poses 1000 10000] [--repeat 5] [--no-tree] [--no-real]

``robocal.calibrate`` diagnoses every calibration; ``robocal.diagnose`` is that diagnosis alone, on the
same result. The calibration's own cost is the first less the second, and the ratio is the
diagnosis' over it. Campaigns: a 6R arm (tests/robots.py) at random poses with a tracker's noise
(POSES each), the published UR5 grid (1,000 poses), an elastic humanoid-like tree of 19 joints
calibrated with compliance (500 poses; over 100 parameters), clean as measured; and, for what a
mistake costs, the 6R arm at the first size with its tracker frame mirrored (every screen then
refits). Times are the best of REPEAT runs: process CPU (the machine may be shared; the BLAS on one
thread) and wall clock.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
import warnings
from dataclasses import replace
from functools import partial

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests"))

import real_campaigns as real  # noqa: E402
from robots import arm6r, humanoid  # noqa: E402

import robocal as rc  # noqa: E402
from robocal.sim import RobotImperfections, measure_campaign  # noqa: E402


def _best(f, repeat: int):
    wall, cpu, out = [], [], None
    for _ in range(repeat):
        w, c = time.perf_counter(), time.process_time()
        out = f()
        wall.append(time.perf_counter() - w)
        cpu.append(time.process_time() - c)
    return min(wall), min(cpu), out


def _cases(args):
    m = arm6r()
    for n in args.poses:
        _, data = rc.simulate(m, n, seed=1, noise=2e-5)
        yield f"6R, {n:,} poses", m, data, {}
    if args.real:
        ur5 = real.nominal("UR5")
        yield "UR5 grid, 1,000 poses", ur5, real.campaign("UR5", "grid", ur5), {}
    if args.tree:
        tree = humanoid()
        true = rc.perturb_model(tree, rc.identifiability(tree).identified, rng=1)
        q = rc.random_configurations(tree, 500, rng=2)
        robot = RobotImperfections(elasticity=4e-4, load_scale=1e9, repeatability_sigma=1e-4, instrument_noise=2e-4)
        data = measure_campaign(true, q, robot, rng=3, robot_seed=0)
        yield "humanoid tree, 500 poses", tree, data, {"parameters": ("geometric", "compliance"), "noise": "camera"}
    _, data = rc.simulate(m, args.poses[0], seed=1, noise=2e-5)
    yield f"6R, {args.poses[0]:,} poses, mirrored", m, replace(data, positions=data.positions * [1.0, -1.0, 1.0]), {}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--poses", type=int, nargs="+", default=[1000, 10000])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--no-tree", dest="tree", action="store_false")
    ap.add_argument("--no-real", dest="real", action="store_false")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    print(f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, python {platform.python_version()}, "
          f"robocal {rc.__version__}, {os.cpu_count()} cpu(s), load {os.getloadavg()[0]:.1f}")
    print(f"{'campaign':<34}{'params':>7}{'calibrate CPU (s)':>19}{'diagnosis CPU (s)':>19}{'ratio':>7}"
          f"{'wall ratio':>12}  first cause")
    for name, model, data, kw in _cases(args):
        cw, cc, result = _best(partial(rc.calibrate, model, data, **kw), args.repeat)
        dw, dc, diagnosis = _best(partial(rc.diagnose, model, data, result, noise=kw.get("noise")), args.repeat)
        own, own_wall = max(cc - dc, 1e-9), max(cw - dw, 1e-9)
        first = diagnosis.cause.hypothesis if diagnosis.cause else "none"
        print(f"{name:<34}{len(result.parameters):>7}{own:>19.4f}{dc:>19.4f}{dc / own:>7.2f}{dw / own_wall:>12.2f}  "
              f"{first}", flush=True)


if __name__ == "__main__":
    main()
