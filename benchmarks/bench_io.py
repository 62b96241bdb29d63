"""The command line end to end on large tracker files: read, solve, write, report, with peak memory.

Run: python benchmarks/bench_io.py [--poses 10000,100000,1000000] [--baseline-poses 100000]

For each size, a 6-joint arm's campaign of one tracked point is simulated and written as a tracker
export (pose label, six joint columns with unit suffixes, x, y, z in mm, 15 significant digits).
Each figure comes from a fresh process, so its peak (``VmHWM``, the process's own high-water mark)
is that step's alone:

- ``read``: ``robocal.read_measurements`` (the compiled parser when pandas is installed);
- ``read (rows)``: the same without pandas (every file row by row), the baseline (up to
  ``--baseline-poses``);
- ``calibrate()``: the library's solve on the measurements, without files;
- ``write``: ``write_result`` (result.json and result.npz) and ``write_model`` (calibrated.yaml);
- ``robocal calibrate``: the whole command (read, solve, checks, write), then ``robocal report`` on
  its result.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np

import robocal as rc

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_identify import arm6r  # noqa: E402

HWM = "int(next(l.split()[1] for l in open('/proc/self/status') if l.startswith('VmHWM:'))) / 1024"

STEPS = {
    "read": """
        import robocal as rc
        model = rc.read_model(MODEL)
        t = time.perf_counter(); data = rc.read_measurements(DATA, model); seconds = time.perf_counter() - t
    """,
    "read (rows)": """
        sys.modules["pandas"] = None  # robocal without its 'fast' extra: every file read row by row
        import robocal as rc
        model = rc.read_model(MODEL)
        t = time.perf_counter(); data = rc.read_measurements(DATA, model); seconds = time.perf_counter() - t
    """,
    "calibrate()": """
        import robocal as rc
        model = rc.read_model(MODEL); data = rc.read_measurements(DATA, model)
        rc.calibrate(model, data.subset(slice(0, 200)))  # warm-up
        t = time.perf_counter(); rc.calibrate(model, data); seconds = time.perf_counter() - t
    """,
    "write": """
        import robocal as rc
        model = rc.read_model(MODEL); result = rc.calibrate(model, rc.read_measurements(DATA, model))
        import os; os.makedirs(OUT, exist_ok=True)
        t = time.perf_counter()
        rc.write_result(result, OUT + "/result.json", force=True)
        rc.write_model(result.calibrated_model, OUT + "/calibrated.yaml", force=True)
        seconds = time.perf_counter() - t
    """,
    "robocal calibrate": """
        from robocal.cli import main
        t = time.perf_counter(); code = main(["calibrate", MODEL, DATA, "--out", OUT, "--force"])
        seconds = time.perf_counter() - t
    """,
    "robocal report": """
        from robocal.cli import main
        t = time.perf_counter(); code = main(["report", OUT + "/result.json", "--out", OUT + "/report.html", "--force"])
        seconds = time.perf_counter() - t
    """,
}


def tracker_file(model, n: int, path: Path) -> None:
    """A tracker export of ``n`` simulated poses (written with numpy, not the reader under test)."""
    _, data = rc.simulate(model, n, seed=1)
    deg = np.rad2deg(data.q)
    mm = data.positions[:, 0] * 1e3
    header = "pose," + ",".join(f"{j}_deg" for j in model.joint_names) + ",tool_x_mm,tool_y_mm,tool_z_mm"
    table = np.column_stack([np.arange(n), deg, mm])
    np.savetxt(path, table, delimiter=",", header=header, comments="", fmt=["P%d"] + ["%.15g"] * (table.shape[1] - 1))


def run_step(name: str, folder: Path) -> tuple[float, float]:
    code = "import sys, time\n" + textwrap.dedent(STEPS[name]).replace("MODEL", repr(str(folder / "model.yaml"))) \
        .replace("DATA", repr(str(folder / "data.csv"))).replace("OUT", repr(str(folder / "run")))
    code += f"\nprint(seconds, {HWM})\n"
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    if p.returncode != 0:
        raise SystemExit(f"{name}: {p.stderr.strip().splitlines()[-1]}")
    seconds, peak = p.stdout.split()[-2:]
    return float(seconds), float(peak)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--poses", default="10000,100000,1000000")
    ap.add_argument("--baseline-poses", type=int, default=100_000)
    args = ap.parse_args(argv)
    print(f"# command line end to end, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, load average "
          f"{os.getloadavg()[0]:.1f}, robocal {rc.__version__}")
    print(f"{'poses':>9} {'step':>18} {'seconds':>8} {'peak MB':>8} {'rows/s':>10}")
    model = arm6r(False)
    for n in (int(v) for v in args.poses.split(",")):
        with tempfile.TemporaryDirectory(prefix="robocal-bench-io-") as d:
            folder = Path(d)
            rc.write_model(model, folder / "model.yaml")
            tracker_file(model, n, folder / "data.csv")
            size = (folder / "data.csv").stat().st_size / 2 ** 20
            print(f"{n:>9,} {'file':>18} {'':>8} {size:>8.0f} MB")
            for name in STEPS:
                if name == "read (rows)" and n > args.baseline_poses:
                    continue
                seconds, peak = run_step(name, folder)
                rate = f"{n / seconds:,.0f}" if name.startswith("read") else ""
                print(f"{n:>9,} {name:>18} {seconds:>8.2f} {peak:>8.0f} {rate:>10}", flush=True)


if __name__ == "__main__":
    main()
