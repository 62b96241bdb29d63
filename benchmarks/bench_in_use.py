"""What judging a calibration in use costs: ``calibrate()`` now against the package before the
accuracy in use existed, in one run.

Run: python benchmarks/bench_in_use.py [--repeat 10] [--baseline 7fe2faf] [--poses 1000] [--folds 2,10]

The baseline is the package at commit ``--baseline`` (``git archive`` into a temporary folder),
timed by this same script in a child process with those sources first on ``sys.path``; the two
take turns, twice. Both calibrate the 6-joint arm of ``bench_identify.py`` (``rc.simulate(m, n,
seed=1)``, geometric parameters, default options), best of ``--repeat`` calls after three untimed
ones. The baseline has no cross-validation, no model choice by it, no coverage and no judgement of
the geometry over the workspace; the difference is what they cost. For a second reading of the
same campaign the new package is also timed with a validation set given (the campaign is still
cross-validated: the model choice and the record's own held-out errors are made on its folds) and
with each of ``--folds`` (the default is 5). Each figure is given as wall-clock time and as CPU time
(``process_time``), the best of each.
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import tempfile
import time
import warnings

HERE = os.path.dirname(os.path.abspath(__file__))


def _time(n: int, repeat: int, validation: bool, folds: int = 5) -> tuple[float, float]:
    import robocal as rc
    sys.path.insert(0, HERE)
    from bench_identify import arm6r  # noqa: E402

    m = arm6r()
    _, data = rc.simulate(m, n, seed=1)
    held = rc.simulate(m, 50, seed=2)[1] if validation else None
    kw = {"validation": held} if validation else ({} if folds == 5 else {"folds": folds})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for _ in range(3):
            rc.calibrate(m, data, **kw)
        wall, cpu = [], []
        for _ in range(repeat):
            t, c = time.perf_counter(), time.process_time()
            rc.calibrate(m, data, **kw)
            wall.append(time.perf_counter() - t)
            cpu.append(time.process_time() - c)
    return min(wall), min(cpu)


def child(src: str, n: int, repeat: int, validation: bool, folds: int = 5) -> tuple[float, float]:
    code = (f"import sys; sys.path.insert(0, {src!r}); sys.path.insert(1, {HERE!r}); "
            f"import bench_in_use as b; print(*b._time({n}, {repeat}, {validation}, {folds}))")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    wall, cpu = out.stdout.strip().splitlines()[-1].split()
    return float(wall), float(cpu)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=10)
    ap.add_argument("--baseline", default="7fe2faf")
    ap.add_argument("--poses", type=int, default=1000)
    ap.add_argument("--folds", default="2,10", help="other numbers of folds to time beside the default 5")
    args = ap.parse_args()
    root = os.path.dirname(HERE)
    now = os.path.join(root, "src")
    others = [int(k) for k in args.folds.split(",") if k]
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        archive = subprocess.run(["git", "-C", root, "archive", args.baseline, "src"], capture_output=True,
                                 check=True).stdout
        subprocess.run(["tar", "-x", "-C", tmp], input=archive, check=True)
        then = os.path.join(tmp, "src")
        runs = {"baseline": (then, False, 5), "now (5 folds)": (now, False, 5),
                **{f"now, {k} folds": (now, False, k) for k in others},
                "now, validation given": (now, True, 5)}
        rows: dict = {k: [] for k in runs}
        for _ in range(2):
            for label, (src, validation, folds) in runs.items():
                rows[label].append(child(src, args.poses, args.repeat, validation, folds))
    base = [min(t[i] for t in rows["baseline"]) for i in (0, 1)]
    print(f"# calibrate() at {args.poses} poses, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, "
          f"{platform.machine()}, load average {load:.1f} before, {os.getloadavg()[0]:.1f} after\n")
    print("| configuration | wall ms | CPU ms | wall / baseline | CPU / baseline |")
    print("|---|---|---|---|---|")
    for label, found in rows.items():
        wall, cpu = (min(t[i] for t in found) for i in (0, 1))
        print(f"| {label} | {wall * 1e3:.2f} | {cpu * 1e3:.2f} | {wall / base[0]:.2f}x | {cpu / base[1]:.2f}x |")


if __name__ == "__main__":
    main()
