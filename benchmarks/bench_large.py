"""Peak memory of a calibration over a large campaign, and the chunked solve against the in-memory one.

Run: python benchmarks/bench_large.py [--poses 1000000] [--check-poses 10000]

Above ``LARGE_POSES`` poses a campaign of point data is evaluated a chunk of poses at a time and
solved on normal equations accumulated chunk by chunk (``Problem(chunked=True)``), so memory
grows with the parameter count, not the pose count. The script calibrates ``--poses`` simulated
poses of a 6-joint arm (geometric parameters) and prints the peak resident memory of the process
(``ru_maxrss``, which includes the interpreter with numpy and scipy and the simulated data); then,
on the first ``--check-poses`` poses, solves the same problem chunked and in memory and prints
the largest relative difference of the parameters.
"""

from __future__ import annotations

import os
import resource
import sys
import time

import numpy as np

import robocal as rc
from robocal.identification import Problem, solve
from robocal.kinematics import parameter_vector

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_identify import arm6r, options  # noqa: E402


def peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def main(argv=None):
    args = options(__doc__, argv, poses=1_000_000, check_poses=10_000)
    print(f"# large campaigns, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, load average "
          f"{os.getloadavg()[0]:.1f}")
    m = arm6r(False)
    print(f"after imports: peak {peak_mb():.0f} MB")
    truth, data = rc.simulate(m, args.poses, seed=1)
    print(f"{args.poses} poses simulated: peak {peak_mb():.0f} MB")
    t = time.perf_counter()
    result = rc.calibrate(m, data)
    elapsed = time.perf_counter() - t
    solver = result.solver
    print(f"calibrate({args.poses} poses): {elapsed:.1f} s, peak {peak_mb():.0f} MB, {len(result.parameters)} "
          f"parameters, nfev {solver.nfev}, verdict {result.verdict}, sigma0 {solver.sigma0 * 1e3:.4f} mm")
    for c in result.checks:
        if c.status != "pass":
            print(f"check {c.name}: {c.status}, {c.summary}")
    err = max(abs(result.estimate(n).estimate - v) / max(result.estimate(n).std, 1e-300)
              for n, v in zip(rc.parameter_names(m), rc.parameter_vector(truth, m)) if n in result.parameter_names)
    print(f"largest error of an estimate against the simulated truth: {err:.2f} standard deviations")
    sub = data.subset(slice(0, args.check_poses))
    names = rc.identifiability(m, sub).identified
    p0 = parameter_vector(m)
    chunked = solve(Problem(m, names, data=sub, compliance=False, chunked=True), p0)
    whole = solve(Problem(m, names, data=sub, compliance=False, chunked=False), p0)
    scale = np.maximum(np.abs(whole.p), 1e-300)
    print(f"{args.check_poses}-pose subset, chunked against in-memory solve: largest relative difference "
          f"{np.max(np.abs(chunked.p - whole.p) / scale):.1e} (nfev {chunked.nfev} and {whole.nfev})")


if __name__ == "__main__":
    main()
