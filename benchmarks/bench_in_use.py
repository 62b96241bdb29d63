"""What judging a calibration in use costs: ``calibrate()`` now against the package before the
accuracy in use existed, in one run.

Run: python benchmarks/bench_in_use.py [--repeat 10] [--baseline 7fe2faf] [--poses 1000]

The baseline is the package at commit ``--baseline`` (``git archive`` into a temporary folder),
timed by this same script in a child process with those sources first on ``sys.path``; the two
take turns, twice. Both calibrate the 6-joint arm of ``bench_identify.py`` (``rc.simulate(m, n,
seed=1)``, geometric parameters, default options), best of ``--repeat`` calls after three untimed
ones. The baseline has no cross-validation, no model choice by it, no coverage and no judgement of
the geometry over the workspace; the difference is what they cost. For a second reading of the
same campaign the new package is also timed with a validation set given (no cross-validation).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
import warnings

HERE = os.path.dirname(os.path.abspath(__file__))


def _time(n: int, repeat: int, validation: bool) -> float:
    import robocal as rc
    sys.path.insert(0, HERE)
    from bench_identify import arm6r  # noqa: E402

    m = arm6r()
    _, data = rc.simulate(m, n, seed=1)
    held = rc.simulate(m, 50, seed=2)[1] if validation else None
    kw = {"validation": held} if validation else {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for _ in range(3):
            rc.calibrate(m, data, **kw)
        times = []
        for _ in range(repeat):
            t = time.perf_counter()
            rc.calibrate(m, data, **kw)
            times.append(time.perf_counter() - t)
    return min(times)


def child(src: str, n: int, repeat: int, validation: bool) -> float:
    code = (f"import sys; sys.path.insert(0, {src!r}); sys.path.insert(1, {HERE!r}); "
            f"import bench_in_use as b; print(b._time({n}, {repeat}, {validation}))")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    return float(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=10)
    ap.add_argument("--baseline", default="7fe2faf")
    ap.add_argument("--poses", type=int, default=1000)
    args = ap.parse_args()
    root = os.path.dirname(HERE)
    now = os.path.join(root, "src")
    with tempfile.TemporaryDirectory() as tmp:
        archive = subprocess.run(["git", "-C", root, "archive", args.baseline, "src"], capture_output=True,
                                 check=True).stdout
        subprocess.run(["tar", "-x", "-C", tmp], input=archive, check=True)
        then = os.path.join(tmp, "src")
        rows = {"baseline": [], "now": [], "now, validation given": []}
        for _ in range(2):
            rows["baseline"].append(child(then, args.poses, args.repeat, False))
            rows["now"].append(child(now, args.poses, args.repeat, False))
            rows["now, validation given"].append(child(now, args.poses, args.repeat, True))
    base = min(rows["baseline"])
    print(json.dumps({"poses": args.poses, "machine": platform.machine(), "load": os.getloadavg()[0],
                      **{k: round(min(v) * 1e3, 2) for k, v in rows.items()},
                      "now / baseline": round(min(rows["now"]) / base, 2)}, indent=1))


if __name__ == "__main__":
    main()
