"""How often the verdict warns or fails on clean campaigns, and whether it ever fails an elastic robot
it places better: real subsets and simulated robots with effects beyond the model.

Run: python benchmarks/judgement_corpus.py [--subsets 25] [--simulated 50] [--elastic 10]

* ``--subsets`` random subsets (60 to 400 poses, geometric) of each of the published UR5 and WAM grids
  (tests/data/real), calibrated as a user would (no option);
* ``--simulated`` campaigns of simulated robots with effects beyond the model (elasticity and
  bending, gear errors, thermal drift, a cable arm's scatter, repeatability), 60 to 300 random poses,
  a tracker's noise, calibrated geometric (and geometric plus compliance where the robot has masses);
* ``--elastic`` campaigns of a humanoid-like elastic robot (two 7-joint arms on a torso, joints that
  deflect several degrees under gravity) calibrated with compliance: how often the verdict fails a
  calibration that improves the accuracy in use (it must never).

For each it prints the share that warns and fails, the checks behind them, and the campaigns where a
point was set aside as a blunder (the clean campaigns hold none).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings
from collections import Counter

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests"))

import real_campaigns as real  # noqa: E402
from robots import beyond_model, humanoid  # noqa: E402

import robocal as rc  # noqa: E402
from robocal.sim import RobotImperfections, measure_campaign  # noqa: E402


def _calibrate(model, data, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return rc.calibrate(model, data, **kw)


def _record(tally: dict, name: str, res) -> None:
    bad = [c.name for c in res.checks if c.status != "pass"]
    tally["n"] += 1
    tally[res.verdict] += 1
    tally["checks"].update(bad)
    if any("set aside" in n for n in res.notes):
        tally["aside"].append(name)
    if res.verdict == "fail":
        tally["failed"].append((name, [c.summary[:160] for c in res.checks if c.status == "fail"]))


def _tally() -> dict:
    return {"n": 0, "pass": 0, "warn": 0, "fail": 0, "checks": Counter(), "aside": [], "failed": []}


def real_subsets(n: int, seed: int) -> dict:
    rng = np.random.default_rng(seed)
    tally = _tally()
    for robot, k, model, subset in real.subsets(n, rng):
        _record(tally, f"{robot} subset {k} ({subset.n_poses} poses)", _calibrate(model, subset))
    return tally


def simulated(n: int, seed: int) -> dict:
    tally = _tally()
    for name, preset, k, nominal, data in beyond_model(n, np.random.default_rng(seed)):
        families = ("geometric", "compliance") if preset in ("elastic", "cable") else ("geometric",)
        _record(tally, f"{name} {preset} #{k} ({data.n_poses} poses, {'+'.join(families)})",
                _calibrate(nominal, data, parameters=families))
    return tally


def elastic_humanoid(n: int, seed: int) -> tuple[dict, int]:
    """Calibrations with compliance of a humanoid whose joints deflect several degrees; returns the
    tally and how many failed although they improved the accuracy in use."""
    rng = np.random.default_rng(seed)
    nominal = humanoid()
    robot = RobotImperfections(elasticity=4e-4, load_scale=1e9, repeatability_sigma=1e-4, instrument_noise=2e-4)
    tally, wrong = _tally(), 0
    for k in range(n):
        true = rc.perturb_model(nominal, rc.identifiability(nominal).identified, rng=int(rng.integers(1 << 30)))
        q = rc.random_configurations(nominal, 500, rng=int(rng.integers(1 << 30)))
        data = measure_campaign(true, q, robot, rng=int(rng.integers(1 << 30)), robot_seed=k)
        res = _calibrate(nominal, data, parameters=("geometric", "compliance"), noise="camera")
        _record(tally, f"humanoid #{k}", res)
        gain, se = res.in_use.improvement
        wrong += int(res.verdict == "fail" and gain > se)
    return tally, wrong


def _print(title: str, tally: dict) -> None:
    n = max(tally["n"], 1)
    share = {k: f"{tally[k]} ({100 * tally[k] / n:.0f} %)" for k in ("warn", "fail")}
    print(f"{title}: {tally['n']} campaigns, pass {tally['pass']}, warn {share['warn']}, fail {share['fail']}")
    for name, count in tally["checks"].most_common():
        print(f"  {name}: {count}")
    for name in tally["aside"]:
        print(f"  points set aside as blunders: {name}")
    for name, why in tally["failed"]:
        print(f"  failed: {name}: {why}")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--subsets", type=int, default=25, help="random subsets of each real grid (default 25)")
    ap.add_argument("--simulated", type=int, default=50, help="simulated campaigns (default 50)")
    ap.add_argument("--elastic", type=int, default=10, help="elastic humanoid campaigns (default 10)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    print(f"# judgement corpus, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, seed {args.seed}")
    if args.subsets:
        _print("real UR5 and WAM subsets", real_subsets(args.subsets, args.seed))
    if args.simulated:
        _print("simulated robots with effects beyond the model", simulated(args.simulated, args.seed))
    if args.elastic:
        tally, wrong = elastic_humanoid(args.elastic, args.seed)
        _print("elastic humanoid, with compliance", tally)
        print(f"  failed although better in use: {wrong}")


if __name__ == "__main__":
    main()
