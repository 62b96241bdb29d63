"""How often the diagnosis names the true cause of a simulated mistake, and how often it names a
cause where there is none (docs/diagnosis.md).

Run: python benchmarks/diagnosis_corpus.py [--seeds 20] [--first 0] [--clean 60] [--effects 20] [--presets 10]

Every mistake of tests/diagnosis_corpus.py on the 6R arm and the TH8-like cylindrical arm, seeds
0..SEEDS-1: the share of campaigns whose first finding is the true cause, per mistake and robot.
Then clean simulated campaigns (CLEAN seeds per robot, 30 to 120 poses) and campaigns of robots with
effects the model does not hold (gear errors, per-pose scatter, link elasticity, slow drift; EFFECTS
seeds each per robot), and of `robocal.sim`'s robots with effects beyond the model (`PRESETS`,
PRESETS seeds each per robot, both arms with masses): the share in which a cause is named. Last,
the real UR5 and WAM campaigns of tests/data/real: the cause named, if any (none expected).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections import defaultdict

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests"))

import diagnosis_corpus as corpus


def _first(case):
    _, diagnosis = case.run()
    return diagnosis.cause.hypothesis if diagnosis.cause else None


def mistakes(seeds: int, first: int = 0) -> None:
    hits, total, wrong = defaultdict(int), defaultdict(int), defaultdict(list)
    for seed in range(first, seeds):
        for robot in corpus.ROBOTS:
            for make in corpus.MISTAKES:
                case = make(robot, seed)
                if case is None:
                    continue
                got = _first(case)
                print(f"  {robot} {seed} {make.__name__}: {'ok' if got == case.expected else 'MISSED'} ({got})",
                      flush=True)
                key = (case.name, robot)
                total[key] += 1
                hits[key] += got == case.expected
                if got != case.expected:
                    wrong[key].append(f"{seed}: {got}")
    print(f"{'mistake':<45}{'robot':<13}{'named first':>12}")
    for key in total:
        print(f"{key[0]:<45}{key[1]:<13}{hits[key]:>7}/{total[key]:<4}" + (f"  missed: {', '.join(wrong[key])}"
                                                                           if wrong[key] else ""))
    n, h = sum(total.values()), sum(hits.values())
    if n:
            print(f"all: {h}/{n} = {100 * h / n:.1f} % named first; mistakes (per robot) below 90 %: "
              f"{sum(hits[k] < 0.9 * total[k] for k in total)} of {len(total)}")


def no_cause(clean: int, effects: int) -> None:
    for make in corpus.NO_CAUSE:
        seeds = clean if make is corpus.clean else effects
        named, n = [], 0
        for robot in corpus.ROBOTS:
            for seed in range(seeds):
                got = _first(make(robot, 1000 + seed))
                n += 1
                if got is not None:
                    named.append(f"{robot} {1000 + seed}: {got}")
        print(f"{make.__name__:<14} a cause named in {len(named)}/{n} campaigns" + (f": {'; '.join(named)}" if named
                                                                                       else ""), flush=True)


def presets(seeds: int) -> None:
    import robocal as rc

    for kind in sorted(rc.sim.PRESETS):
        named, n = [], 0
        for robot, make in corpus.ROBOTS.items():
            for seed in range(seeds):
                m = make(masses=True)
                true, d = rc.simulate(m, corpus.N_POSES, seed=2000 + seed, noise=corpus.NOISE)
                data = rc.sim.measure_real(true, d.q, rc.sim.PRESETS[kind], rng=2000 + seed, robot_seed=2000 + seed)
                got = _first(corpus.Case(kind, m, data, None))
                n += 1
                if got is not None:
                    named.append(f"{robot} {2000 + seed}: {got}")
        print(f"preset {kind:<8} a cause named in {len(named)}/{n} campaigns" + (f": {'; '.join(named)}" if named
                                                                                   else ""), flush=True)


def real() -> None:
    """The published UR5 and WAM tracker campaigns (tests/data/real, both files of each): no cause
    should be named."""
    import real_campaigns

    for robot in ("UR5", "WAM"):
        for kind in ("grid", "random"):
            got = _first(corpus.Case(robot, real_campaigns.nominal(robot), real_campaigns.campaign(robot, kind), None))
            print(f"real {robot} {kind:<7} cause named: {got}", flush=True)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--first", type=int, default=0, help="the first seed (to continue an interrupted run)")
    ap.add_argument("--clean", type=int, default=60)
    ap.add_argument("--effects", type=int, default=20)
    ap.add_argument("--presets", type=int, default=10, help="seeds per robot of each of robocal.sim.PRESETS")
    ap.add_argument("--no-real", dest="real", action="store_false", help="skip the real UR5 and WAM campaigns")
    args = ap.parse_args(argv)
    t = time.perf_counter()
    mistakes(args.seeds, args.first)
    no_cause(args.clean, args.effects)
    presets(args.presets)
    if args.real:
        real()
    print(f"({time.perf_counter() - t:.0f} s)")


if __name__ == "__main__":
    main()
