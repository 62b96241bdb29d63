"""Time calibrate() and forward kinematics against the package at an earlier commit, in one run.

Run: python benchmarks/bench_engine.py [--repeat 10] [--baseline 7fe2faf] [--other REV] [--fk-poses 100000]

The configurations take turns, twice, each in its own child process: the package at
``--baseline`` (``git archive`` into a temporary folder, put first on ``sys.path``); the package
at ``--other`` when given (the same way: for instance the commit before a change, to measure the
change); this one; and this one in a process whose C allocator was first tuned as the baseline
tuned it on its first call (a 31 MB block allocated and freed: glibc then keeps freed memory for
reuse), which shows what that process-wide change would still add. Figures, on the 6-joint arm of
``bench_identify.py``:

* ``calibrate()`` at 1,000 and 10,000 poses (``rc.simulate(m, n, seed=1)``, geometric), best of
  ``--repeat`` (a fifth of it at 10,000) after three untimed calls;
* forward kinematics at ``--fk-poses`` poses (``rc.forward_kinematics``, positions and
  orientations), three sets of readings in turn, best of ``--repeat``.

Each figure is given as wall-clock time and as CPU time (``process_time``: this process' user and
system time, page faults included), the best of each; on a shared machine the CPU time is the one
other processes disturb least. Each child also saves the calibrated parameters and the positions,
and the parent checks that every package gives the same (1e-9 of the largest parameter, 1e-12 m).
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from bench_identify import arm6r, options  # noqa: E402
from bench_kinematics import baseline_sources, child_figures, heading  # noqa: E402

import robocal as rc  # noqa: E402

POSES = (1000, 10_000)
# what the baseline freed at its first call to retune glibc's allocator
PRIMER_BYTES = 31 << 20


def best(fn, repeat: int) -> tuple[float, float]:
    """Best wall-clock and best CPU time of ``repeat`` calls, after three untimed ones."""
    fn(), fn(), fn()
    wall, cpu = [], []
    for _ in range(repeat):
        t, c = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    return min(wall), min(cpu)


def child(repeat: int, fk_poses: int, folder: str, variant: str) -> None:
    """This process' figures as JSON on stdout (the package first on ``sys.path`` is timed)."""
    if variant == "tuned":
        np.empty(PRIMER_BYTES, dtype=np.uint8)
    m = arm6r(False)
    out, saved = {}, {}
    for n in POSES:
        _, data = rc.simulate(m, n, seed=1)
        rep = repeat if n <= 1000 else max(3, repeat // 5)
        out[f"calibrate {n}"] = best(lambda data=data: rc.calibrate(m, data), rep)
        saved[f"p{n}"] = [e.estimate for e in rc.calibrate(m, data).parameters]
    qs = [rc.random_configurations(m, fk_poses, rng=k) for k in range(3)]
    turn = iter(range(10 ** 6))
    out["forward kinematics"] = best(lambda: rc.forward_kinematics(m, qs[next(turn) % 3]), repeat)
    saved["fk"] = rc.forward_kinematics(m, qs[0]).positions
    np.savez(os.path.join(folder, "out.npz"), **saved)
    print(json.dumps(out))


def agree(a: str, b: str) -> None:
    with np.load(a) as x, np.load(b) as y:
        for n in POSES:
            k = f"p{n}"
            assert np.abs(x[k] - y[k]).max() <= 1e-9 * np.abs(y[k]).max(), k
        assert np.abs(x["fk"] - y["fk"]).max() <= 1e-12


def main(argv=None):
    args = options(__doc__, argv, repeat=10, baseline="7fe2faf", other="", fk_poses=100_000, child=0, folder="",
                   variant="")
    if args.child:
        return child(args.repeat, args.fk_poses, args.folder, args.variant)
    print(heading("calibrate() and forward kinematics", args.baseline, args.repeat))
    revs = [args.baseline] + ([args.other] if args.other else [])
    labels = tuple(revs) + ("now", "now, allocator tuned first")
    with tempfile.TemporaryDirectory() as tmp:
        sources = {}
        for rev in revs:
            os.mkdir(os.path.join(tmp, rev))
            sources[rev] = baseline_sources(rev, os.path.join(tmp, rev))
        dirs = {label: os.path.join(tmp, f"run{i}") for i, label in enumerate(labels)}
        for d in dirs.values():
            os.mkdir(d)
        found: dict = {label: {} for label in labels}
        for _ in range(2):
            for label in labels:
                variant = "tuned" if label.endswith("tuned first") else ""
                figures = child_figures(__file__, sources.get(label), "--repeat", args.repeat, "--fk-poses",
                                        args.fk_poses, "--folder", dirs[label], "--variant", variant)
                for key, t in figures.items():
                    for clock, v in zip(("wall", "cpu"), t):
                        found[label][(key, clock)] = min(found[label].get((key, clock), np.inf), v)
        for label in labels[1:]:
            agree(os.path.join(dirs[label], "out.npz"), os.path.join(dirs[labels[0]], "out.npz"))
    print("| figure | clock | " + " | ".join(f"{label} (ms)" for label in labels) + " | "
          + " | ".join(f"{label} / {labels[0]}" for label in labels[1:]) + " |")
    print("|---" * (2 * len(labels) + 1) + "|")
    for key, clock in found[labels[0]]:
        name = f"forward kinematics, {args.fk_poses} poses" if key == "forward kinematics" else f"{key} poses"
        t = [found[label][(key, clock)] for label in labels]
        print(f"| {name} | {clock} | " + " | ".join(f"{v * 1e3:.2f}" for v in t) + " | "
              + " | ".join(f"{v / t[0]:.2f}x" for v in t[1:]) + " |")
    print(f"\nload average after: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
