"""What the transmission family costs: calibrate() and one Jacobian, with and without it, in one run.

Run: python benchmarks/bench_transmission.py [--repeat 5]

On the 6-joint arm of ``bench_identify.py`` with geometric errors and first harmonics of 0.02 to
0.03 deg on joints 2 and 3 (``rc.simulate`` then the harmonics set on the true model), at 1,000 and
10,000 poses, in this process: ``calibrate(parameters=("geometric",))`` beside
``calibrate(parameters=("geometric", "transmission"))`` (every joint's scale and two harmonics:
30 more candidates), and ``evaluate(..., jacobian=True)`` of the geometric columns beside the
geometric and transmission columns. Best wall-clock and CPU time of ``--repeat`` (a fifth of it
at 10,000 poses) after three untimed calls; the held-out mean error of each calibration on 1,000 other
poses is printed beside it.
"""

from __future__ import annotations

import os
import platform
import time
from dataclasses import replace

import numpy as np
from bench_engine import best
from bench_identify import arm6r, options

import robocal as rc
from robocal.kinematics import candidate_parameters, evaluate, parameter_layout

DEG = np.pi / 180
HARMONICS = {1: dict(gear_cos1=0.025 * DEG, gear_sin1=-0.02 * DEG),
             2: dict(gear_cos1=-0.03 * DEG, gear_sin1=0.022 * DEG)}


def main(argv=None):
    args = options(__doc__, argv, repeat=5)
    print(f"# the transmission family's cost, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, "
          f"{platform.machine()}, {os.cpu_count()} cores, numpy {np.__version__}, best of {args.repeat}; load average "
          f"{' '.join(f'{v:.2f}' for v in os.getloadavg())}\n")
    m = arm6r(False)
    lay = parameter_layout(m)
    print("| poses | what | geometric (ms, wall / cpu) | geometric + transmission (ms, wall / cpu) | ratio (cpu) "
          "| held-out mean (mm), geometric / with transmission |")
    print("|---|---|---|---|---|---|")
    for n in (1000, 10_000):
        true, data = rc.simulate(m, n, seed=1)
        frames = list(true.frames)
        for i, kinds in HARMONICS.items():
            frames[i] = replace(frames[i], **kinds)
        true = true.replace(frames=tuple(frames))
        data = rc.sim.measure(true, data.q, rng=2)
        held = rc.sim.measure(true, rc.random_configurations(m, 1000, rng=3), rng=4)
        rep = args.repeat if n <= 1000 else max(2, args.repeat // 5)
        times, errors = [], []
        for fams in (("geometric",), ("geometric", "transmission")):
            times.append(best(lambda fams=fams, data=data: rc.calibrate(m, data, parameters=fams), rep))
            r = rc.calibrate(m, data, parameters=fams, validation=held)
            errors.append(np.mean(r.validation.errors_after) * 1e3)
        row(n, "calibrate()", times, f"{errors[0]:.4f} / {errors[1]:.4f}")
        times = [best(lambda c=c, q=data.q: evaluate(m, q, jacobian=True, columns=lay.indices(c)), rep)
                 for c in (candidate_parameters(m), candidate_parameters(m, ("geometric", "transmission")))]
        row(n, "Jacobian", times, "")


def row(n: int, what: str, times: list, extra: str) -> None:
    (w0, c0), (w1, c1) = times
    print(f"| {n} | {what} | {w0 * 1e3:.1f} / {c0 * 1e3:.1f} | {w1 * 1e3:.1f} / {c1 * 1e3:.1f} | {c1 / c0:.2f}x "
          f"| {extra} |")


if __name__ == "__main__":
    main()
