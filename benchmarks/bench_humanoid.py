"""Time calibrate() of a humanoid-sized model against the package at an earlier commit, in one run.

Run: python benchmarks/bench_humanoid.py [--baseline 7fe2faf] [--poses 500] [--repeat 3] [--profile 0]

The model is the 19-joint tree of ``tests/robots.py`` (a trunk, two 7-joint arms and a head; masses
assumed from the geometry) with two markers, one on each hand; ``--poses`` simulated poses of both
(500 poses: 1,000 measured points; ``rc.simulate(m, n, parameters=families, seed=1)``), calibrated
with default options (``rc.calibrate(m, data, parameters=families)``), geometric, then geometric
and compliance. The package at ``--baseline`` (``git archive`` into a temporary folder, first on
``sys.path``) and this one each run in child processes of their own, taking turns, twice; a figure
is the best CPU time (``process_time``) of ``--repeat`` calls after one untimed, BLAS on one thread.
Beside the times: the verdict, the parameters fitted and the RMS error after the fit on the fitted
poses, so that the two packages are seen to do the same job.

``--profile 1``: this package's calls also under the profiler, the cumulative CPU time of the
steps the calibration takes (each function of robocal's that takes at least 3 % of it).
"""

from __future__ import annotations

import cProfile
import json
import os
import pstats
import sys
import tempfile
import time

import numpy as np
from threadpoolctl import threadpool_limits

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(os.path.dirname(HERE), "tests"))
from bench_identify import options  # noqa: E402
from bench_kinematics import baseline_sources, child_figures, heading  # noqa: E402
from robots import humanoid  # noqa: E402

import robocal as rc  # noqa: E402

FAMILIES = (("geometric",), ("geometric", "compliance"))


def cpu_best(fn, repeat: int) -> float:
    fn()
    best = np.inf
    for _ in range(repeat):
        c = time.process_time()
        fn()
        best = min(best, time.process_time() - c)
    return best


def child(poses: int, repeat: int) -> None:
    """This process' figures as JSON on stdout (the package first on ``sys.path`` is timed)."""
    m = humanoid(markers=("lhand", "rhand"))
    out = {}
    with threadpool_limits(limits=1, user_api="blas"):
        for fam in FAMILIES:
            _, data = rc.simulate(m, poses, parameters=fam, seed=1)
            res = rc.calibrate(m, data, parameters=fam)
            out["+".join(fam)] = {"cpu": cpu_best(lambda d=data, f=fam: rc.calibrate(m, d, parameters=f), repeat),
                                  "verdict": res.verdict, "fitted": len(res.parameters),
                                  "rms": res.stats.fit_after.rms}
    print(json.dumps(out))


def profile(poses: int) -> None:
    """The steps of this package's calibrations, cumulative CPU time under the profiler."""
    m = humanoid(markers=("lhand", "rhand"))
    for fam in FAMILIES:
        _, data = rc.simulate(m, poses, parameters=fam, seed=1)
        rc.calibrate(m, data, parameters=fam)
        prof = cProfile.Profile(timer=time.process_time)
        with threadpool_limits(limits=1, user_api="blas"):
            prof.runcall(rc.calibrate, m, data, parameters=fam)
        stats = pstats.Stats(prof).stats      # type: ignore[attr-defined]
        total = max(v[3] for v in stats.values())
        print(f"\n{'+'.join(fam)}, under the profiler: {total:.3f} s\n")
        print("| step | cumulative CPU (s) | share |\n|---|---|---|")
        rows = sorted(((v[3], f"{os.path.basename(k[0])}:{k[2]}") for k, v in stats.items()
                       if "robocal" in k[0] and v[3] >= 0.03 * total), reverse=True)
        for t, name in rows:
            print(f"| {name} | {t:.3f} | {t / total:.0%} |")


def main(argv=None):
    args = options(__doc__, argv, baseline="7fe2faf", poses=500, repeat=3, profile=0, child=0)
    if args.child:
        return child(args.poses, args.repeat)
    print(heading(f"calibrate() of the humanoid-sized tree (19 joints, two markers, {args.poses} poses)", args.baseline,
                  args.repeat))
    with tempfile.TemporaryDirectory() as tmp:
        src = baseline_sources(args.baseline, tmp)
        found: dict = {}
        for _ in range(2):
            for label, path in ((args.baseline, src), ("now", None)):
                for fam, got in child_figures(__file__, path, "--poses", args.poses, "--repeat", args.repeat).items():
                    prev = found.setdefault((label, fam), got)
                    prev["cpu"] = min(prev["cpu"], got["cpu"])
    print(f"| parameters | {args.baseline} CPU (s) | now CPU (s) | now / {args.baseline} | verdicts | parameters "
          "fitted | RMS after the fit (mm) |")
    print("|---|---|---|---|---|---|---|")
    for fam in ("+".join(f) for f in FAMILIES):
        a, b = found[(args.baseline, fam)], found[("now", fam)]
        print(f"| {fam} | {a['cpu']:.3f} | {b['cpu']:.3f} | {b['cpu'] / a['cpu']:.2f}x | {a['verdict']}, "
              f"{b['verdict']} | {a['fitted']}, {b['fitted']} | {a['rms'] * 1e3:.4f}, {b['rms'] * 1e3:.4f} |")
    print(f"\nload average after: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
    if args.profile:
        profile(args.poses)


if __name__ == "__main__":
    main()
