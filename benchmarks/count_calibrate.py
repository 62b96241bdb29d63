"""Instructions and cache misses per calibrate() against the package at an earlier commit.

Run: python benchmarks/count_calibrate.py [--baseline 7fe2faf] [--calls 5]   (needs valgrind)

Timings on a shared virtual machine scatter by a fifth from process to process, and the package's
share of that scatter depends on how much of the caches it needs; counts do not scatter. Each
figure is counted by valgrind's cachegrind (``--cache-sim=yes``; hash seed 0, one BLAS thread)
in a child process that prepares (imports, simulation, three untimed calls) and then makes
``--calls`` calls, minus the same child making none, divided by ``--calls``. The campaigns are
those of ``bench_engine.py`` (the 6-joint arm of ``bench_identify.py``, ``rc.simulate(m, n,
seed=1)``, default options) and ``bench_humanoid.py`` (the 19-joint tree, two markers, 500 poses,
geometric and compliance). The package at ``--baseline`` comes from ``git archive``.

Columns: instructions (``I refs``), first-level instruction-cache misses (``I1 misses``: the
interpreter and numpy running through more distinct code), first-level data-cache misses.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
CASES = ("6R, 1,000 poses", "6R, 10,000 poses", "humanoid, geometric and compliance")
COUNTS = ("I   refs", "I1  misses", "D1  misses")


def child(case: int, calls: int) -> None:
    """Prepare ``CASES[case]``, then make ``calls`` calibrations (the package first on sys.path)."""
    import warnings

    sys.path.insert(1, HERE)
    sys.path.insert(2, os.path.join(os.path.dirname(HERE), "tests"))
    import robocal as rc

    warnings.simplefilter("ignore")
    if case < 2:
        from bench_identify import arm6r
        m, kwargs = arm6r(False), {}
        _, data = rc.simulate(m, (1000, 10_000)[case], seed=1)
    else:
        from robots import humanoid
        fam = ("geometric", "compliance")
        m, kwargs = humanoid(markers=("lhand", "rhand")), {"parameters": fam}
        _, data = rc.simulate(m, 500, parameters=fam, seed=1)
    for _ in range(3):
        rc.calibrate(m, data, **kwargs)
    for _ in range(calls):
        rc.calibrate(m, data, **kwargs)


def counted(src: str, case: int, calls: int) -> dict[str, int]:
    """cachegrind's totals of a child with the package at ``src`` first on its path."""
    env = dict(os.environ, PYTHONHASHSEED="0", OPENBLAS_NUM_THREADS="1", PYTHONPATH=src)
    with tempfile.TemporaryDirectory() as tmp:
        out = subprocess.run(["valgrind", "--tool=cachegrind", "--cache-sim=yes",
                              f"--cachegrind-out-file={os.path.join(tmp, 'cg.out')}", sys.executable,
                              os.path.abspath(__file__), "--child", str(case), "--calls", str(calls)],
                             env=env, capture_output=True, text=True, check=True).stderr
    found = {}
    for key in COUNTS:
        m = re.search(re.escape(key) + r":\s+([\d,]+)", out)
        if m is None:
            raise SystemExit(f"no '{key}' in valgrind's output:\n{out[-2000:]}")
        found[key] = int(m.group(1).replace(",", ""))
    return found


def per_call(src: str, case: int, calls: int) -> dict[str, float]:
    none, some = counted(src, case, 0), counted(src, case, calls)
    return {k: (some[k] - none[k]) / calls for k in COUNTS}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", default="7fe2faf")
    ap.add_argument("--calls", type=int, default=5)
    ap.add_argument("--child", type=int, default=-1, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child >= 0:
        return child(args.child, args.calls)
    if shutil.which("valgrind") is None:
        raise SystemExit("count_calibrate.py needs valgrind (Debian: apt install valgrind)")
    sys.path.insert(0, HERE)
    from bench_kinematics import baseline_sources

    root = os.path.dirname(HERE)
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=root, capture_output=True, text=True,
                          check=True).stdout.strip()
    print(f"# calibrate() counted by cachegrind against {args.baseline}, this package at {head}, "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {args.calls} calls\n")
    print("| campaign | count | " + f"{args.baseline} (M) | now (M) | now / {args.baseline} |")
    print("|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as folder:
        base = baseline_sources(args.baseline, folder)
        for case, name in enumerate(CASES):
            b, n = per_call(base, case, args.calls), per_call(os.path.join(root, "src"), case, args.calls)
            for key in COUNTS:
                print(f"| {name} | {key.split()[0]} | {b[key] / 1e6:.1f} | {n[key] / 1e6:.1f} | "
                      f"{n[key] / b[key]:.2f}x |", flush=True)


if __name__ == "__main__":
    main()
