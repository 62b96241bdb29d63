"""The fixed cost of a calibrate() call: its function calls and CPU time by size, against an earlier commit.

Run: python benchmarks/bench_calls.py [--baseline 7fe2faf] [--poses 100,300,1000,3000] [--repeat 10]

The 6-joint arm of ``bench_identify.py``, ``rc.simulate(m, n, seed=1)``, ``rc.calibrate(m, data)``
with default options (as ``bench_engine.py``), BLAS on one thread. For each size: the number of
function calls one call makes (Python functions and the C functions Python calls, counted by
``sys.setprofile`` after one untimed call) and the best CPU time (``process_time``) of ``--repeat``
calls. The package at ``--baseline`` (``git archive`` into a temporary folder, first on
``sys.path``) and this one each run in a child process of their own, taking turns, twice (the lower
time kept). Last, each package's time fitted as a fixed cost plus a cost per pose (least squares
over the sizes): at small sizes a call's time follows its count of calls, whatever the poses.
"""

from __future__ import annotations

import json
import os
import platform
import sys
import tempfile
import time

import numpy as np
from threadpoolctl import threadpool_limits

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from bench_identify import arm6r, options  # noqa: E402
from bench_kinematics import baseline_sources, child_figures  # noqa: E402

import robocal as rc  # noqa: E402


def calls_of(fn) -> int:
    """How many Python and C function calls ``fn()`` makes."""
    count = 0

    def seen(frame, event, arg):
        nonlocal count
        if event in ("call", "c_call"):
            count += 1

    sys.setprofile(seen)
    try:
        fn()
    finally:
        sys.setprofile(None)
    return count


def child(sizes: list[int], repeat: int) -> None:
    """This process' figures as JSON on stdout (the package first on ``sys.path`` is measured)."""
    m = arm6r(False)
    out = {}
    with threadpool_limits(limits=1, user_api="blas"):
        for n in sizes:
            _, data = rc.simulate(m, n, seed=1)
            rc.calibrate(m, data)
            calls = calls_of(lambda d=data: rc.calibrate(m, d))
            best = np.inf
            for _ in range(repeat):
                c = time.process_time()
                rc.calibrate(m, data)
                best = min(best, time.process_time() - c)
            out[str(n)] = {"calls": calls, "cpu": best}
    print(json.dumps(out))


def main(argv=None):
    args = options(__doc__, argv, baseline="7fe2faf", poses="100,300,1000,3000", repeat=10, child=0)
    sizes = [int(v) for v in args.poses.split(",")]
    if args.child:
        return child(sizes, args.repeat)
    print(f"# calibrate()'s calls and CPU time against {args.baseline}, "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {platform.machine()}, {os.cpu_count()} cores, "
          f"numpy {np.__version__}, best of {args.repeat}; load average before "
          f"{' '.join(f'{v:.2f}' for v in os.getloadavg())}\n")
    found: dict = {}
    with tempfile.TemporaryDirectory() as tmp:
        src = baseline_sources(args.baseline, tmp)
        for _ in range(2):
            for label, path in ((args.baseline, src), ("now", None)):
                for n, got in child_figures(__file__, path, "--poses", args.poses, "--repeat", args.repeat).items():
                    prev = found.setdefault((label, int(n)), got)
                    prev["cpu"] = min(prev["cpu"], got["cpu"])
    print(f"| poses | {args.baseline} calls | now calls | {args.baseline} CPU (ms) | now CPU (ms) | now / "
          f"{args.baseline} |")
    print("|---|---|---|---|---|---|")
    for n in sizes:
        a, b = found[(args.baseline, n)], found[("now", n)]
        print(f"| {n} | {a['calls']:,} | {b['calls']:,} | {a['cpu'] * 1e3:.2f} | {b['cpu'] * 1e3:.2f} | "
              f"{b['cpu'] / a['cpu']:.2f}x |")
    print()
    A = np.column_stack([np.ones(len(sizes)), sizes])
    for label in (args.baseline, "now"):
        fixed, per_pose = np.linalg.lstsq(A, [found[(label, n)]["cpu"] for n in sizes], rcond=None)[0]
        print(f"- {label}: {fixed * 1e3:.2f} ms a call plus {per_pose * 1e6:.2f} us a pose")
    print(f"\nload average after: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
