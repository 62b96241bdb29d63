"""How often the diagnosis names the true cause of a simulated mistake, and how often it names a
cause where there is none (docs/diagnosis.md).

Run: python benchmarks/diagnosis_corpus.py [--seeds 20] [--first 0] [--clean 60] [--effects 20] [--presets 10]
     python benchmarks/diagnosis_corpus.py --contacts [--seeds 5] [--clean 20]

Every mistake of tests/diagnosis_corpus.py on the 6R arm and the TH8-like cylindrical arm, seeds
0..SEEDS-1: the share of campaigns whose first finding is the true cause, per mistake and robot.
Then clean simulated campaigns (CLEAN seeds per robot, 30 to 120 poses) and campaigns of robots with
effects the model does not hold (gear errors, per-pose scatter, link elasticity, slow drift; EFFECTS
seeds each per robot), and of `robocal.sim`'s robots with effects beyond the model (`PRESETS`,
PRESETS seeds each per robot, both arms with masses): the share in which a cause is named. Last,
the real UR5 and WAM campaigns of tests/data/real: the cause named, if any (none expected).

With ``--contacts``, calibrations from contacts instead (``diagnose_contacts``): every mistake of
tests/test_contact_diagnosis.py injected into socket campaigns of the 6R arm (3 placements of a
3-socket plate, 12 seatings a socket, spacings stated), SEEDS seeds each, calibrated as a user would
(``calibrate`` with contacts and its defaults); then CLEAN seeds each of clean campaigns, of an arm whose
shoulder and elbow bend under gravity and of one with gear errors, calibrated as geometric; last the
time of ``diagnose_contacts`` on 3-placement campaigns of 25 seatings a socket against the
calibration's it explains.
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


def _contact_run(contacts, model=None):
    """(first cause or None, calibration seconds, diagnosis seconds), or None when the calibration fails."""
    import warnings

    import test_contact_diagnosis as cases

    from robocal.errors import RobocalError
    from robocal.identification import calibrate, diagnose_contacts

    model = model or cases.arm()
    t0 = time.process_time()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = calibrate(model, contacts=contacts)
    except RobocalError as e:
        print(f"    calibration failed: {e}", flush=True)
        return None
    t1 = time.process_time()
    diagnosis = diagnose_contacts(model, contacts, result)
    t2 = time.process_time()
    return (diagnosis.cause.hypothesis if diagnosis.cause else None), t1 - t0, t2 - t1


def contacts(seeds: int, clean: int) -> None:
    import numpy as np
    import test_contact_diagnosis as cases

    from robocal.sim import socket_campaign

    for mistake in cases.MISTAKES:
        hits, n, failed, missed = 0, 0, 0, []
        for seed in range(seeds):
            changed, expected, _ = cases.injected(mistake, seed)
            got = _contact_run(changed)
            if got is None:
                failed += 1
                continue
            n += 1
            hits += got[0] == expected
            if got[0] != expected:
                missed.append(f"{seed}: {got[0]}")
        print(f"{mistake.__name__:<22} true cause first {hits}/{n}" + (f", {failed} calibration(s) failed" if failed
                                                                       else "") + (f"  missed: {', '.join(missed)}"
                                                                                   if missed else ""), flush=True)
    for effect in ("", "compliance", "gears"):
        named = []
        for seed in range(100, 100 + clean):
            got = _contact_run(cases.campaign(seed, effect), cases.arm(masses=bool(effect)))
            if got is not None and got[0] is not None:
                named.append(f"{seed}: {got[0]}")
        print(f"{effect or 'clean':<22} a cause named in {len(named)}/{clean}" + (f": {'; '.join(named)}" if named
                                                                                  else ""), flush=True)
    times = []
    for seed in range(3):
        c = socket_campaign(cases.truth(seed), placements=3, poses_per_socket=25, joint_noise=cases.ENCODER, rng=seed)
        got = _contact_run(c)
        if got is not None:
            times.append(got[1:])
    cal, diag = np.array(times).T
    print(f"3 placements x 3 sockets x 25 seatings ({c.n_rows} rows), 6R arm, CPU s over {len(times)} campaigns: "
          f"diagnose_contacts {diag.mean():.2f} (max {diag.max():.2f}), the calibration it explains {cal.mean():.2f} "
          f"(max {cal.max():.2f})", flush=True)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--first", type=int, default=0, help="the first seed (to continue an interrupted run)")
    ap.add_argument("--clean", type=int, default=60)
    ap.add_argument("--effects", type=int, default=20)
    ap.add_argument("--presets", type=int, default=10, help="seeds per robot of each of robocal.sim.PRESETS")
    ap.add_argument("--no-real", dest="real", action="store_false", help="skip the real UR5 and WAM campaigns")
    ap.add_argument("--contacts", action="store_true", help="calibrations from contacts instead (SEEDS seeds a "
                    "mistake, CLEAN seeds a robot without one)")
    args = ap.parse_args(argv)
    t = time.perf_counter()
    if args.contacts:
        contacts(args.seeds, args.clean)
        print(f"({time.perf_counter() - t:.0f} s)")
        return
    mistakes(args.seeds, args.first)
    no_cause(args.clean, args.effects)
    presets(args.presets)
    if args.real:
        real()
    print(f"({time.perf_counter() - t:.0f} s)")


if __name__ == "__main__":
    main()
