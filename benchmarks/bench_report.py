"""Time `robocal report` on a 20,000-pose 6D simulated campaign, against an earlier report, same run.

    python benchmarks/bench_report.py                      # 20,000 poses, baseline commit 2f0763d
    python benchmarks/bench_report.py --poses 2000 --baseline HEAD~3
    python benchmarks/bench_report.py --humanoid --baseline 7fe2faf   # 135 parameters, 19 joints

``--humanoid``: the humanoid-sized tree of tests/robots.py (19 joints, three fixed frames, five
markers, masses from the geometry), 400 poses (320 fitted), geometric and compliance parameters.

The campaign: a 6R arm measured with positions and orientations (a tracker with a 6D probe), 20 %
of the poses held out, written as model YAML and measurement CSVs and calibrated by `robocal
calibrate`. Each report is one `robocal report` process: wall time, peak memory of the process
(ru_maxrss) and the size of the HTML file. Wall time, from starting the process to its exit, is
what a user waits; CPU time (user + system of the process) is the figure that holds on a shared
machine, where wall time grows with the load. The baseline is the report of an earlier commit
(``git archive`` of its ``src`` into a temporary folder, run with the same interpreter).
"""

from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import robocal as rc

DEG = math.pi / 180
ROOT = Path(__file__).resolve().parent.parent


def arm() -> rc.RobotModel:
    """A 6R industrial arm with shoulder and elbow offsets (modified DH), about 1.1 m reach."""
    rows = [dict(r=0.40), dict(alpha=-90 * DEG, d=0.15, theta=-90 * DEG), dict(d=0.60),
            dict(alpha=-90 * DEG, d=0.12, r=0.62), dict(alpha=90 * DEG), dict(alpha=-90 * DEG)]
    limits = [(-170 * DEG, 170 * DEG), (-120 * DEG, 60 * DEG), (-60 * DEG, 160 * DEG),
              (-170 * DEG, 170 * DEG), (-110 * DEG, 110 * DEG), (-180 * DEG, 180 * DEG)]
    return rc.serial_model("bench6r", rows, markers=[("tool", (0.02, 0.01, 0.1))], joint_limits=limits)


def campaign(folder: Path, poses: int) -> Path:
    """result.json of a calibration on ``poses`` simulated 6D poses, through the command line."""
    model = arm()
    _, data = rc.simulate(model, poses, orientation=True, noise=2e-5, noise_rot=2e-5, seed=7)
    n_fit = int(0.8 * poses)
    rc.write_model(model, folder / "model.yaml")
    rc.write_measurements(data.subset(slice(0, n_fit)), folder / "fit.csv", model=model)
    rc.write_measurements(data.subset(slice(n_fit, None)), folder / "validation.csv", model=model)
    run([sys.executable, "-m", "robocal", "calibrate", str(folder / "model.yaml"), str(folder / "fit.csv"),
         "--validation", str(folder / "validation.csv"), "--limit-mm", "0.05", "--out", str(folder / "out")])
    return folder / "out" / "result.json"


def humanoid_campaign(folder: Path, poses: int) -> Path:
    """result.json of the humanoid-sized model of tests/robots.py on ``poses`` simulated poses."""
    sys.path.insert(0, str(ROOT / "tests"))
    from robots import humanoid

    model = humanoid()
    _, data = rc.simulate(model, poses, parameters=("geometric", "compliance"), seed=3)
    n_fit = int(0.8 * poses)
    rc.write_model(model, folder / "model.yaml")
    rc.write_measurements(data.subset(slice(0, n_fit)), folder / "fit.csv", model=model)
    rc.write_measurements(data.subset(slice(n_fit, None)), folder / "validation.csv", model=model)
    run([sys.executable, "-m", "robocal", "calibrate", str(folder / "model.yaml"), str(folder / "fit.csv"),
         "--validation", str(folder / "validation.csv"), "--parameters", "geometric,compliance",
         "--out", str(folder / "out")])
    return folder / "out" / "result.json"


def run(cmd, env=None) -> None:
    done = subprocess.run(cmd, env=env, capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{done.stdout}{done.stderr}")


def timed_report(result: Path, out: Path, src: Path | None) -> tuple[float, float, float, float]:
    """(wall seconds, CPU seconds, peak MB, file MB) of one `robocal report` process, start to exit."""
    env = dict(os.environ, PYTHONPATH=str(src)) if src else None
    script = ("import resource, sys; from robocal.cli import main; "
              f"code = main(['report', {str(result)!r}, '--out', {str(out)!r}, '--force']); "
              "u = resource.getrusage(resource.RUSAGE_SELF); print(u.ru_utime + u.ru_stime, u.ru_maxrss); "
              "sys.exit(code)")
    t = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t
    if done.returncode != 0:
        sys.exit(f"report failed:\n{done.stdout}{done.stderr}")
    cpu, kb = done.stdout.split()[-2:]
    return wall, float(cpu), float(kb) / 1024, out.stat().st_size / 1e6


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--poses", type=int, default=20_000)
    ap.add_argument("--baseline", default="2f0763d", help="commit whose report is the baseline")
    ap.add_argument("--repeat", type=int, default=2, help="best of this many runs of each report")
    ap.add_argument("--humanoid", action="store_true", help="the humanoid-sized model (--poses default 400)")
    args = ap.parse_args()
    if args.humanoid and args.poses == 20_000:
        args.poses = 400
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        t = time.perf_counter()
        result = (humanoid_campaign if args.humanoid else campaign)(tmp, args.poses)
        print(f"campaign: {args.poses} poses, {'humanoid-sized' if args.humanoid else '6D'}, "
              f"calibrated in {time.perf_counter() - t:.1f} s; "
              f"result.json {result.stat().st_size / 1e6:.1f} MB")
        base = tmp / "baseline"
        base.mkdir()
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", args.baseline, "src"], capture_output=True,
                                 check=True).stdout
        subprocess.run(["tar", "-x", "-C", str(base)], input=archive, check=True)
        print(f"load average before: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
        print("| report | wall time (s) | CPU time (s) | peak memory (MB) | file (MB) |\n|---|---|---|---|---|")
        for label, src in ((f"baseline {args.baseline}", base / "src"), ("this tree", None)):
            runs = [timed_report(result, tmp / "report.html", src) for _ in range(args.repeat)]
            wall, cpu, mb, size = min(runs)
            print(f"| {label} | {wall:.2f} | {cpu:.2f} | {mb:.0f} | {size:.2f} |")


if __name__ == "__main__":
    main()
