"""Where calibrate() spends its time, step by step, against the whole call of an earlier release.

Run: python benchmarks/bench_steps.py [--robot arm6r] [--poses 1000] [--repeat 20] [--baseline 7fe2faf] [--within 1.3]

``--robot arm6r``: the 6-joint arm of ``bench_identify.py``, ``rc.simulate(m, poses, seed=1)``,
geometric (as ``bench_engine.py``); ``--robot humanoid``: the 19-joint tree of ``tests/robots.py``
with a marker on each hand, geometric and compliance (as ``bench_humanoid.py``). BLAS on one thread.

Each step of the calibration (the functions its sequence calls, ``robocal._identification.calibrate.
run``, and the diagnosis screen after it) is wrapped to add up its own CPU time (``process_time``;
the steps it calls are counted apart), over ``--repeat`` calls after three untimed ones; "the rest"
is the whole call less every step. The steps fall into three groups:

* the fit as ``--baseline`` made it: preparing the data, the identifiability analysis, the first
  design's solve, outliers and weak parameters, the nominal's registration, the covariance, the
  estimates;
* the record and the checks' wording (the record, the input, fit, result and use checks);
* the evidence ``--baseline`` did not have: the cross-validations (the fit's and the nominal's), the
  model choice's other designs, the accuracy in use, the workspace (reach), the coverage and the
  diagnosis screen.

The package at ``--baseline`` runs the same calibration in a child process of its own (``git archive``
into a temporary folder, first on ``sys.path``), median CPU time of its calls; it and this one take
turns, twice, and each side's run with the lower median is kept (the timing of a step adds about a
microsecond to its call, some 0.05 ms to a call at most). The table gives each step's median per
call and, last, what a call within ``--within`` times the baseline's would leave for the evidence.
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from collections import defaultdict

import numpy as np
from threadpoolctl import threadpool_limits

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(os.path.dirname(HERE), "tests"))
from bench_identify import arm6r, options  # noqa: E402
from bench_kinematics import baseline_sources  # noqa: E402

import robocal as rc  # noqa: E402

FIT, RECORD, EVIDENCE = "the fit as the baseline made it", "the record and the checks' wording", \
    "evidence the baseline did not have"
# (module, function, label, group): the functions looked up where the calibration's steps call them
STEPS = (
    ("_identification.calibrate", "prepare", "prepare the data", FIT),
    ("_identification.calibrate", "analyse", "identifiability analysis", FIT),
    ("_identification.calibrate", "choose", "the first design's fit (solve, outliers, weak parameters)", FIT),
    ("_identification.calibrate", "registered_nominal", "the nominal's registration", FIT),
    ("_identification.calibrate", "covariance", "covariance", FIT),
    ("_identification.calibrate", "estimates", "estimates", FIT),
    ("_identification.calibrate", "record", "the record", RECORD),
    ("_identification.calibrate", "input_checks", "input checks", RECORD),
    ("_identification.calibrate", "fit_checks", "fit checks", RECORD),
    ("_identification.calibrate", "result_checks", "result checks", RECORD),
    ("_identification.calibrate", "use_checks", "use checks", RECORD),
    ("_identification.calibrate", "alone_check", "use checks", RECORD),
    ("_identification.calibrate", "placed_better", "use checks", RECORD),
    ("_identification.calibrate", "point_misfit", "use checks", RECORD),
    ("_identification.steps", "cross_validate", "the fits' cross-validations", EVIDENCE),
    ("_identification.steps", "_simplest", "the model choice's other designs", EVIDENCE),
    ("_identification.calibrate", "holdout_of", "the folds", EVIDENCE),
    ("_identification.calibrate", "in_use", "accuracy in use (the nominal's cross-validation apart)", EVIDENCE),
    ("_identification.judgement", "cross_validate", "the nominal's cross-validation", EVIDENCE),
    ("_identification.calibrate", "reach", "the workspace (reach)", EVIDENCE),
    ("_identification.calibrate", "campaign_coverage", "coverage", EVIDENCE),
    ("_diagnosis.calibrate", "screened", "the diagnosis screen", EVIDENCE),
)


def case(robot: str, poses: int):
    """The model, its simulated data and the calibration's keyword arguments."""
    if robot == "humanoid":
        from robots import humanoid
        m, families = humanoid(markers=("lhand", "rhand")), ("geometric", "compliance")
        return m, rc.simulate(m, poses, parameters=families, seed=1)[1], {"parameters": families}
    m = arm6r(False)
    return m, rc.simulate(m, poses, seed=1)[1], {}


def whole_calls(robot: str, poses: int, repeat: int) -> list[float]:
    """CPU time of each of ``repeat`` calls (after three untimed), the package first on ``sys.path``."""
    m, data, kw = case(robot, poses)
    out = []
    with threadpool_limits(limits=1, user_api="blas"):
        for k in range(repeat + 3):
            c = time.process_time()
            rc.calibrate(m, data, **kw)
            if k >= 3:
                out.append(time.process_time() - c)
    return out


