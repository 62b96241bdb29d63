"""Run many malformed inputs through every command and count how each run ended.

    python benchmarks/fuzz_cli.py --cases 20000 [--seed 0] [--jobs 2] [--in-process] [--show 3] [--keep DIR]
                                   [--commands a,b] [--seconds S]

Cases come from the hypothesis strategies in tests/fuzz_cases.py, one per command of its COMMANDS
table (model files, measurement, repeatability, target and contact CSVs, folders of seatings, robot programs, stores,
result files and their per-pose sidecars, profiles, limit files, DH tables, URDFs, command lines;
devices, FIFOs, pipes, sockets and folders in any input slot, read-only folders and inputs, programs
compensated with other tools and work objects than their motions).
Each runs ``robocal.cli.main(argv)`` in a forked child, in a folder of its own, under a limit of
20 s of CPU time (wall-clock time on a shared machine is not the program's; a 120 s wall-clock
backstop too) and 1 GB of memory (on top of the address space the parent already holds); with
--in-process, in this process under the same limits as guards (a CPU-time signal, a soft
address-space limit), a case that ends badly run again in a forked child and that outcome
counted. Outcomes (fuzz_cases.OUTCOMES): clean error, ok result, traceback, hang, over-memory,
non-finite output, unreadable output (an output robocal's own reader refuses), wrong output (an
output that does not reproduce its source: an export's forward kinematics, planned poses or 'ok'
commands beyond the joint limits, a program compensated against its own model whose targets
moved), multi-line error, written beside a failure (a failed command left a file, changed an
input or a store); in total and per command. A few examples of each bad outcome are
printed with the command line and the last lines of stderr.
"""

from __future__ import annotations

import argparse
import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import collections  # noqa: E402
import importlib.util  # noqa: E402
import pkgutil  # noqa: E402
import shutil  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import fuzz_cases  # noqa: E402
from hypothesis import HealthCheck, Phase, given, settings  # noqa: E402

import robocal  # noqa: E402,F401
import robocal.report  # noqa: E402,F401

# every module imported once here, not in every child (and not from files edited during a run)
for _m in pkgutil.walk_packages(importlib.util.find_spec("robocal").submodule_search_locations, "robocal."):
    if not _m.name.endswith(".__main__"):
        importlib.import_module(_m.name)


class Runner:
    def __init__(self, show: int, keep: Path | None, jobs: int):
        self.keep, self.jobs, self.running, self.started = keep, jobs, {}, 0
        self.counts = collections.Counter()
        self.by_command: dict[str, collections.Counter] = collections.defaultdict(collections.Counter)
        self.examples = collections.defaultdict(list)
        self.show = show
        self.times = []
        self.root = Path(tempfile.mkdtemp(prefix="robocal-fuzz-"))

    def run(self, command: str, files: dict, argv: list[str]) -> None:
        """Start one case; with ``jobs`` cases running, first wait for one to finish."""
        while len(self.running) >= self.jobs:
            self.reap()
        self.started += 1
        folder = self.root / f"case{self.started}"
        folder.mkdir()
        made = fuzz_cases.Materialised(folder, files, argv)
        pid = fuzz_cases.fork_case(folder, made.argv)
        self.running[pid] = (folder, time.monotonic(), argv, files, command, made)

    def run_here(self, command: str, files: dict, argv: list[str]) -> None:
        """Run one case in this process (fuzz_cases.run_guarded); one that ends badly runs again in a
        forked child, under the operating system's limits, and that outcome is counted."""
        start = time.monotonic()
        outcome, err = fuzz_cases.run_guarded(files, argv)
        if outcome not in ("clean error", "ok result"):
            outcome, err = fuzz_cases.run_forked(files, argv)
        self.times.append(time.monotonic() - start)
        self.tally(command, outcome, files, argv, err)

    def reap(self) -> None:
        """Wait until one running case ends (or overruns the wall-clock backstop) and count it."""
        while True:
            for pid, (_folder, start, *_) in list(self.running.items()):
                ended = fuzz_cases.poll_case(pid, start)
                if ended:
                    return self.count(pid, *ended)
            time.sleep(0.005)

    def count(self, pid, status, usage, killed) -> None:
        folder, start, argv, files, command, made = self.running.pop(pid)
        self.times.append(time.monotonic() - start)
        changed = made.close()
        outcome, err = fuzz_cases.forked_outcome(status, usage, killed, folder, files, argv, changed)
        self.tally(command, outcome, files, argv, err)
        shutil.rmtree(folder, ignore_errors=True)

    def tally(self, command, outcome, files, argv, err) -> None:
        """Count one outcome; keep and show a few bad ones."""
        self.counts[outcome] += 1
        self.by_command[command][outcome] += 1
        if outcome not in ("clean error", "ok result") and len(self.examples[outcome]) < self.show:
            self.examples[outcome].append((argv, fuzz_cases.preview(files, 300), err[-1500:]))
        if self.keep and outcome not in ("clean error", "ok result"):
            kept = self.keep / f"{outcome.replace(' ', '-')}-{sum(self.counts.values())}"
            fuzz_cases.keep_case(kept, files, argv, err)
        n = sum(self.counts.values())
        if n % 100 == 0:
            print(f"{n} cases: {dict(self.counts)}", file=sys.stderr, flush=True)


