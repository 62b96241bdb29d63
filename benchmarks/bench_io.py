"""The command line end to end on large tracker files: read, solve, write, report, with peak memory.

Run: python benchmarks/bench_io.py [--poses 10000,100000,1000000] [--baseline a2fc338] [--baseline-poses 100000]

For each size, a 6-joint arm's campaign of one tracked point is simulated and written as a tracker
export (pose label, six joint columns with unit suffixes, x, y, z in mm, 15 significant digits).
Each figure comes from a fresh process, so its peak (``VmHWM``, the process's own high-water mark)
is that step's alone; each is given as wall-clock time and as CPU time (``process_time``: the
process's user and system time), the one other processes on a shared machine disturb least:

- ``read``: ``robocal.read_measurements`` (numpy's compiled text parser);
- ``read (rows)``: the same file with its first label quoted, which the compiled parser leaves to
  the row reader (up to ``--baseline-poses``);
- ``read, --joints``: the same campaign as two files, points and joint readings, joined on ``pose``;
- ``calibrate()``: the library's solve on the measurements, without files;
- ``write``: ``write_result`` (result.json and result.npz) and ``write_model`` (calibrated.yaml);
- ``robocal calibrate``: the whole command (read, solve, checks, write), then ``robocal report`` on
  its result.

With ``--baseline REV`` the package at that commit (``git archive`` into a temporary folder, first
on ``sys.path``) runs the same steps on the same files in the same run, step by step after this
one's; beyond ``--baseline-poses`` it runs the two commands only (its steps take many minutes there).
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
        import robocal as rc
        model = rc.read_model(MODEL)
        t = time.perf_counter(); data = rc.read_measurements(ROWS, model); seconds = time.perf_counter() - t
    """,
    "read, --joints": """
        import robocal as rc
        model = rc.read_model(MODEL)
        t = time.perf_counter(); data = rc.read_measurements(POINTS, model, joints=JOINTS)
        seconds = time.perf_counter() - t
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


def tracker_file(model, n: int, folder: Path) -> None:
    """A tracker export of ``n`` simulated poses (written with numpy, not the reader under test), the
    same with its first label quoted (rows.csv), and the same campaign as a file of points and a file
    of joint readings."""
    _, data = rc.simulate(model, n, seed=1)
    deg = np.rad2deg(data.q)
    mm = data.positions[:, 0] * 1e3
    joints = ",".join(f"{j}_deg" for j in model.joint_names)
    points = "tool_x_mm,tool_y_mm,tool_z_mm"
    for name, header, table in (("data.csv", f"pose,{joints},{points}", np.column_stack([np.arange(n), deg, mm])),
                                ("points.csv", f"pose,{points}", np.column_stack([np.arange(n), mm])),
                                ("joints.csv", f"pose,{joints}", np.column_stack([np.arange(n), deg]))):
        np.savetxt(folder / name, table, delimiter=",", header=header, comments="",
                   fmt=["P%d"] + ["%.15g"] * (table.shape[1] - 1))
    raw = (folder / "data.csv").read_bytes()
    (folder / "rows.csv").write_bytes(raw.replace(b"\nP0,", b'\n"P0",', 1))


def run_step(name: str, folder: Path, src: str | None) -> tuple[float, float, float]:
    """(wall seconds, CPU seconds, peak MB) of one step in a fresh process (``src``: the package's
    sources to put first on the path, None for the one installed here)."""
    code = "import sys, time\n" + (f"sys.path.insert(0, {src!r})\n" if src else "")
    clocks = "(time.perf_counter(), time.process_time())"
    body = textwrap.dedent(STEPS[name]).replace("time.perf_counter()", clocks)
    body = body.replace(f"seconds = {clocks} - t", f"now = {clocks}; seconds = now[0] - t[0]; cpu = now[1] - t[1]")
    for key, file in (("MODEL", "model.yaml"), ("DATA", "data.csv"), ("POINTS", "points.csv"),
                      ("JOINTS", "joints.csv"), ("ROWS", "rows.csv")):
        body = body.replace(key, repr(str(folder / file)))
    code += body.replace("OUT", repr(str(folder / "run"))) + f"\nprint(seconds, cpu, {HWM})\n"
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    if p.returncode != 0:
        raise SystemExit(f"{name}: {p.stderr.strip().splitlines()[-1]}")
    seconds, cpu, peak = p.stdout.split()[-3:]
    return float(seconds), float(cpu), float(peak)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--poses", default="10000,100000,1000000")
    ap.add_argument("--baseline", default=None, help="a commit to compare with (git archive of its src)")
    ap.add_argument("--baseline-poses", type=int, default=100_000)
    args = ap.parse_args(argv)
    print(f"# command line end to end, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, load average "
          f"{os.getloadavg()[0]:.1f}, robocal {rc.__version__}" + (f", baseline {args.baseline}" if args.baseline
                                                                     else ""))
    print(f"{'poses':>9} {'package':>9} {'step':>18} {'seconds':>8} {'CPU s':>8} {'peak MB':>8} {'rows/s':>10}",
          flush=True)
    model = arm6r(False)
    with tempfile.TemporaryDirectory(prefix="robocal-bench-io-base-") as base:
        packages: list[tuple[str, str | None]] = [("now", None)]
        if args.baseline:
            root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
            archive = subprocess.run(["git", "-C", root, "archive", args.baseline, "src"], capture_output=True,
                                     check=True).stdout
            subprocess.run(["tar", "-x", "-C", base], input=archive, check=True)
            packages.append((args.baseline, os.path.join(base, "src")))
        for n in (int(v) for v in args.poses.split(",")):
            with tempfile.TemporaryDirectory(prefix="robocal-bench-io-") as d:
                folder = Path(d)
                rc.write_model(model, folder / "model.yaml")
                tracker_file(model, n, folder)
                size = (folder / "data.csv").stat().st_size / 2 ** 20
                print(f"{n:>9,} {'':>9} {'file':>18} {'':>8} {'':>8} {size:>8.0f} MB", flush=True)
                for name in STEPS:
                    for label, src in packages:
                        if n > args.baseline_poses and (name == "read (rows)" or (
                                src is not None and not name.startswith("robocal"))):
                            continue  # beyond it the baseline runs the two commands only
                        seconds, cpu, peak = run_step(name, folder, src)
                        rate = f"{n / seconds:,.0f}" if name.startswith("read") else ""
                        print(f"{n:>9,} {label:>9} {name:>18} {seconds:>8.2f} {cpu:>8.2f} {peak:>8.0f} {rate:>10}",
                              flush=True)


if __name__ == "__main__":
    main()
