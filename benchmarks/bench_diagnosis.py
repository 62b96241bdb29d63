"""Time the diagnosis of a bad fit against the calibration it explains, at 1,000 to 100,000 poses.

Run: python benchmarks/bench_diagnosis.py [--poses 1000 10000 100000] [--repeat 3]

A 6R arm (tests/robots.py) measured at random poses with tracker noise, its tracker frame mirrored
(every hypothesis then runs its refit) and, as it is, clean. ``calibrate`` on the same data is the
baseline. Times are the best of REPEAT runs, wall clock and process CPU (the machine may be shared).
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
import warnings
from dataclasses import replace

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests"))

from robots import arm6r

import robocal as rc


def _best(f, repeat: int):
    wall, cpu = [], []
    for _ in range(repeat):
        w, c = time.perf_counter(), time.process_time()
        out = f()
        wall.append(time.perf_counter() - w)
        cpu.append(time.process_time() - c)
    return min(wall), min(cpu), out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--poses", type=int, nargs="+", default=[1000, 10000, 100000])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    print(f"python {platform.python_version()}, robocal {rc.__version__}, {os.cpu_count()} cpu(s)")
    print(f"{'poses':>7} {'data':<9} {'calibrate wall/cpu (s)':>24} {'diagnose wall/cpu (s)':>23}  first finding")
    m = arm6r()
    for n in args.poses:
        _, data = rc.simulate(m, n, seed=1, noise=2e-5)
        mirrored = replace(data, positions=data.positions * [1.0, -1.0, 1.0])
        for label, d in (("clean", data), ("mirrored", mirrored)):
            cw, cc, result = _best(lambda d=d: rc.calibrate(m, d), args.repeat)
            dw, dc, diagnosis = _best(lambda d=d, result=result: rc.diagnose(m, d, result), args.repeat)
            first = diagnosis.cause.hypothesis if diagnosis.cause else "none"
            print(f"{n:>7} {label:<9} {cw:>11.3f} / {cc:<10.3f} {dw:>10.3f} / {dc:<10.3f}  {first}")


if __name__ == "__main__":
    main()
