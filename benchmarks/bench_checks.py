"""What the argument checks cost per call of the kinematics entry points.

Run: python benchmarks/bench_checks.py [--repeat 15] [--calls 300] [--poses 1]

Each entry point is timed as called (its ``checked`` decorator first) and without the decorator
(the function it wraps), in turns within one process, on the 6-joint arm of ``bench_identify.py``
at ``--poses`` random configurations: CPU time (``process_time``) per call, best of ``--repeat``
blocks of ``--calls`` calls. The difference is the checks' cost. ``forward_kinematics`` calls the
checked ``evaluate`` either way, so its difference is its own checks only.
"""

from __future__ import annotations

import os
import platform
import sys
import time

import numpy as np

import robocal as rc

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_identify import arm6r, options  # noqa: E402


def per_call(fn, calls: int, repeat: int) -> float:
    """Best CPU time per call over ``repeat`` blocks of ``calls`` calls."""
    fn()
    best = np.inf
    for _ in range(repeat):
        t = time.process_time()
        for _ in range(calls):
            fn()
        best = min(best, (time.process_time() - t) / calls)
    return best


def main(argv=None):
    args = options(__doc__, argv, repeat=15, calls=300, poses=1)
    m = arm6r(False)
    q = rc.random_configurations(m, args.poses, rng=0)
    print(f"# argument checks per call, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {platform.machine()}, "
          f"{args.poses} pose(s), best of {args.repeat} x {args.calls} calls, CPU time; load average before "
          f"{os.getloadavg()[0]:.1f}\n")
    print("| function | checked (us) | unchecked (us) | the checks (us) |")
    print("|---|---|---|---|")
    for name, fn in (("evaluate", rc.kinematics.evaluate), ("forward_kinematics", rc.forward_kinematics),
                     ("jacobian", rc.jacobian), ("gravity_loads", rc.kinematics.gravity_loads)):
        checked = per_call(lambda fn=fn: fn(m, q), args.calls, args.repeat)
        bare = per_call(lambda fn=fn: fn.__wrapped__(m, q), args.calls, args.repeat)
        print(f"| {name} | {checked * 1e6:.1f} | {bare * 1e6:.1f} | {(checked - bare) * 1e6:.1f} |")


if __name__ == "__main__":
    main()
