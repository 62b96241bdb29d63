"""How often the verdict warns or fails on clean campaigns, and whether it ever fails an elastic robot
it places better: real subsets and simulated robots with effects beyond the model.

Run: python benchmarks/judgement_corpus.py [--subsets 25] [--simulated 50] [--elastic 10] [--combined 30]

* ``--subsets`` random subsets (60 to 400 poses, geometric) of each of the published UR5 and WAM grids
  (tests/data/real), calibrated as a user would (no option);
* ``--simulated`` campaigns of simulated robots with effects beyond the model (elasticity and
  bending, gear errors, thermal drift, a cable arm's scatter, repeatability), 60 to 300 random poses,
  a tracker's noise, calibrated geometric (and geometric plus compliance where the robot has masses);
* ``--elastic`` campaigns of a humanoid-like elastic robot (two 7-joint arms on a torso, joints that
  deflect several degrees under gravity) calibrated with compliance: how often the verdict fails a
  calibration that improves the accuracy in use (it must never);
* ``--combined`` campaigns of simulated robots (a 6R, a cylindrical and a 7-joint arm, with masses)
  with 2 to 4 effects beyond the model at once (encoder counts, repeatability, backlash held by
  friction, gear errors, elasticity and bending, thermal drift), a tracker's noise, 60 to 300 random
  poses, calibrated geometric, with compliance where the robot is elastic, and through ``compare``
  every third campaign; each verdict is held against the truth: where the calibrated and the
  registered nominal model place the robot at random configurations over its limits
  (``robocal.sim.placement_errors``). A false fail fails a model that places the robot better by a
  clear margin; a false pass passes one that places it worse, or whose stated accuracy in use is
  more than twice optimistic.

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
from dataclasses import dataclass

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests"))

import real_campaigns as real  # noqa: E402
from robots import beyond_model, combined_effects, humanoid  # noqa: E402

import robocal as rc  # noqa: E402
from robocal.sim import RobotImperfections, measure_campaign, placement_errors  # noqa: E402

# the truth: configurations drawn per model, a clear margin between two models' mean placement errors
# (this many standard errors of their paired difference, and this share of the nominal's), and how
# many times the stated accuracy in use the true error may be before the statement is false
TRUTH_POSES = 500
CLEAR_SIGMAS, CLEAR_SHARE = 3.0, 0.05
OPTIMISM_MAX = 2.0


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


@dataclass(frozen=True)
class Judged:
    """One calibration's verdict against the truth: ``truth`` "better", "worse" or "same" (the
    calibrated model's placement errors against the registered nominal's, by a clear margin), their
    means ``nominal`` and ``calibrated`` and the calibrated one's RMS ``true_rms`` (m); the stated
    accuracy in use, its mean ``stated`` and its RMS over the range of use ``stated_rms`` (m, nan
    without one); the checks that did not pass, (status, name, summary)."""

    label: str
    verdict: str
    truth: str
    nominal: float
    calibrated: float
    true_rms: float
    stated: float
    stated_rms: float
    checks: tuple

    @property
    def optimism(self) -> float:
        """How many times the stated accuracy in use the true error is, the worse of mean and RMS over
        the range of use (nan without a statement)."""
        return float(np.nanmax([self.calibrated / self.stated, self.true_rms / self.stated_rms]))

    @property
    def false_fail(self) -> bool:
        return self.verdict == "fail" and self.truth == "better"

    @property
    def false_pass(self) -> bool:
        return self.verdict == "pass" and (self.truth == "worse" or self.optimism > OPTIMISM_MAX)


def _truth(eb: np.ndarray, ea: np.ndarray) -> str:
    """"better", "worse" or "same": the calibrated model's placement errors ``ea`` against the
    nominal's ``eb`` at the same configurations, by a clear margin."""
    d = eb - ea
    margin = max(CLEAR_SIGMAS * float(d.std(ddof=1)) / np.sqrt(len(d)), CLEAR_SHARE * float(eb.mean()))
    return "better" if d.mean() > margin else "worse" if -d.mean() > margin else "same"


def _stated(res) -> tuple[float, float]:
    """The stated accuracy in use: its mean (m) and its RMS over the range of use (m), as the check
    "where the model holds" figures it (the parameters' uncertainty carried from the measured poses to
    the configurations of use); nan without one."""
    if res.in_use is None or not res.in_use.position_after.n:
        return float("nan"), float("nan")
    a, cover = res.in_use.position_after, res.coverage
    grown = 0.0 if cover is None else max(cover.uncertainty_workspace ** 2 - cover.uncertainty_measured ** 2, 0.0)
    return float(a.mean), float(np.sqrt(a.rms ** 2 + grown))


