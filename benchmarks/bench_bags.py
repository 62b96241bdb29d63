"""``robocal import-bag`` on an hour's recording, in each storage, with peak memory.

Run: python benchmarks/bench_bags.py [--hours 1] [--storage ros1,sqlite,mcap] [--folder /tmp/robocal-bags]

An hour of a TH8's campaign (tests/bag_campaign.py): the robot stands still 1 to 3 s at each of
about 1,100 poses and moves 0.8 to 1.6 s between them; its joint states at 250 Hz (about 900,000
messages), a tracker's PointStamped at 100 Hz with noise and 5 % dropouts on a clock 0.37 s ahead.
The bags are written once by the rosbags package's writers into ``--folder`` and reused.

For each storage, in a new process each: the whole command (``robocal import-bag``, from start to
exit: reading, still moments, writing the CSV), its wall-clock and CPU time (the process's user and
system time, which other jobs on a shared machine disturb least) and its peak memory
(``VmHWM``); then the baseline, what a conversion script does with the same library: every
message of the two topics deserialized by the rosbags reader (reading only: no still moments,
nothing written).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np

import robocal as rc

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))
from bag_campaign import recording, write_bag  # noqa: E402

BAGS = {"ros1": "hour.bag", "sqlite": "hour-sqlite", "mcap": "hour-mcap"}
# the peak is VmHWM, the process's own high-water mark: ru_maxrss would keep this parent's across the exec
TIMED = """
import re, sys, time
t = time.perf_counter()
{body}
peak = re.search(r"VmHWM:\\s*(\\d+) kB", open("/proc/self/status").read()).group(1)
print(time.perf_counter() - t, time.process_time(), int(peak) / 1024)
"""
COMMAND = """
from robocal.cli import main
code = main(sys.argv[1:])
assert code == 0, code
"""
BASELINE = """
from pathlib import Path
from rosbags.highlevel import AnyReader
with AnyReader([Path(sys.argv[1])]) as reader:
    wanted = [c for c in reader.connections if c.topic in ("/joint_states", "/tracker/point")]
    n = sum(1 for c, _, raw in reader.messages(connections=wanted) if reader.deserialize(raw, c.msgtype))
print(n, "messages", file=sys.stderr)
"""


def timed(body: str, *args) -> tuple[float, float, float, str]:
    """(wall s, CPU s, peak MB, what it printed) of ``body`` run in a new process with ``args``."""
    run = subprocess.run([sys.executable, "-c", TIMED.format(body=textwrap.dedent(body)), *map(str, args)],
                         capture_output=True, text=True, cwd=ROOT, env=dict(os.environ, PYTHONPATH=str(ROOT / "src")))
    if run.returncode:
        raise SystemExit(run.stderr)
    wall, cpu, peak = map(float, run.stdout.splitlines()[-1].split())
    return wall, cpu, peak, run.stdout + run.stderr


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--hours", type=float, default=1.0)
    ap.add_argument("--storage", default="ros1,sqlite,mcap")
    ap.add_argument("--folder", type=Path, default=Path("/tmp/robocal-bags"))
    args = ap.parse_args(argv)
    model = rc.read_model(ROOT / "examples" / "th8" / "model.yaml")
    true, _ = rc.simulate(model, 5, seed=11)
    n_poses = int(round(args.hours * 3600 / 3.2))         # 2 s still and 1.2 s moving, on average
    rec = recording(model, true, rc.random_configurations(model, n_poses, np.random.default_rng(0)), seed=1)
    print(f"{n_poses} poses over {rec.joint_t[-1] / 3600:.2f} h: {rec.joint_t.size} joint states, "
          f"{rec.tracker_t.size} tracker points")
    args.folder.mkdir(parents=True, exist_ok=True)
    for storage in args.storage.split(","):
        bag = args.folder / f"{args.hours:g}-{BAGS[storage]}"
        if not bag.exists():
            t = time.perf_counter()
            write_bag(bag, rec, storage=storage)
            print(f"{storage}: wrote {bag} in {time.perf_counter() - t:.0f} s")
        size = sum(f.stat().st_size for f in bag.rglob("*")) if bag.is_dir() else bag.stat().st_size
        out = args.folder / f"{storage}.csv"
        out.unlink(missing_ok=True)
        wall, cpu, peak, printed = timed(COMMAND, "import-bag", bag, "--model", "examples/th8/model.yaml",
                                         "--joints", "/joint_states", "--marker", "tool=/tracker/point",
                                         "--clock-offset", rec.clock_offset, "--out", out)
        found = rc.read_measurements(out, model).n_poses
        print(f"{storage} ({size / 1e6:.0f} MB): import-bag {wall:.1f} s wall, {cpu:.1f} s CPU, {peak:.0f} MB peak; "
              f"{found} of {n_poses} poses")
        wall, cpu, peak, printed = timed(BASELINE, bag)
        print(f"{storage}: baseline, every message deserialized {wall:.1f} s wall, {cpu:.1f} s CPU, "
              f"{peak:.0f} MB peak")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
