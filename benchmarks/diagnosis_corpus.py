"""How well the diagnosis decides (docs/diagnosis.md): mistakes caught and named, no cause where there
is none, and no wrong model written as good.

Run: python benchmarks/diagnosis_corpus.py [--seeds 1] [--subsets 25] [--simulated 50] [--no-real]
     python benchmarks/diagnosis_corpus.py --contacts [--seeds 5] [--clean 20]

* **Mistakes**: every mistake of tests/diagnosis_corpus.py on the 6R arm and the TH8-like
  cylindrical arm (SEEDS seeds from 0) and every mistake of tests/real_mistakes.py injected into the
  published UR5 and WAM campaigns, each calibrated as a user would (``robocal.calibrate``, which
  diagnoses). Per case: the verdict, the first cause named and its strength, whether it is one of the
  expected ones, and how far the calibrated model places the robot from the truth (the true robot,
  or for the real campaigns the calibration of the whole clean grid, at its test poses). A case is
  **caught** when the verdict fails or a cause is named; a model is **wrong** beyond ``WRONG``
  (0.3 mm RMS); a wrong model is **written as good** when its verdict is not "fail" (the command
  line writes it and exits 0).
* **No cause**: SUBSETS random subsets (60 to 400 poses) of each real grid and SIMULATED campaigns
  of simulated robots with effects beyond the model (``robocal.sim.PRESETS``), calibrated as a user
  would: how often a cause is named, and how often the verdict fails.
* **Real campaigns**: the UR5 and WAM grids and test poses, and the MUKCa Panda's sockets.

With ``--contacts``, calibrations from contacts instead: every mistake of
tests/test_contact_diagnosis.py injected into socket campaigns of the 6R arm, then clean campaigns.
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

import diagnosis_corpus as corpus  # noqa: E402
import real_campaigns as real  # noqa: E402
import real_mistakes  # noqa: E402
from robots import beyond_model  # noqa: E402

import robocal as rc  # noqa: E402
from robocal.errors import InputError, RobocalError  # noqa: E402
from robocal.sim import PRESETS  # noqa: E402

# a calibrated model this far (RMS, m) from the truth is wrong
WRONG = 0.3e-3


def _first(result) -> tuple[str | None, str]:
    d = result.diagnosis
    cause = d.cause if d is not None else None
    return (None, "") if cause is None else (cause.hypothesis, cause.status)


def _one(case) -> dict:
    """The outcome of one mistake: verdict, first cause, its strength, model error (m)."""
    try:
        result = case.run()
        if isinstance(result, tuple):
            result = result[0]
    except InputError as e:          # refused before any fit: the message names the cause
        said = "validation repeated" if "repeat" in str(e) else "input refused"
        return {"verdict": "refused", "cause": said, "status": "fail", "error": None, "message": str(e)[:120]}
    except RobocalError as e:
        return {"verdict": "error", "cause": None, "status": "", "error": None, "message": str(e)[:120]}
    cause, status = _first(result)
    return {"verdict": result.verdict, "cause": cause, "status": status, "error": case.model_error(result),
            "message": result.diagnosis.summary[:160] if result.diagnosis else ""}


def mistakes(seeds: int, with_real: bool) -> None:
    cases = [c for seed in range(seeds) for robot in corpus.ROBOTS for c in corpus.mistakes(robot, seed)]
    names = [f"{c.name} ({robot} {seed})" for seed in range(seeds) for robot in corpus.ROBOTS
             for c in corpus.mistakes(robot, seed)]
    if with_real:
        injected = real_mistakes.mistakes()
        cases += injected
        names += [c.name for c in injected]
    tally = Counter()
    for name, case in zip(names, cases):
        out = _one(case)
        caught = out["verdict"] in ("fail", "refused") or out["cause"] is not None
        right = out["cause"] in case.expected
        wrong = out["error"] is not None and out["error"] > WRONG
        good = wrong and out["verdict"] not in ("fail", "refused", "error")
        real_case = name.startswith(("UR5", "WAM"))
        tally.update({"n": 1, "caught": caught, "right": right, "real": real_case, "real right": real_case and right,
                      "decisive": out["status"] == "fail", "wrong written": good,
                      "wrong written, decisive": good and out["status"] == "fail"})
        err = "-" if out["error"] is None else f"{out['error'] * 1e3:.3g} mm"
        print(f"  {'ok ' if right else ('~  ' if caught else 'MISSED')} {name}: {out['verdict']}, "
              f"{out['cause']} ({out['status'] or '-'}), model {err}{'  WRITTEN WRONG' if good else ''}"
              + ("" if right else f"  | {out['message']}"), flush=True)
    n = max(tally["n"], 1)
    print(f"mistakes: {tally['n']} ({tally['real']} injected into the real campaigns); caught {tally['caught']} "
          f"({100 * tally['caught'] / n:.0f} %), right cause first {tally['right']} ({100 * tally['right'] / n:.0f} %; "
          f"real {tally['real right']} of {tally['real']}), decisive {tally['decisive']}; wrong models written as "
          f"good {tally['wrong written']}, of them with a decisive cause {tally['wrong written, decisive']}")


def _calibrated(model, data, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return rc.calibrate(model, data, **kw)


def no_cause(subsets: int, simulated: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    named, failed, n = [], [], 0
    for robot, k, model, subset in real.subsets(subsets, rng):
        n += 1
        _tally(f"{robot} subset {k} ({subset.n_poses} poses)", _calibrated(model, subset), named, failed)
    for name, preset, k, nominal, data in beyond_model(simulated, rng, presets=sorted(PRESETS)):
        families = ("geometric", "compliance") if preset in ("elastic", "cable") else ("geometric",)
        res = _calibrated(nominal, data, parameters=families)
        n += 1
        _tally(f"{name} {preset} #{k} ({data.n_poses} poses)", res, named, failed)
    print(f"clean campaigns: {n}; a cause named in {len(named)}, the verdict failed in {len(failed)}")
    for line in named + failed:
        print(f"  {line}")


def _tally(name, res, named, failed) -> None:
    cause, status = _first(res)
    if cause is not None:
        named.append(f"{name}: {cause} ({status}): {res.diagnosis.summary[:160]}")
    if res.verdict == "fail":
        failed.append(f"{name}: failed ({', '.join(c.name for c in res.checks if c.status == 'fail')})")
    print(f"  {name}: {res.verdict}, cause {cause}", flush=True)


def real_campaigns() -> None:
    """Every real campaign as published: no cause, no fail."""
    for robot in ("UR5", "WAM"):
        for kind in ("grid", "random"):
            model = real.nominal(robot)
            res = _calibrated(model, real.campaign(robot, kind, model))
            print(f"real {robot} {kind}: {res.verdict}, cause {_first(res)[0]}: {res.diagnosis.summary[:120]}",
                  flush=True)
    mukca = os.path.join(HERE, "..", "tests", "data", "real", "mukca")   # the same files as shared/data/real
    model = rc.read_urdf(os.path.join(mukca, "panda.urdf"), tip_link="ball_link", markers=[("ball", (0.0, 0.0, 0.0))])
    contacts = rc.io.read_contacts(os.path.join(mukca, "panda_3"), model)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = rc.calibrate(model, contacts=contacts)
    print(f"real MUKCa Panda sockets: {res.verdict}, cause {_first(res)[0]}: {res.diagnosis.summary[:120]}",
          flush=True)


def contacts(seeds: int, clean: int) -> None:
    import test_contact_diagnosis as cases

    for mistake in cases.MISTAKES:
        hits, n, missed = 0, 0, []
        for seed in range(seeds):
            changed, expected, _ = cases.injected(mistake, seed)
            try:
                res = _calibrated_contacts(changed)
            except RobocalError as e:
                missed.append(f"{seed}: calibration failed ({e})")
                continue
            n += 1
            got = _first(res)[0]
            hits += got == expected
            if got != expected:
                missed.append(f"{seed}: {got}")
        print(f"{mistake.__name__:<22} true cause first {hits}/{n}" + (f"  missed: {', '.join(missed)}" if missed
                                                                       else ""), flush=True)
    for effect in ("", "compliance", "gears"):
        named = []
        for seed in range(100, 100 + clean):
            res = _calibrated_contacts(cases.campaign(seed, effect), cases.arm(masses=bool(effect)))
            if _first(res)[0] is not None:
                named.append(f"{seed}: {_first(res)[0]}")
        print(f"{effect or 'clean':<22} a cause named in {len(named)}/{clean}" + (f": {'; '.join(named)}" if named
                                                                                  else ""), flush=True)


def _calibrated_contacts(c, model=None):
    import test_contact_diagnosis as cases

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return rc.calibrate(model or cases.arm(), contacts=c)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=1, help="seeds of each simulated mistake and robot (default 1)")
    ap.add_argument("--subsets", type=int, default=25, help="random subsets of each real grid (default 25)")
    ap.add_argument("--simulated", type=int, default=50, help="simulated robots beyond the model (default 50)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--no-real", dest="real", action="store_false", help="leave the real campaigns out")
    ap.add_argument("--no-mistakes", dest="mistakes", action="store_false", help="leave the mistakes out")
    ap.add_argument("--contacts", action="store_true", help="calibrations from contacts instead")
    ap.add_argument("--clean", type=int, default=20, help="with --contacts: clean campaigns per robot")
    args = ap.parse_args(argv)
    t = time.perf_counter()
    print(f"# diagnosis corpus, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")
    if args.contacts:
        contacts(args.seeds, args.clean)
    else:
        if args.mistakes:
            mistakes(args.seeds, args.real)
        if args.subsets or args.simulated:
            no_cause(args.subsets, args.simulated, args.seed)
        if args.real:
            real_campaigns()
    print(f"({time.perf_counter() - t:.0f} s)")


if __name__ == "__main__":
    main()