class Ledger:
    """Each wrapped step's own CPU time per call (the steps it calls counted apart)."""

    def __init__(self):
        self.own: dict = defaultdict(float)
        self.inner: list = []

    def wrap(self, module, name: str, label: str) -> None:
        fn = getattr(module, name)

        def timed(*args, **kwargs):
            start = time.process_time()
            self.inner.append(0.0)
            try:
                return fn(*args, **kwargs)
            finally:
                spent = time.process_time() - start
                self.own[label] += spent - self.inner.pop()
                if self.inner:
                    self.inner[-1] += spent

        setattr(module, name, timed)


def stepped_calls(robot: str, poses: int, repeat: int) -> tuple[list[dict], list[float]]:
    """Each step's own time in each of ``repeat`` calls, and each call's whole time."""
    import importlib
    ledger = Ledger()
    for module, name, label, _ in STEPS:
        ledger.wrap(importlib.import_module(f"robocal.{module}"), name, label)
    m, data, kw = case(robot, poses)
    per_call, whole = [], []
    with threadpool_limits(limits=1, user_api="blas"):
        for k in range(repeat + 3):
            ledger.own.clear()
            c = time.process_time()
            rc.calibrate(m, data, **kw)
            if k >= 3:
                whole.append(time.process_time() - c)
                per_call.append(dict(ledger.own))
    return per_call, whole


def baseline_call(rev: str, robot: str, poses: int, repeat: int, folder: str) -> float:
    """The median CPU time of ``rev``'s calls, in a child process of its own."""
    path = os.pathsep.join([baseline_sources(rev, folder), os.environ.get("PYTHONPATH", "")])
    env = dict(os.environ, PYTHONPATH=path)
    cmd = [sys.executable, os.path.abspath(__file__), "--child", "1", "--robot", robot, "--poses", str(poses),
           "--repeat", str(repeat)]
    return float(np.median(json.loads(subprocess.run(cmd, env=env, check=True, capture_output=True,
                                                     text=True).stdout)))


def main(argv=None):
    args = options(__doc__, argv, robot="arm6r", poses=1000, repeat=20, baseline="7fe2faf", within=1.3, child=0)
    if args.child:
        print(json.dumps(whole_calls(args.robot, args.poses, args.repeat)))
        return
    print(f"# calibrate() step by step, {args.robot} at {args.poses} poses, against {args.baseline}; "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {platform.machine()}, {os.cpu_count()} cores, "
          f"numpy {np.__version__}, median of {args.repeat} calls; load average before "
          f"{' '.join(f'{v:.2f}' for v in os.getloadavg())}\n")
    runs, base = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(2):              # taking turns; each side's quieter run is kept
            base.append(baseline_call(args.baseline, args.robot, args.poses, args.repeat, tmp))
            runs.append(stepped_calls(args.robot, args.poses, args.repeat))
    per_call, whole = min(runs, key=lambda run: float(np.median(run[1])))
    median = {label: float(np.median([c.get(label, 0.0) for c in per_call])) for _, _, label, _ in STEPS}
    total = float(np.median(whole))
    rest = float(np.median([w - sum(c.values()) for c, w in zip(per_call, whole)]))
    group_of = {label: group for _, _, label, group in STEPS}
    print("| step | group | CPU ms per call | share |")
    print("|---|---|---|---|")
    for label, v in sorted(median.items(), key=lambda kv: -kv[1]):
        print(f"| {label} | {group_of[label]} | {v * 1e3:.2f} | {v / total:.0%} |")
    print(f"| the rest (the call's own glue) | {FIT} | {rest * 1e3:.2f} | {rest / total:.0%} |")
    sums = {g: sum(v for label, v in median.items() if group_of[label] == g) for g in (FIT, RECORD, EVIDENCE)}
    sums[FIT] += rest
    t_base = min(base)
    print(f"\nthe whole call: {total * 1e3:.2f} ms ({' and '.join(f'{float(np.median(w)) * 1e3:.2f}' for _, w in runs)}"
          f"); {args.baseline}: {t_base * 1e3:.2f} ms ({' and '.join(f'{b * 1e3:.2f}' for b in base)})")
    for g, v in sums.items():
        print(f"- {g}: {v * 1e3:.2f} ms ({v / t_base:.2f}x {args.baseline}'s whole call)")
    room = args.within * t_base - sums[FIT] - sums[RECORD]
    print(f"- a call within {args.within:g}x of {args.baseline} leaves {room * 1e3:.2f} ms for the evidence, "
          f"which costs {sums[EVIDENCE] * 1e3:.2f} ms")
    print(f"\nload average after: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