def base_result() -> tuple[str, str]:
    """Real result.json files (measured points, contacts), the seeds of the result-file cases."""
    folder = Path(tempfile.mkdtemp(prefix="robocal-fuzz-base-"))
    texts = fuzz_cases.base_results(folder)
    shutil.rmtree(folder)
    return texts


class _TimeUp(Exception):
    """--seconds have passed: start no more cases."""


def main_fuzz(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cases", type=int, default=10_000)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--jobs", type=int, default=2, help="cases run at once")
    p.add_argument("--show", type=int, default=3, help="examples printed per bad outcome")
    p.add_argument("--seconds", type=float, help="start no case after this many seconds (the summary counts the "
                                                 "cases run; for a shared machine's time slot)")
    p.add_argument("--commands", help="only these commands of tests/fuzz_cases.py's COMMANDS (comma-separated; "
                                      "default every one)")
    p.add_argument("--in-process", action="store_true",
                   help="run each case in this process under a CPU-time and a memory guard (about twice as many "
                        "cases a second), a case that ends badly run again in a forked child, whose outcome counts")
    p.add_argument("--keep", type=Path, help="copy the folder of every bad case here (argv.txt holds its command)")
    args = p.parse_args(argv)
    import random

    runner = Runner(args.show, args.keep, args.jobs)
    if args.keep:
        args.keep.mkdir(parents=True, exist_ok=True)
    result_text = base_result()
    fuzz_cases.install_guard()

    @settings(max_examples=args.cases, database=None, deadline=None, phases=[Phase.generate],
              suppress_health_check=list(HealthCheck))
    @given(fuzz_cases.case(result_text, args.commands.split(",") if args.commands else None))
    def each(c):
        if args.seconds is not None and time.monotonic() - t0 > args.seconds:
            raise _TimeUp
        if args.in_process:
            runner.run_here(*c)
        else:
            runner.run(*c)

    random.seed(args.seed)
    t0 = time.monotonic()
    each._hypothesis_internal_use_seed = args.seed
    try:
        each()
    except _TimeUp:
        print(f"time up after {args.seconds:.0f} s: stopped starting cases", file=sys.stderr)
    while runner.running:
        runner.reap()
    wall = time.monotonic() - t0
    n = sum(runner.counts.values())
    times = sorted(runner.times)
    for outcome, examples in runner.examples.items():
        for argv_, files, err in examples:
            print(f"--- {outcome}: robocal {' '.join(a[:80] for a in argv_)}\n    files: "
                  f"{ {k: v[:120] for k, v in files.items()} }\n{err}")
    print(f"\n{n} cases in {wall:.0f} s (median {times[n // 2]:.2f} s, slowest {times[-1]:.1f} s per case)")
    for outcome in fuzz_cases.OUTCOMES:
        print(f"  {outcome:18s} {runner.counts.get(outcome, 0)}")
    print("\nper command (cases: " + ", ".join(fuzz_cases.OUTCOMES) + ")")
    for command, counts in sorted(runner.by_command.items()):
        row = " ".join(str(counts.get(o, 0)) for o in fuzz_cases.OUTCOMES)
        print(f"  {command:18s} {sum(counts.values()):6d}: {row}")
    shutil.rmtree(runner.root, ignore_errors=True)
    bad = sum(runner.counts.get(o, 0) for o in fuzz_cases.OUTCOMES[2:])
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main_fuzz())
