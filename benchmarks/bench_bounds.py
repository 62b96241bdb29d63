"""Every stated bound measured (issue 45): the worst case inside each bound, and what lies just
beyond it, run as the command a user runs, each in its own process.

    python benchmarks/bench_bounds.py                          # this tree
    git worktree add ../robocal-32a3abb 32a3abb
    python benchmarks/bench_bounds.py --baseline ../robocal-32a3abb   # and a checkout to compare, same run

Each case's CPU time (user + system) and peak memory (maximum resident set) from /usr/bin/time;
wall time only says how busy the machine was. A case still running after ``--timeout`` seconds is
killed and said so.
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import robocal as rc

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_programs import arm, module  # noqa: E402  (the 6R arm and RAPID module of that benchmark)

TH8 = ROOT / "examples" / "th8"
ARM7 = ROOT / "examples" / "arm7" / "model.yaml"
TH8_RESOLUTION = "0.01deg,0.1mm,0.12mm,0.005deg,0.002deg,0.002deg"


def run(tree: Path, argv: list[str], cwd: Path, timeout: float) -> str:
    """``robocal argv`` of ``tree``'s sources: "exit E, CPU C s, wall W s, peak M MB". Measured by
    /usr/bin/time, a small process: a child forked from this one would report this process's memory
    as its own floor (Linux carries the peak across exec)."""
    env = dict(os.environ, PYTHONPATH=str(tree / "src"))
    p = subprocess.Popen(["/usr/bin/time", "-f", "TIME %x %U %S %e %M", sys.executable, "-m", "robocal", *argv],
                         cwd=cwd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                         start_new_session=True)
    try:
        err = p.communicate(timeout=timeout)[1]
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)            # the timer and the command it runs
        p.communicate()
        return f"killed at the timeout ({timeout:.0f} s wall)"
    lines = err.strip().splitlines()
    code, user, system, wall, peak = lines[-1].split()[1:]
    said = [ln for ln in lines[:-1] if ln.startswith("robocal") and ": error: " in ln]
    last = f"; {said[-1][:160]}" if said else ""
    return (f"exit {code}, CPU {float(user) + float(system):.1f} s, wall {float(wall):.1f} s, "
            f"peak {int(peak) / 1024:.0f} MB{last}")


def files(d: Path) -> None:
    """The programs and the mixed contact campaign the cases read."""
    (d / "million.script").write_text("def p():\n" + "movej([0,0,0,0,0,0])\n" * 1_000_000 + "end\n")
    nominal = arm()
    rc.write_model(nominal, d / "arm.yaml")
    rc.write_model(rc.sim.perturb_model(nominal, rc.candidate_parameters(nominal, ("geometric",)), rng=1),
                   d / "arm-calibrated.yaml")
    (d / "bound.mod").write_text(module(nominal, 30_000, np.random.default_rng(0))[0])
    arm7 = rc.read_model(ARM7)
    true = rc.sim.perturb_model(arm7, rc.candidate_parameters(arm7, ("geometric",)), rng=3)
    rc.io.write_contacts(rc.sim.socket_campaign(true, placements=3, poses_per_socket=20, rng=7), d / "s.csv", arm7)
    rc.write_measurements(rc.measure(true, rc.random_configurations(arm7, 40, 1), rng=1), d / "t.csv", model=arm7)
    # joints j2 and j3 swapped in both files (their headers as they were)
    for name, first in (("s.csv", 4), ("t.csv", 1)):
        rows = (d / name).read_text().splitlines()
        for i, row in enumerate(rows):
            cells = row.split(",")
            if len(cells) > first + 2 and not row.startswith(("#", "placement", "pose,")):
                cells[first + 1], cells[first + 2] = cells[first + 2], cells[first + 1]
                rows[i] = ",".join(cells)
        (d / f"swapped-{name}").write_text("\n".join(rows) + "\n")


def cases() -> list[tuple[str, list[str], list[str] | None]]:
    """(what, argv of this tree, argv of the baseline or None for the same)."""
    limit = ["limit", str(TH8 / "model.yaml"), "--repeatability-mm", "0.3", "--encoder-resolution", TH8_RESOLUTION,
             "--length-quantum-mm", "0.1", "--angle-quantum-deg", "0.001", "--out", "limit.json", "--force"]
    return [
        ("plan-sockets, 1,000 placements x 1 seating per socket (3,000 seatings)",
         ["plan-sockets", str(ARM7), "--placements", "1000", "--poses-per-socket", "1"], None),
        ("plan-sockets, 20 placements x 83 seatings per socket (4,980 seatings)",
         ["plan-sockets", str(ARM7), "--placements", "20", "--poses-per-socket", "83"], None),
        ("plan-sockets, 50 placements x 8 seatings per socket (the analysis: 3,750 x 488^2 = 8.9e8)",
         ["plan-sockets", str(ARM7), "--placements", "50", "--poses-per-socket", "8"], None),
        ("plan-sockets, 3 placements x 555 seatings per socket (4,995 seatings)",
         ["plan-sockets", str(ARM7), "--placements", "3", "--poses-per-socket", "555"], None),
        ("limit, TH8, 10^7 samples (this tree's maximum; the baseline: 10^8, its maximum)",
         limit + ["--samples", "10000000"], limit + ["--samples", "100000000"]),
        ("compensate, a program of 1,000,000 URScript moves (21 MB)",
         ["compensate", "arm.yaml", "arm-calibrated.yaml", "million.script", "--out", "o.script", "--force"], None),
        ("compensate, a RAPID program of 30,000 targets (half Cartesian)",
         ["compensate", "arm.yaml", "arm-calibrated.yaml", "bound.mod", "--out", "o.mod", "--force"], None),
        ("calibrate, 40 tracker points and 189 socket rows, joints j2 and j3 swapped",
         ["calibrate", str(ARM7), "swapped-t.csv", "--contacts", "swapped-s.csv", "--out", "o", "--force"], None),
        ("the same, --loss soft_l1 --compare (four fits, each diagnosed)",
         ["calibrate", str(ARM7), "swapped-t.csv", "--contacts", "swapped-s.csv", "--out", "o", "--force",
          "--loss", "soft_l1", "--compare"], None),
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", type=Path, help="a checkout whose src/ runs the same cases")
    ap.add_argument("--timeout", type=float, default=300.0, help="seconds of wall time before a case is killed")
    ap.add_argument("--only", help="run the cases whose description holds this text")
    args = ap.parse_args()
    print(f"load average before: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; {time.strftime('%Y-%m-%d %H:%M')}")
    with tempfile.TemporaryDirectory() as d:
        files(Path(d))
        for what, argv, base in cases():
            if args.only and args.only not in what:
                continue
            print(what)
            print(f"  this tree: {run(ROOT, argv, Path(d), args.timeout)}")
            if args.baseline is not None:
                print(f"  baseline:  {run(args.baseline, base or argv, Path(d), args.timeout)}")
            sys.stdout.flush()


if __name__ == "__main__":
    main()
