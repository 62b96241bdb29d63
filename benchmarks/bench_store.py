"""The store of calibrations at plant size, and its judgements over many seeds.

    python benchmarks/bench_store.py [--robots 10000] [--calibrations 10] [--postgres URL]
    python benchmarks/bench_store.py --judgement [--seeds 100]

Size: a store of ``--robots`` robots of one type with ``--calibrations`` calibrations each (every
calibration with a calibrated model of its own), filled in transactions of 1,000 records; then
one robot's history (the median of 50 robots) and the type's comparison (all robots side by side,
the median of 3). Baseline in the same run: reading one robot's calibrations as 10 result.json
files. SQLite in a temporary folder; PostgreSQL when ``--postgres`` (or $ROBOCAL_TEST_POSTGRES)
names a database, in a schema made and dropped here.

Judgement: per seed, a simulated arm calibrated twice (unchanged, or with j3.d moved by 3 or 5
combined standard deviations between the campaigns): the share of histories naming a change, and
the share naming the moved one; and verifications of 20 poses on the robot as calibrated and
after a drift of 0.3 mm (j3.d). Then, for every judged parameter in turn, histories drawn from
the first seed's covariance with that parameter moved by 3 combined standard deviations: the
share naming it.
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
import uuid
from dataclasses import replace
from pathlib import Path

import numpy as np

import robocal as rc

DEG = np.pi / 180


def arm() -> rc.RobotModel:
    """A 6R arm (modified DH) with a tool marker, about 1 m reach."""
    rows = [dict(), dict(alpha=-90 * DEG), dict(d=0.45), dict(alpha=-90 * DEG, r=0.45), dict(alpha=90 * DEG),
            dict(alpha=-90 * DEG)]
    return rc.serial_model("bench6r", rows, markers=[("tool", (0.05, 0.02, 0.12))],
                           base_position=(1.5, -0.4, 0.2))


def calibration(seed: int = 1, true=None):
    """(model, true robot, result) of a simulated campaign: 42 poses fitted, 18 held out."""
    model = arm()
    t, data = rc.simulate(model, 60, seed=seed, noise=2e-5)
    if true is not None:
        data = rc.measure(true, data.q, noise=2e-5, rng=seed)
    fit, val = data.split(0.3, rng=seed)
    return model, true or t, rc.calibrate(model, fit, validation=val)


def fill(store, result, robots: int, per_robot: int, rng) -> float:
    """Record robots x per_robot calibrations (estimates drawn with the result's standard deviations);
    seconds taken."""
    base = rc.stored_calibration(result, "R", robot_type="bench6r", at="2026-01-01")
    nominal = rc.model_document(result.nominal_model)
    text = rc.model_to_dict(result.calibrated_model)
    import json
    import zlib

    std = np.array([e.std for e in base.estimates])
    mean = np.array([e.estimate for e in base.estimates])
    t0 = time.perf_counter()
    batch, models = [], [nominal]
    for i in range(robots * per_robot):
        robot, k = divmod(i, per_robot)
        doc = json.dumps({**text, "name": f"R{robot:05d}-{k}"}, sort_keys=True).encode()
        sha = f"{uuid.uuid4().hex}{uuid.uuid4().hex}"
        models.append((sha, zlib.compress(doc, 6)))
        x = mean + rng.normal(0, 1, mean.size) * std
        batch.append(replace(base, robot=f"R{robot:05d}", calibrated_at=f"{2016 + k}-01-01T00:00:00+00:00",
                             calibrated_model=sha, fingerprint=f"{i:08d}",
                             estimates=tuple(e._replace(estimate=float(v)) for e, v in zip(base.estimates, x))))
        if len(batch) == 1000:
            store.add(batch, models)
            batch, models = [], [nominal]
    if batch:
        store.add(batch, models)
    return time.perf_counter() - t0


def timed(f, n: int) -> float:
    times = []
    for i in range(n):
        t0 = time.perf_counter()
        f(i)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def size_run(location: str, result, result_path: Path, robots: int, per_robot: int, label: str) -> None:
    rng = np.random.default_rng(0)
    with rc.open_store(location, create=True) as store:
        filled = fill(store, result, robots, per_robot, rng)
        h_time = timed(lambda i: rc.history(store, f"R{(i * 197) % robots:05d}"), 50)
        h = rc.history(store, "R00000")
        t_time = timed(lambda i: rc.type_comparison(store, "bench6r"), 3)
        t = rc.type_comparison(store, "bench6r")
    base = timed(lambda i: [rc.read_result(result_path) for _ in range(per_robot)], 5)
    print(f"{label}: {robots} robots x {per_robot} calibrations filled in {filled:.0f} s; "
          f"one history ({len(h.calibrations)} calibrations, {len(h.comparisons)} comparisons) {h_time * 1e3:.1f} ms "
          f"(baseline: {per_robot} result.json read {base * 1e3:.0f} ms); type comparison ({len(t.robots)} robots, "
          f"{len(t.names)} parameters, {len(t.outliers)} standing out) {t_time:.2f} s")


def judgement(seeds: int) -> None:
    named = {0.0: 0, 3.0: 0, 5.0: 0}
    moved = {3.0: 0, 5.0: 0}
    verdicts = {"unchanged": 0, "drifted": 0}
    t0 = time.perf_counter()
    for seed in range(seeds):
        model, true, first = calibration(seed)
        j = first.parameter_names.index("j3.d")
        for size in named:
            lay = rc.parameter_names(true)
            p = rc.parameter_vector(true)
            p[lay.index("j3.d")] += size * np.sqrt(2) * first.parameters[j].std
            _, _, second = calibration(seed + 10_000, rc.model_from_vector(true, p))
            a = rc.stored_calibration(first, "R", at="2026-01-01")
            b = rc.stored_calibration(second, "R", at="2026-06-01")
            pair = [replace(a, id=1), replace(b, id=2)]
            changes, _ = rc.judge_changes(pair)
            names = [c.name for c in changes if c.named]
            named[size] += bool(names) or rc.judge_overall(pair)[0].named
            if size:
                moved[size] += "j3.d" in names
        then = rc.accuracy_at_calibration(rc.io.result_to_dict(first))
        lay = rc.parameter_names(true)
        p = rc.parameter_vector(true)
        p[lay.index("j3.d")] += 3e-4
        q = rc.random_configurations(model, 20, np.random.default_rng(seed))
        for key, robot in (("unchanged", true), ("drifted", rc.model_from_vector(true, p))):
            v = rc.verify(first.calibrated_model, rc.measure(robot, q, noise=2e-5, rng=seed), then)
            verdicts[key] += v.verdict == ("within accuracy" if key == "unchanged" else "recalibrate")
    drawn_power(seeds)
    print(f"judgement over {seeds} seeds ({time.perf_counter() - t0:.0f} s): unchanged robots naming a change "
          f"{named[0.0]}/{seeds}; j3.d moved by 3 combined std named {moved[3.0]}/{seeds}, by 5 {moved[5.0]}/{seeds}; "
          f"verification of 20 poses: unchanged 'within accuracy' {verdicts['unchanged']}/{seeds}, drifted 0.3 mm "
          f"'recalibrate' {verdicts['drifted']}/{seeds}")


def drawn_history(result, rng, name=None, size=0.0):
    """Two calibrations drawn about the result's estimates with its covariance; ``name`` moved by
    ``size`` combined standard deviations between them."""
    base = rc.stored_calibration(result, "R", at="2026-01-01")
    truth = np.array([p.estimate for p in result.parameters])
    cals = []
    for k in range(2):
        x = rng.multivariate_normal(truth, result.covariance)
        if name and k == 1:
            j = result.parameter_names.index(name)
            x[j] += size * np.sqrt(2) * result.parameters[j].std
        cals.append(replace(base, calibrated_at=f"2026-0{k + 1}-01T00:00:00+00:00", id=k + 1,
                            estimates=tuple(e._replace(estimate=float(v)) for e, v in zip(base.estimates, x))))
    return cals


def _any_named(cals) -> bool:
    return any(c.named for c in rc.judge_changes(cals)[0]) or any(o.named for o in rc.judge_overall(cals))


def drawn_power(seeds: int) -> None:
    """Histories drawn from one campaign's covariance: unchanged, and each judged parameter moved by 3
    combined standard deviations; the share naming it against what its test's mean allows (the
    statistic's mean ``3 sqrt(C_jj (C^-1)_jj)`` against the threshold)."""
    from scipy.stats import norm

    _, _, result = calibration(0)
    rng = np.random.default_rng(0)
    idx = [i for i, p in enumerate(result.parameters) if p.family in rc.JUDGED_FAMILIES]
    names = [result.parameters[i].name for i in idx]
    C = result.covariance[np.ix_(idx, idx)]
    gain = np.sqrt(np.diag(C) * np.diag(np.linalg.inv(C)))
    unchanged = sum(_any_named(drawn_history(result, rng)) for _ in range(10 * seeds))
    threshold = rc.judge_changes(drawn_history(result, rng))[1]
    per = {n: sum(n in [c.name for c in rc.judge_changes(drawn_history(result, rng, n, 3.0))[0] if c.named]
                  for _ in range(seeds)) for n in names}
    print(f"drawn histories: unchanged naming a change (single-parameter or overall tests) {unchanged}/{10 * seeds}; "
          f"one parameter moved by 3 combined std named, mean over the {len(names)} judged parameters "
          f"{np.mean(list(per.values())):.0f}/{seeds} (fewest {min(per.values())}, {min(per, key=per.get)}; most "
          f"{max(per.values())}, {max(per, key=per.get)}); threshold {threshold:.3f}")
    print(f"{'parameter':<12}{'gain':>6}{'named':>8}{'allowed':>9}")
    for n, g in zip(names, gain):
        print(f"{n:<12}{g:>6.2f}{per[n]:>8}{100 * norm.sf(threshold - 3.0 * g):>9.0f}")
    print(f"parameters named in >= 95 % of seeds: {sum(v >= 0.95 * seeds for v in per.values())} of {len(names)}; "
          f"those whose test's mean allows it (>= 95 %): {int(np.sum(norm.sf(threshold - 3.0 * gain) >= 0.95))}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", type=int, default=10_000)
    ap.add_argument("--calibrations", type=int, default=10)
    ap.add_argument("--postgres", default=os.environ.get("ROBOCAL_TEST_POSTGRES"))
    ap.add_argument("--judgement", action="store_true", help="the judgements over seeds instead of the size run")
    ap.add_argument("--seeds", type=int, default=100)
    args = ap.parse_args()
    if args.judgement:
        judgement(args.seeds)
        return
    _, _, result = calibration()
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "result.json"
        rc.io.write_result(result, path)
        size_run(str(Path(folder) / "store.sqlite"), result, path, args.robots, args.calibrations, "sqlite")
        if args.postgres:
            import psycopg

            schema = "bench_" + uuid.uuid4().hex[:8]
            with psycopg.connect(args.postgres, autocommit=True) as c:
                c.execute(f"CREATE SCHEMA {schema}")
            try:
                sep = "&" if "?" in args.postgres else "?"
                size_run(f"{args.postgres}{sep}options=-csearch_path%3D{schema}", result, path, args.robots,
                         args.calibrations, "postgresql")
            finally:
                with psycopg.connect(args.postgres, autocommit=True) as c:
                    c.execute(f"DROP SCHEMA {schema} CASCADE")


if __name__ == "__main__":
    main()
