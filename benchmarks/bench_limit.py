"""Time the controller-precision Monte Carlo on a 6R arm and report its peak memory.

    python benchmarks/bench_limit.py --samples 1000000

Peak memory is ``ru_maxrss`` of this process (kB on Linux), so run one sample count per process
to compare sizes.
"""

from __future__ import annotations

import argparse
import math
import os
import resource
import time

import robocal as rc
from robocal.limit import controller_precision

DEG = math.pi / 180


def arm() -> rc.RobotModel:
    """A 6R industrial arm with shoulder and elbow offsets (modified DH), about 1.1 m reach."""
    rows = [dict(r=0.40), dict(alpha=-90 * DEG, d=0.15, theta=-90 * DEG), dict(d=0.60),
            dict(alpha=-90 * DEG, d=0.12, r=0.62), dict(alpha=90 * DEG), dict(alpha=-90 * DEG)]
    return rc.serial_model("bench6r", rows, markers=[("tool", (0.0, 0.0, 0.1))])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=1_000_000)
    ap.add_argument("--chunk-size", type=int, default=2048)
    ap.add_argument("--repeat", type=int, default=3, help="report the best of this many runs")
    args = ap.parse_args()
    model = arm()
    kw = dict(encoder_resolution=0.01 * DEG, length_quantum=1e-4, angle_quantum=1e-3 * DEG)
    controller_precision(model, n_samples=1000, rng=0, **kw)  # warm caches and imports
    times = []
    for k in range(args.repeat):
        t0 = time.perf_counter()
        r = controller_precision(model, n_samples=args.samples, chunk_size=args.chunk_size, rng=k, **kw)
        times.append(time.perf_counter() - t0)
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"samples {args.samples}  chunk {args.chunk_size}  cores {os.cpu_count()}  "
          f"best {min(times):.2f} s  (runs: {', '.join(f'{t:.2f}' for t in times)})  "
          f"peak RSS {peak_mb:.0f} MB  mean deviation {r.mean * 1e3:.4f} mm")


if __name__ == "__main__":
    main()