def _calibrations(nominal, data, effects, k: int) -> list:
    """(label, result) of each calibration a user would run on a campaign: geometric; with compliance
    where the robot is elastic; ``compare`` (with backlash where it has some) every third campaign."""
    out = [("geometric", _calibrate(nominal, data))]
    if "elasticity" in effects:
        out.append(("geometric+compliance", _calibrate(nominal, data, parameters=("geometric", "compliance"))))
    if k % 3 == 2:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            best = rc.compare(nominal, data, backlash="backlash" in effects).best
        kept = "+".join(dict.fromkeys("transmission" if "." in f else f for f in best.families))
        out.append((f"compare, kept {kept}", best))
    return out


def combined(n: int, seed: int) -> tuple[dict, list[Judged]]:
    """Calibrations of robots with several effects beyond the model at once, each held against the
    truth at the same random configurations: the tally and each one ``Judged``."""
    tally, judged = _tally(), []
    for name, effects, k, nominal, true, imp, data in combined_effects(n, np.random.default_rng(seed)):
        before = _calibrate(nominal, data, parameters=("base", "markers")).calibrated_model
        at = int(np.random.default_rng([seed, k]).integers(1 << 30))
        eb = placement_errors(true, before, imp, n=TRUTH_POSES, rng=at, robot_seed=k)
        for how, res in _calibrations(nominal, data, effects, k):
            label = f"{name} #{k} {'+'.join(effects)} ({data.n_poses} poses, {how})"
            _record(tally, label, res)
            ea = placement_errors(true, res.calibrated_model, imp, n=TRUTH_POSES, rng=at, robot_seed=k)
            judged.append(Judged(label, res.verdict, _truth(eb, ea), float(eb.mean()), float(ea.mean()),
                                 float(np.sqrt(np.mean(ea ** 2))), *_stated(res),
                                 tuple((c.status, c.name, c.summary) for c in res.checks if c.status != "pass")))
    return tally, judged


def _print_truth(judged: list[Judged]) -> None:
    truth = Counter(j.truth for j in judged)
    print(f"  truth ({TRUTH_POSES} random configurations over the limits, against the registered nominal): better "
          f"{truth['better']}, no clear difference {truth['same']}, worse {truth['worse']}")
    mean = np.array([j.calibrated / j.stated for j in judged])
    rms = np.array([j.true_rms / j.stated_rms for j in judged])
    print(f"  true over stated accuracy in use: mean {np.nanmedian(mean):.3g} median, {np.nanmax(mean):.3g} worst; "
          f"RMS over the range of use {np.nanmedian(rms):.3g} median, {np.nanmax(rms):.3g} worst")
    for (t, status, check), count in sorted(Counter((j.truth, s, c) for j in judged for s, c, _ in j.checks).items()):
        print(f"  {status} {check}, truth {t}: {count}")
    wrong = [("false fail", j) for j in judged if j.false_fail] + [("false pass", j) for j in judged if j.false_pass]
    print(f"  false fails {sum(j.false_fail for j in judged)}, false passes {sum(j.false_pass for j in judged)}")
    for kind, j in wrong:
        print(f"  {kind}: {j.label}: {j.nominal * 1e3:.4g} mm -> {j.calibrated * 1e3:.4g} mm in truth, stated "
              f"{j.stated * 1e3:.4g} mm ({j.stated_rms * 1e3:.4g} mm RMS over the range of use, true "
              f"{j.true_rms * 1e3:.4g}); " + "; ".join(f"{c}: {why[:200]}" for s, c, why in j.checks if s == "fail"))


def _print(title: str, tally: dict, counted: str = "campaigns") -> None:
    n = max(tally["n"], 1)
    share = {k: f"{tally[k]} ({100 * tally[k] / n:.0f} %)" for k in ("warn", "fail")}
    print(f"{title}: {tally['n']} {counted}, pass {tally['pass']}, warn {share['warn']}, fail {share['fail']}")
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
    ap.add_argument("--combined", type=int, default=30,
                    help="campaigns of simulated robots with several effects beyond the model at once (default 30)")
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
    if args.combined:
        tally, judged = combined(args.combined, args.seed)
        _print(f"simulated robots with several effects beyond the model at once, {args.combined} campaigns", tally,
               "calibrations")
        _print_truth(judged)


if __name__ == "__main__":
    main()
