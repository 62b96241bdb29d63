"""Forward kinematics in any process: fresh ones and a long-lived one busy with other work, against an earlier commit.

Run: python benchmarks/bench_fk_processes.py [--baseline 7fe2faf] [--processes 10] [--repeat 10] [--rounds 24]
     [--fk-poses 100000]

Forward kinematics (``rc.forward_kinematics``, positions and orientations) of the 6-joint arm of
``bench_identify.py`` at ``--fk-poses`` poses, three sets of readings in turn, timed in CPU time
(``process_time``) by the package at ``--baseline`` (``git archive`` into a temporary folder, first on
``sys.path``) and by this one, each in a child process of its own. The two children of a pair run
side by side and take turns call by call (the one called first alternating), so that both see the
same moment of a shared machine's load; the ratio of a pair is that of the medians of its calls.

* **fresh processes**: ``--processes`` pairs of new processes; in each, three untimed calls, then
  ``--repeat`` timed ones;
* **a long-lived process mixed with other work**: one pair runs ``--rounds`` rounds; in each round
  both first do the same other work (drawn from one seed): a calibration at 1,000 or 10,000 poses,
  an HTML report every sixth round when matplotlib is there, arrays of 64 kB to 64 MB written and
  freed, some kept for later rounds; then one timed call each.

The C allocator keeps or returns freed memory by thresholds that what the process did before sets:
memory a call takes and gives back each time is faulted in again (a page fault a 4 kB page) when the
allocator returned it to the system, and not when it kept it. The page faults (minor) per timed call
show which. The two packages' positions are checked to agree to 1e-12 m.
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


def child(args) -> None:
    """Serve the parent's requests, one a line: ``fk`` (a timed call: its CPU time and page faults
    as JSON), ``work K`` (round K's other work), ``save`` (the positions at the first readings)."""
    import warnings
    warnings.simplefilter("ignore")
    m = arm6r(False)
    qs = [rc.random_configurations(m, args.fk_poses, rng=k) for k in range(3)]
    data: dict = {}
    rng, kept, turn = np.random.default_rng(0), [], 0
    print("ready", flush=True)
    for line in sys.stdin:
        what = line.split()
        if what[0] == "fk":
            f, c = faults(), time.process_time()
            rc.forward_kinematics(m, qs[turn % 3])
            print(json.dumps([time.process_time() - c, faults() - f]), flush=True)
            turn += 1
        elif what[0] == "work":
            data = data or {n: rc.simulate(m, n, seed=1)[1] for n in (1000, 10_000)}
            other_work(m, data, rng, kept, int(what[1]))
            print("done", flush=True)
        else:
            np.save(os.path.join(args.folder, "fk.npy"), rc.forward_kinematics(m, qs[0]).positions)
            print("saved", flush=True)


class Child:
    """A child process of the package in ``src`` (None: this one), answering requests."""

    def __init__(self, src: str | None, args, folder: str):
        env = dict(os.environ)
        if src is not None:
            env["PYTHONPATH"] = os.pathsep.join([src, env.get("PYTHONPATH", "")])
        cmd = [sys.executable, os.path.abspath(__file__), "--child", "1", "--fk-poses", str(args.fk_poses),
               "--folder", folder]
        self.proc = subprocess.Popen(cmd, env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        self.ask(None)

    def ask(self, request: str | None) -> str:
        assert self.proc.stdin is not None and self.proc.stdout is not None
        if request is not None:
            self.proc.stdin.write(request + "\n")
            self.proc.stdin.flush()
        answer = self.proc.stdout.readline()
        if not answer:
            raise RuntimeError(f"the child stopped (exit {self.proc.wait()})")
        return answer

    def close(self) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.close()
        self.proc.wait()


def paired(children: dict, calls: int, work: bool) -> dict:
    """``calls`` timed calls of each child, taking turns (with ``work``: each round's other work
    first); per child the CPU times and page faults of its calls."""
    found: dict = {label: [] for label in children}
    order = list(children)
    for k in range(calls):
        if work:
            for label in order:
                children[label].ask(f"work {k}")
        for label in order[::1 if k % 2 == 0 else -1]:
            found[label].append(json.loads(children[label].ask("fk")))
    return found


def row(name: str, found: dict) -> tuple[str, float]:
    cpu = {label: [c for c, _ in calls] for label, calls in found.items()}
    best = {label: min(v) for label, v in cpu.items()}
    med = {label: statistics.median(v) for label, v in cpu.items()}
    fl = {label: statistics.mean(f for _, f in calls) for label, calls in found.items()}
    ratio = med["now"] / med["base"]
    line = (f"| {name} | {best['base'] * 1e3:.1f} | {best['now'] * 1e3:.1f} | {best['now'] / best['base']:.2f}x | "
            f"{med['base'] * 1e3:.1f} | {med['now'] * 1e3:.1f} | {ratio:.2f}x | {fl['base']:.0f} | {fl['now']:.0f} |")
    return line, ratio


def main(argv=None):
    args = options(__doc__, argv, baseline="7fe2faf", processes=10, repeat=10, rounds=24, fk_poses=100_000,
                   child=0, folder="")
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
        for k in range(args.processes + 1):
            fresh = k < args.processes
            children = {label: Child(path, args, folders[label])
                        for label, path in (("base", src), ("now", None))[::1 if k % 2 == 0 else -1]}
            if fresh:
                for _ in range(3):
                    for c in children.values():
                        c.ask("fk")
            found = paired(children, args.repeat if fresh else args.rounds, work=not fresh)
            line, ratio = row(f"fresh #{k + 1}" if fresh else f"long-lived, {args.rounds} rounds of other work", found)
            print(line, flush=True)
            ratios += [ratio] if fresh else []
            for c in children.values():
                c.ask("save")
                c.close()
        a, b = (np.load(os.path.join(folders[label], "fk.npy")) for label in ("base", "now"))
        assert np.abs(a - b).max() <= 1e-12, np.abs(a - b).max()
    print(f"\nfresh processes, ratio of medians: worst {max(ratios):.2f}x, median {statistics.median(ratios):.2f}x; "
          f"load average after: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
