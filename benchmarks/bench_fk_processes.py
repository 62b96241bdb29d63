"""Forward kinematics in any process: fresh ones and a long-lived one busy with other work, against an earlier commit.

Run: python benchmarks/bench_fk_processes.py [--baseline 7fe2faf] [--processes 10] [--repeat 10] [--rounds 24]
     [--fk-poses 100000]

Forward kinematics (``rc.forward_kinematics``, positions and orientations) of the 6-joint arm of
``bench_identify.py`` at ``--fk-poses`` poses, three sets of readings in turn, timed in CPU time
(``process_time``) by the package at ``--baseline`` (``git archive`` into a temporary folder, first on
``sys.path``) and by this one, each in child processes of its own:

* **fresh processes**: ``--processes`` pairs of new processes, the two packages taking turns (the
  baseline first in every other pair); in each, three untimed calls, then the best and the median of
  ``--repeat`` timed ones, and the page faults (minor) per timed call;
* **a long-lived process mixed with other work**: one process per package runs ``--rounds`` rounds;
  each does other work first, the same for both packages (drawn from one seed): calibrations at
  1,000 and 10,000 poses, an HTML report when matplotlib is there, arrays of 64 kB to 64 MB written
  and freed, some kept for later rounds; then one timed call. Its best and median over the rounds.

The C allocator keeps or returns freed memory by thresholds that what the process did before sets:
memory a call takes and gives back each time is faulted in again (a page fault a 4 kB page) when the
allocator returned it to the system, and not when it kept it. The faults per call show which. The
two packages' positions are checked to agree to 1e-12 m.
"""

from __future__ import annotations

import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from bench_identify import arm6r, options  # noqa: E402
from bench_kinematics import baseline_sources  # noqa: E402

import robocal as rc  # noqa: E402


def faults() -> int:
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt


def timed(fn) -> tuple[float, int]:
    """CPU time and minor page faults of one call."""
    f, c = faults(), time.process_time()
    fn()
    return time.process_time() - c, faults() - f


def summary(calls: list) -> dict:
    cpu = [c for c, _ in calls]
    return {"best": min(cpu), "median": statistics.median(cpu), "faults": statistics.mean(f for _, f in calls)}


def fresh(m, qs, repeat: int) -> dict:
    turn = iter(range(10 ** 6))

    def fk():
        return rc.forward_kinematics(m, qs[next(turn) % 3])
    for _ in range(3):
        fk()
    return summary([timed(fk) for _ in range(repeat)])


def other_work(m, data: dict, rng, kept: list, k: int) -> None:
    """One round's work besides the timed call: a calibration, a report every sixth round, arrays."""
    res = rc.calibrate(m, data[1000 if k % 3 else 10_000])
    if k % 6 == 5:
        try:
            from robocal.report import render_report
            render_report(res)
        except ImportError:         # no report extra: the rest of the round still runs
            pass
    for _ in range(int(rng.integers(1, 5))):
        a = np.ones(int(np.exp(rng.uniform(np.log(64e3), np.log(64e6)))) // 8)
        if rng.random() < 0.3:
            kept.append(a)
        del a
    while len(kept) > 3:
        kept.pop(int(rng.integers(len(kept))))


def mixed(m, qs, rounds: int) -> dict:
    rng = np.random.default_rng(0)
    data = {n: rc.simulate(m, n, seed=1)[1] for n in (1000, 10_000)}
    kept: list = []
    calls = []
    for k in range(rounds):
        other_work(m, data, rng, kept, k)
        calls.append(timed(lambda k=k: rc.forward_kinematics(m, qs[k % 3])))
    return summary(calls)


def child(args) -> None:
    """This process' figures as JSON on stdout (the package first on ``sys.path`` is timed)."""
    import warnings
    warnings.simplefilter("ignore")
    m = arm6r(False)
    qs = [rc.random_configurations(m, args.fk_poses, rng=k) for k in range(3)]
    out = fresh(m, qs, args.repeat) if args.child == "fresh" else mixed(m, qs, args.rounds)
    np.save(os.path.join(args.folder, "fk.npy"), rc.forward_kinematics(m, qs[0]).positions)
    print(json.dumps(out))


def run(src: str | None, args, kind: str, folder: str) -> dict:
    env = dict(os.environ)
    if src is not None:
        env["PYTHONPATH"] = os.pathsep.join([src, env.get("PYTHONPATH", "")])
    cmd = [sys.executable, os.path.abspath(__file__), "--child", kind, "--repeat", str(args.repeat),
           "--rounds", str(args.rounds), "--fk-poses", str(args.fk_poses), "--folder", folder]
    return json.loads(subprocess.run(cmd, env=env, check=True, capture_output=True, text=True).stdout)


def row(name: str, base: dict, now: dict) -> str:
    return (f"| {name} | {base['best'] * 1e3:.1f} | {now['best'] * 1e3:.1f} | {now['best'] / base['best']:.2f}x | "
            f"{base['median'] * 1e3:.1f} | {now['median'] * 1e3:.1f} | {now['median'] / base['median']:.2f}x | "
            f"{base['faults']:.0f} | {now['faults']:.0f} |")


def main(argv=None):
    args = options(__doc__, argv, baseline="7fe2faf", processes=10, repeat=10, rounds=24, fk_poses=100_000,
                   child="", folder="")
    if args.child:
        return child(args)
    print(f"# forward kinematics at {args.fk_poses} poses in fresh and long-lived processes against {args.baseline}, "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {platform.machine()}, {os.cpu_count()} cores, "
          f"numpy {np.__version__}; CPU time; load average before {' '.join(f'{v:.2f}' for v in os.getloadavg())}\n")
    print(f"| process | {args.baseline} best (ms) | now best (ms) | ratio | {args.baseline} median (ms) | "
          f"now median (ms) | ratio | {args.baseline} faults per call | now faults per call |")
    print("|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        src = baseline_sources(args.baseline, tmp)
        folders = {label: os.path.join(tmp, label) for label in ("base", "now")}
        for d in folders.values():
            os.mkdir(d)
        ratios = []
        for k in range(args.processes):
            order = (("base", src), ("now", None))[::1 if k % 2 == 0 else -1]
            got = {label: run(path, args, "fresh", folders[label]) for label, path in order}
            ratios.append(got["now"]["median"] / got["base"]["median"])
            print(row(f"fresh #{k + 1}", got["base"], got["now"]), flush=True)
        got = {label: run(path, args, "mixed", folders[label]) for label, path in (("base", src), ("now", None))}
        print(row(f"long-lived, {args.rounds} rounds of other work", got["base"], got["now"]))
        a, b = (np.load(os.path.join(folders[label], "fk.npy")) for label in ("base", "now"))
        assert np.abs(a - b).max() <= 1e-12, np.abs(a - b).max()
    print(f"\nfresh processes, ratio of medians: worst {max(ratios):.2f}x, median {statistics.median(ratios):.2f}x; "
          f"load average after: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
