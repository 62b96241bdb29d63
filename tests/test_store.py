"""The store of calibrations (docs/store.md), the same tests on SQLite and on a PostgreSQL server:
records read back whole, the schema upgraded in place, concurrent and killed writers, changes
judged against their combined uncertainty, robots of a type compared, verification verdicts, and
the commands record, history, verify and calibrate --record.

PostgreSQL: ``ROBOCAL_TEST_POSTGRES`` names a server (a ``postgresql://`` URL of a database the
tests may make schemas in), by default the one ``.ci/run`` starts; each test gets a schema of its
own. Where none answers, the PostgreSQL half is skipped, saying why.
"""

import json
import multiprocessing as mp
import os
import signal
import sqlite3
import sys
import time
import uuid
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_one_line_error
from robots import arm6r

import robocal as rc
from robocal._store import store as _store

ROOT = Path(__file__).resolve().parents[1]

PG_ENV = "ROBOCAL_TEST_POSTGRES"
# where .ci/run's server is when the variable is not set
PG_DEFAULT = "postgresql://robocal:robocal@localhost:5432/robocal"


def _pg_url():
    url = os.environ.get(PG_ENV) or PG_DEFAULT
    try:
        import psycopg
    except ImportError:
        pytest.skip("PostgreSQL half skipped: psycopg is not installed (pip install 'robocal[store-pg]')")
    try:
        psycopg.connect(url, connect_timeout=5).close()
    except psycopg.Error as e:
        pytest.skip(f"PostgreSQL half skipped: no server at {_store.shown_location(url)} ({' '.join(str(e).split())}); "
                    f"set {PG_ENV} to a postgresql:// URL (.ci/run starts a server and sets it)")
    return url


@pytest.fixture(params=["sqlite", "postgresql"])
def location(request, tmp_path):
    """A fresh, empty store location of each back-end."""
    if request.param == "sqlite":
        yield str(tmp_path / "store.sqlite")
        return
    import psycopg

    url = _pg_url()
    schema = "t_" + uuid.uuid4().hex[:12]
    with psycopg.connect(url, autocommit=True) as c:
        c.execute(f"CREATE SCHEMA {schema}")
    sep = "&" if "?" in url else "?"
    yield f"{url}{sep}options=-csearch_path%3D{schema}"
    with psycopg.connect(url, autocommit=True) as c:
        c.execute(f"DROP SCHEMA {schema} CASCADE")


@pytest.fixture(scope="module")
def campaign():
    """A simulated arm calibrated on 42 poses and judged on 18 held out: (model, true robot, result)."""
    model = arm6r()
    true, data = rc.simulate(model, 60, seed=1, noise=2e-5)
    fit, val = data.split(0.3, rng=0)
    return model, true, rc.calibrate(model, fit, validation=val)


@pytest.fixture(scope="module")
def result_file(campaign, tmp_path_factory):
    path = tmp_path_factory.mktemp("store") / "result.json"
    rc.io.write_result(campaign[2], path)
    return path


# -- records ----------------------------------------------------------------------------------------

def test_a_record_reads_back_whole(location, campaign):
    result = campaign[2]
    with rc.open_store(location, create=True) as store:
        rec = store.record(result, "SN-1", robot_type="arm", at="2026-03-02T10:00:00Z", source="r.json")
        assert store.version == _store.SCHEMA_VERSION
    with rc.open_store(location) as store:
        (back,) = store.calibrations("SN-1")
        assert back.id == rec.id and back.calibrated_at == "2026-03-02T10:00:00+00:00"
        assert [(e.name, e.estimate, e.std) for e in back.estimates] == \
               [(p.name, p.estimate, p.std) for p in result.parameters]
        assert back.verdict == result.verdict and len(back.checks) == len(result.checks)
        assert back.accuracy.rms == result.stats.validation_after.rms and back.accuracy.n == 18
        assert back.accuracy.source == "held-out poses"
        assert rc.parameter_vector(store.model(back.calibrated_model)) == \
               pytest.approx(rc.parameter_vector(result.calibrated_model), abs=1e-12)
        assert store.model(back.nominal_model).name == result.nominal_model.name
        assert dict(back.inputs)["data"] == result.provenance["data"]["sha256"]
        assert store.robots() == (("SN-1", "arm", 1),)
        assert back.correlation.dtype == np.float64
        assert np.allclose(back.correlation, result.correlation, rtol=0, atol=1e-15)     # not single precision


def test_a_version_2_store_keeps_its_single_precision_correlations_and_judges_with_them(location, campaign):
    result = campaign[2]
    with rc.open_store(location, create=True) as store:
        store.record(result, "SN-1", at="2026-01-01")
    single = np.asarray(result.correlation, dtype="<f4")[np.triu_indices(len(result.parameters))].tobytes()
    with rc.open_store(location, write=True) as store, store._db.transaction(write=True) as cur:  # as version 2
        store._execute(cur, "UPDATE robocal_calibrations SET correlation = ?", (single,))
        store._execute(cur, "UPDATE robocal_schema SET version = 2")
    with rc.open_store(location, create=True) as store:
        assert store.version == 3
        second = rc.stored_calibration(result, "SN-1", at="2026-02-01")
        moved = tuple(e._replace(estimate=e.estimate + 6 * np.sqrt(2) * e.std) if e.name == "j5.theta" else e
                      for e in second.estimates)
        store.add([replace(second, estimates=moved)], [rc.model_document(result.nominal_model),
                                                       rc.model_document(result.calibrated_model)])
        old, new = store.calibrations("SN-1")
        h = rc.history(store, "SN-1")
    assert old.correlation.dtype == np.float32 and new.correlation.dtype == np.float64
    assert np.allclose(old.correlation, result.correlation, atol=1e-7)
    assert [c.name for c in h.changes] == ["j5.theta"] and h.overall[0].named


def test_the_same_calibration_twice_is_refused_and_nothing_stored(location, campaign):
    with rc.open_store(location, create=True) as store:
        store.record(campaign[2], "SN-1", at="2026-03-02")
        with pytest.raises(rc.InputError, match="stored already"):
            store.record(campaign[2], "SN-1", at="2026-03-02")
        assert len(store.calibrations("SN-1")) == 1


def test_a_verification_is_held_against_the_accuracy_the_instrument_saw(campaign):
    d = json.loads(json.dumps(_store.result_to_dict(campaign[2])))
    d["in_use"] = {"method": "validation", "k": None, "position_after": {"n": 18, "mean": 0.0, "rms": 0.0,
                                                                       "p95": 0.0, "max": 0.0}}
    acc = rc.accuracy_at_calibration(d)        # the robot's accuracy in use has the noise taken out
    assert (acc.rms, acc.n, acc.source) == (campaign[2].stats.validation_after.rms, 18, "held-out poses")
    rec = rc.stored_calibration(campaign[2], "R")
    assert rec.in_use == (rc.io.result_to_dict(campaign[2]).get("in_use"))
    d["stats"]["validation_after"] = {"n": 0}
    fit = rc.accuracy_at_calibration(d)
    assert fit.source == "fitted poses" and fit.rms > campaign[2].stats.fit_after.rms


def test_an_older_schema_is_upgraded_in_place(location, campaign):
    store = rc.open_store(location, create=True)
    store.close()
    with rc.open_store(location, write=True) as store, store._db.transaction(write=True) as cur:  # back to version 1
        store._execute(cur, "DROP TABLE robocal_verifications")
        store._execute(cur, "UPDATE robocal_schema SET version = 1")
    with rc.open_store(location, create=True) as store:
        assert store.version == _store.SCHEMA_VERSION
        store.record(campaign[2], "SN-1", at="2026-01-01")
    with rc.open_store(location, create=True) as store:
        store.record(campaign[2], "SN-1", at="2026-02-01")
        assert len(store.calibrations("SN-1")) == 2 and store.verifications("SN-1") == ()


def test_a_newer_schema_a_missing_store_and_a_foreign_file_are_refused(location, tmp_path):
    if location.endswith(".sqlite"):
        with pytest.raises(rc.InputError, match="no store here"):
            rc.open_store(location)
        (tmp_path / "junk.sqlite").write_bytes(b"not a database at all" * 100)
        with pytest.raises(rc.InputError, match="junk.sqlite: not a store of calibrations"):
            rc.open_store(tmp_path / "junk.sqlite", create=True)
        (tmp_path / "result.json").write_text('{\n "schema": "robocal.result/1"\n}\n')   # a store given a result
        with pytest.raises(rc.InputError, match="result.json: a robocal result file, not a store of calibrations"):
            rc.open_store(tmp_path / "result.json", create=True)
        assert (tmp_path / "result.json").read_text() == '{\n "schema": "robocal.result/1"\n}\n'
        other = tmp_path / "other.sqlite"
        with sqlite3.connect(other) as c:
            c.execute("CREATE TABLE invoices (n INTEGER)")
        with pytest.raises(rc.InputError, match="something else"):
            rc.open_store(other, create=True)
    with rc.open_store(location, create=True) as store, store._db.transaction(write=True) as cur:
        store._execute(cur, "UPDATE robocal_schema SET version = 99")
    with pytest.raises(rc.InputError, match="newer"):
        rc.open_store(location)


# -- writers at once, and killed ----------------------------------------------------------------------

def _writer(location, record, models, tag, n, start):
    start.wait()
    with rc.open_store(location, create=True) as store:
        for i in range(n):
            store.add([replace(record, calibrated_at="2026-01-01T00:00:00+00:00", fingerprint=f"{tag}-{i:04d}")],
                      models)


def _recorder(location, record, models, ready):
    with rc.open_store(location, create=True) as store:
        for i in range(100_000):
            store.add([replace(record, fingerprint=f"k-{i:06d}")], models)
            if i == 20:
                ready.set()


def _record_and_models(result):
    rec = rc.stored_calibration(result, "SN-1", robot_type="arm", at="2026-01-01")
    return rec, [_store.model_document(result.nominal_model), _store.model_document(result.calibrated_model)]


def test_two_processes_recording_500_each_lose_and_duplicate_nothing(location, campaign):
    rec, models = _record_and_models(campaign[2])
    rc.open_store(location, create=True).close()
    ctx = mp.get_context("fork")
    start = ctx.Event()
    procs = [ctx.Process(target=_writer, args=(location, rec, models, tag, 500, start)) for tag in ("a", "b")]
    for p in procs:
        p.start()
    start.set()
    for p in procs:
        p.join(300)
    assert [p.exitcode for p in procs] == [0, 0]
    with rc.open_store(location) as store:
        cals = store.calibrations("SN-1")
    tags = [c.fingerprint for c in cals]
    assert len(tags) == 1000 and len(set(tags)) == 1000 and len({c.id for c in cals}) == 1000
    assert sorted(tags) == sorted([f"{t}-{i:04d}" for t in "ab" for i in range(500)])


def test_a_process_killed_while_recording_leaves_whole_records_only(location, campaign):
    rec, models = _record_and_models(campaign[2])
    rc.open_store(location, create=True).close()
    ctx = mp.get_context("fork")
    ready = ctx.Event()
    p = ctx.Process(target=_recorder, args=(location, rec, models, ready))
    p.start()
    assert ready.wait(120)
    time.sleep(0.05 + 0.1 * np.random.default_rng().random())
    os.kill(p.pid, signal.SIGKILL)
    p.join()
    assert p.exitcode == -signal.SIGKILL
    with rc.open_store(location, create=True) as store:
        cals = store.calibrations("SN-1")              # every row decodes: no partial record
        n = len(cals)
        assert n > 20 and [c.fingerprint for c in cals] == [f"k-{i:06d}" for i in range(n)]
        assert all(len(c.estimates) == len(rec.estimates) and store.model(c.calibrated_model) for c in cals[-3:])
        with store._db.transaction(write=False) as cur:
            orphans = store._execute(cur, "SELECT COUNT(*) FROM robocal_models WHERE sha256 NOT IN "
                                          "(SELECT nominal_model FROM robocal_calibrations UNION "
                                          "SELECT calibrated_model FROM robocal_calibrations)").fetchone()[0]
        assert orphans == 0
        store.add([replace(rec, fingerprint="after")], models)
        assert len(store.calibrations("SN-1")) == n + 1


# -- changes between calibrations -------------------------------------------------------------------

def _drawn_history(result, rng, drift=None):
    """Two calibrations of one robot: estimates drawn about the same truth with the result's
    covariance; ``drift`` (name, size in combined standard deviations) moves one between them."""
    base = rc.stored_calibration(result, "R", at="2026-01-01")
    std = np.array([p.std for p in result.parameters])
    truth = np.array([p.estimate for p in result.parameters])
    cals = []
    for k, at in enumerate(("2026-01-01T00:00:00+00:00", "2026-06-01T00:00:00+00:00")):
        x = rng.multivariate_normal(truth, result.covariance)
        if drift and k == 1:
            j = result.parameter_names.index(drift[0])
            x[j] += drift[1] * np.sqrt(2) * std[j]
        cals.append(replace(base, calibrated_at=at, id=k + 1,
                            estimates=tuple(e._replace(estimate=float(v)) for e, v in zip(base.estimates, x))))
    return cals


def test_unchanged_robots_name_a_change_in_at_most_5_percent(campaign):
    rng = np.random.default_rng(7)
    named = [any(c.named for c in rc.judge_changes(_drawn_history(campaign[2], rng))[0]) for _ in range(100)]
    assert sum(named) <= 5


def _gain(result, name):
    """How much the correlations sharpen the test of ``name`` moving alone: sqrt((C^-1)_jj C_jj)
    over the judged parameters (each calibration of a drawn history has the same covariance)."""
    idx = [i for i, p in enumerate(result.parameters) if p.family in rc.JUDGED_FAMILIES]
    C = result.covariance[np.ix_(idx, idx)]
    j = [result.parameters[i].name for i in idx].index(name)
    return float(np.sqrt(np.linalg.inv(C)[j, j] * C[j, j]))


def test_a_drift_of_3_std_is_named_as_often_as_its_size_allows(campaign):
    from scipy.stats import norm

    result = campaign[2]
    rng = np.random.default_rng(3)
    for size, at_least in ((3.0, 0.8), (5.0, 0.95)):
        hits, wrong = 0, 0
        for _ in range(100):
            changes, threshold = rc.judge_changes(_drawn_history(result, rng, ("j3.d", size)))
            named = [c.name for c in changes if c.named]
            hits += "j3.d" in named
            wrong += bool(set(named) - {"j3.d"})
        mean = size * _gain(result, "j3.d")          # the test statistic's mean under this drift
        power = norm.sf(threshold - mean) + norm.cdf(-threshold - mean)
        assert abs(hits / 100 - power) < 0.12, (size, hits, power)
        assert hits >= 100 * at_least and wrong <= 10, (size, hits, wrong)


def test_an_overall_test_names_a_change_spread_over_every_parameter(campaign):
    from scipy.stats import chi2, ncx2

    result = campaign[2]
    rng = np.random.default_rng(11)
    idx = [i for i, p in enumerate(result.parameters) if p.family in rc.JUDGED_FAMILIES]
    C = 2 * result.covariance[np.ix_(idx, idx)]
    overall, either = 0, 0
    for _ in range(100):
        cals = _drawn_history(result, rng)
        step = rng.normal(0, 1, len(idx))
        step *= 5.0 / np.sqrt(step @ np.linalg.solve(C, step))      # 5 standard deviations in all, spread
        b = cals[1]
        x = np.array([e.estimate for e in b.estimates])
        x[idx] += step
        cals[1] = replace(b, estimates=tuple(e._replace(estimate=float(v)) for e, v in zip(b.estimates, x)))
        overall += rc.judge_overall(cals)[0].named
        either += rc.judge_overall(cals)[0].named or any(c.named for c in rc.judge_changes(cals)[0])
    (o,) = rc.judge_overall(_drawn_history(result, rng))
    assert o.dof == len(idx) and 0 <= o.p <= 1
    power = ncx2.sf(chi2.isf(0.05 * _store.OVERALL_SHARE, len(idx)), len(idx), 25.0)    # noncentrality 5 ** 2
    assert abs(overall / 100 - power) < 0.12 and either >= overall, (overall, power, either)


def test_a_singular_combined_covariance_is_judged_on_the_directions_it_identifies(campaign):
    base = rc.stored_calibration(campaign[2], "R", at="2026-01-01")
    est = tuple(rc.Estimate(n, "m", "frames", 0.0, 0.0, 1e-4) for n in ("j1.d", "j2.d", "j3.d"))
    corr = np.array([[1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, 1.0]])    # j1.d and j2.d one direction
    rng = np.random.default_rng(2)
    named, hits = 0, 0
    for k in range(200):
        x0, x1 = rng.normal(0, 1e-4, (2, 2))
        a = replace(base, id=1, estimates=tuple(e._replace(estimate=float(v)) for e, v in zip(est, [x0[0], x0[0],
                                                                                                  x0[1]])),
                    correlation=corr)
        moved = x1[1] + (6 * np.sqrt(2) * 1e-4 if k % 2 else 0.0)
        b = replace(a, id=2, calibrated_at="2026-06-01T00:00:00+00:00",
                    estimates=tuple(e._replace(estimate=float(v)) for e, v in zip(est, [x1[0], x1[0], moved])))
        changes, threshold = rc.judge_changes([a, b])
        (o,) = rc.judge_overall([a, b])
        assert o.dof == 2 and np.isfinite(threshold) and all(np.isfinite(c.sigma) for c in changes)
        if k % 2:
            hits += [c.name for c in changes if c.named] == ["j3.d"]
        else:
            named += any(c.named for c in changes) or o.named
    assert named <= 10 and hits >= 95, (named, hits)


def _judged_through_the_store(location, result, histories, prefix):
    """Each drawn history recorded as a robot of its own, then judged by ``rc.history``."""
    models = [rc.model_document(result.nominal_model), rc.model_document(result.calibrated_model)]
    recs = [replace(c, robot=f"{prefix}{i:03d}", id=None, fingerprint=f"{i}-{k}")
            for i, cals in enumerate(histories) for k, c in enumerate(cals)]
    with rc.open_store(location, create=True) as store:
        store.add(recs, models)
        return [rc.history(store, f"{prefix}{i:03d}") for i in range(len(histories))]


def test_judged_through_either_back_end_unchanged_robots_name_nothing_and_moves_are_named(location, campaign):
    from scipy.stats import norm

    result = campaign[2]
    rng = np.random.default_rng(17)
    unchanged = _judged_through_the_store(location, result, [_drawn_history(result, rng) for _ in range(100)],
                                          "U")
    assert sum(bool(h.changes) or any(o.named for o in h.overall) for h in unchanged) <= 5
    for name in ("j5.theta", "j3.d"):
        moved = _judged_through_the_store(location, result, [_drawn_history(result, rng, (name, 3.0))
                                                             for _ in range(100)], name)
        hits = sum(name in [c.name for c in h.changes] for h in moved)
        mean = 3.0 * _gain(result, name)
        power = norm.sf(moved[0].threshold - mean)
        assert abs(hits / 100 - power) < 0.12, (name, hits, power)


def test_without_correlations_a_change_is_its_difference_over_the_combined_std(campaign):
    cals = [replace(c, correlation=None) for c in _drawn_history(campaign[2], np.random.default_rng(1))]
    changes, threshold = rc.judge_changes(cals)
    a, b = cals
    for c in changes:
        s = np.hypot(a.estimate(c.name).std, b.estimate(c.name).std)
        assert c.sigma == pytest.approx(c.delta / s) and c.shift == pytest.approx(c.delta)
    assert threshold == pytest.approx(rc.sidak_threshold(0.05 * (1 - _store.OVERALL_SHARE), len(changes)))


def test_a_change_reads_in_display_units_with_its_sigma(campaign):
    rng = np.random.default_rng(0)
    cals = _drawn_history(campaign[2], rng, ("j2.theta", 40.0))
    assert cals[0].correlation is not None
    with_drift = rc.judge_changes(cals)[0]
    (c,) = [c for c in with_drift if c.name == "j2.theta"]
    assert c.named and c.since == "2026-01-01T00:00:00+00:00"
    line = rc.change_line(c)
    assert line.startswith("j2.theta +") and line.endswith(f"since 2026-01-01, {abs(c.sigma):.1f} sigma")
    assert f"{np.degrees(c.delta):.5f}".lstrip("-") in line


def test_calibrations_of_other_parameters_are_compared_as_each_would_hold_the_others(cli, tmp_path):
    """The same campaign calibrated with compliance, then without: the geometric calibration's
    estimates carry the compliances it leaves out (the elbow's, 8 standard deviations from zero), so
    comparing the estimates as they are named changes of a robot that did not change (j2.d and
    j2.theta, and something changed at p = 7e-38). The one with compliance is taken to it held at
    nominal (conditioned on its covariance): the same data then agree to rounding. Without stored
    correlations that cannot be done, and the two are not compared; record and history say why."""
    model = arm6r(masses=True)
    _, data = rc.simulate(model, 60, parameters=("geometric", "compliance"), compliance_error=(2e-6, 6e-6), seed=3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        both = rc.calibrate(model, data, parameters=("geometric", "compliance"))
        geo = rc.calibrate(model, data)
    pair = [replace(rc.stored_calibration(both, "R", at="2026-01-01"), id=1),
            replace(rc.stored_calibration(geo, "R", at="2026-06-01"), id=2)]
    assert not any(c.named for c in rc.judge_changes(pair)[0])
    (o,) = rc.judge_overall(pair)
    assert o.compared and o.dof > 10 and o.chi2 < 1e-2, o
    apart = {p.name for p in both.parameters
             if p.family == "compliance" and abs(p.estimate - p.nominal) > _store.APART_SIGMAS * p.std}
    bare = [replace(c, correlation=None) for c in pair]
    (o,) = rc.judge_overall(bare)
    assert not o.compared and not o.named and apart and set(o.apart) == apart
    assert not any(c.named for c in rc.judge_changes(bare)[0])
    # through the command line, the result files keep the correlations
    for name, result in (("both", both), ("geo", geo)):
        rc.io.write_result(result, tmp_path / f"{name}.json")
    store = tmp_path / "store.sqlite"
    assert cli("record", tmp_path / "both.json", "--robot", "R", "--store", store, "--at", "2026-01-01")[0] == 0
    code, out, err = cli("record", tmp_path / "geo.json", "--robot", "R", "--store", store, "--at", "2026-06-01")
    assert code == 0 and "changes since the previous calibration: none beyond" in out, out + err
    from robocal.report import history_summary

    with rc.open_store(store) as opened:
        h = rc.history(opened, "R")
    said = history_summary(replace(h, overall=(o,))).split("changes between consecutive")[1]
    assert "none among the calibrations compared" in said and "not compared with 2026-01-01: j3.k_theta" in said


def test_a_robot_of_a_type_calibrated_with_more_parameters_is_compared_as_it_would_hold_them(location):
    """Six campaigns of one elastic robot, five calibrated geometric and one with compliance: the
    five's estimates carry the compliance they leave out, so the sixth stood out of its type
    (j2.theta -6.2, j2.d 3.5 robust sigmas). It is now compared with its compliances held at nominal
    (conditioned on its covariance); without stored correlations it is left out and said so. The
    store's comparison (``history --type``) is the same: it read no correlations and held nothing."""
    from robocal.report import type_summary

    model = arm6r(masses=True)
    true, _ = rc.simulate(model, 10, parameters=("geometric", "compliance"), compliance_error=(2e-6, 6e-6), seed=3)
    cals = []
    with warnings.catch_warnings(), rc.open_store(location, create=True) as store:
        warnings.simplefilter("ignore")
        for i in range(6):
            data = rc.sim.measure(true, rc.random_configurations(model, 60, np.random.default_rng(100 + i)),
                                  noise=2e-5, rng=i)
            res = rc.calibrate(model, data, parameters=("geometric", "compliance") if i == 2 else ("geometric",))
            cals.append(replace(rc.stored_calibration(res, f"R{i}", at="2026-01-01"), id=i + 1))
            store.record(res, f"R{i}", robot_type="arm", at="2026-01-01")
        stored = rc.type_comparison(store, "arm")
    t = rc.compare_type("arm", cals)
    assert t.outliers == () and [r for r, _ in t.held] == ["R2"] and t.apart == ()
    assert stored.held == t.held and stored.outliers == () and np.allclose(stored.z, t.z, equal_nan=True)
    if location.endswith(".sqlite"):     # the store reads R2's correlations only to hold its compliances
        with sqlite3.connect(location) as db:
            db.execute("UPDATE robocal_calibrations SET correlation = x'00112233' WHERE robot = 'R2'")
        with rc.open_store(location) as store, pytest.raises(rc.InputError, match="calibration #3: 4 bytes"):
            rc.type_comparison(store, "arm")
    assert all(n.split(".")[1].startswith("k_") for n in t.held[0][1]) and not any(".k_" in n for n in t.names)
    assert "R2: #3 2026-01-01" in type_summary(t) and "held at nominal" in type_summary(t)
    bare = rc.compare_type("arm", [replace(c, correlation=None) for c in cals])
    assert bare.outliers == () and [r for r, _ in bare.apart] == ["R2"] and np.isnan(bare.values[2]).all()
    assert "R2" in type_summary(bare) and "not compared" in type_summary(bare)


def test_what_was_not_compared_is_said_so_and_a_family_not_calibrated_is_not_called_weak(campaign, tmp_path):
    """Robots of one type, two calibrated with compliance and two geometric. Of two robots nothing is
    compared (fewer than three hold each parameter): history --type printed "named beyond 1.96 (0
    comparisons...)" and said the geometric robot "holds j2.k_theta ... at nominal (weak for its
    poses), which most of the type's calibrations identify", one of two. Of three, the geometric one's
    compliances are said not calibrated. Of four, two and two: "most" counted half, so the two with
    compliance were held against themselves alone, and neither was compared at all. A history of one
    calibration printed "judged at 2.05 sigma (0 comparisons...)"."""
    from robocal.report import history_summary, type_summary

    model = arm6r(masses=True)
    true, _ = rc.simulate(model, 10, parameters=("geometric", "compliance"), compliance_error=(2e-6, 6e-6), seed=3)
    cals = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for i, families in enumerate((("geometric", "compliance"), ("geometric",)) * 2):
            data = rc.sim.measure(true, rc.random_configurations(model, 60, np.random.default_rng(200 + i)),
                                  noise=2e-5, rng=i)
            cals.append(replace(rc.stored_calibration(rc.calibrate(model, data, parameters=families), f"R{i}",
                                                      at="2026-01-01"), id=i + 1))
    pair = rc.compare_type("arm", cals[:2])
    text = type_summary(pair)
    assert pair.compared == 0 and "nothing compared" in text and "and the type has 2" in text
    assert "comparisons" not in text and "weak" not in text and "most" not in text
    three = rc.compare_type("arm", cals[:3])
    text = type_summary(three)
    assert three.compared > 0 and [r for r, _ in three.uncalibrated] == ["R1"]
    lines = {line.split(":")[0].strip(): line for line in text.splitlines() if line.startswith("  R")}
    assert "(their family not calibrated) at nominal" in lines["R1"] and "weak" not in lines["R1"]
    # the two with compliance: three robots identify what they do, their median is no reference
    assert [bool(np.isfinite(row).any()) for row in three.z] == [False, True, False]
    assert all("not compared: fewer than three" in lines[r] for r in ("R0", "R2"))
    four = rc.compare_type("arm", cals)
    assert all(np.isfinite(row).any() for row in four.z), four.z     # every robot compared
    assert sorted(r for r, _ in four.held) == ["R0", "R2"] and four.conditioned == ()
    with rc.open_store(tmp_path / "s.sqlite", create=True) as store:
        store.record(campaign[2], "SN-1")
        text = history_summary(rc.history(store, "SN-1"))
    assert "changes between consecutive calibrations: nothing compared (one calibration" in text
    assert "comparisons" not in text and "judged at" not in text


def test_robots_of_a_type_side_by_side_name_the_one_that_stands_out(location, campaign):
    result = campaign[2]
    rng = np.random.default_rng(5)
    with rc.open_store(location, create=True) as store:
        rec, models = _record_and_models(result)
        recs = []
        for i in range(12):
            x = rng.multivariate_normal([p.estimate for p in result.parameters], result.covariance)
            if i == 7:
                x[result.parameter_names.index("j2.d")] += 2e-3     # 2 mm off its type
            recs.append(replace(rec, robot=f"R{i:02d}", fingerprint=f"f{i}",
                                estimates=tuple(e._replace(estimate=float(v)) for e, v in zip(rec.estimates, x))))
        store.add(recs, models)
        store.add([replace(recs[7], robot="other", robot_type="scara", fingerprint="x")], models)
        t = rc.type_comparison(store, "arm")
    assert t.robots == tuple(f"R{i:02d}" for i in range(12))
    assert [(o.robot, o.name) for o in t.outliers] == [("R07", "j2.d")]
    assert t.z.shape == (12, len(t.names)) and "base.x" not in t.names


# -- verification -----------------------------------------------------------------------------------

def _drifted(true, name="j3.d", by=3e-4):
    lay = rc.parameter_names(true)
    p = rc.parameter_vector(true)
    p[lay.index(name)] += by
    return rc.model_from_vector(true, p)


def test_a_verification_of_copied_rows_is_refused(campaign):
    """Fifteen copies of one measured pose, relabelled, were judged as fifteen points "within accuracy"."""
    model, true, result = campaign
    then = rc.accuracy_at_calibration(rc.io.result_to_dict(result))
    data = rc.measure(true, rc.random_configurations(model, 12, 3), noise=2e-5, rng=3)
    assert rc.verify(result.calibrated_model, data, then).n_points == 12
    copied = replace(data.subset(np.zeros(15, dtype=int)), labels=tuple(f"V{i}" for i in range(15)))
    with pytest.raises(rc.DegenerateDataError, match="14 of 15 poses repeat an earlier one exactly"):
        rc.verify(result.calibrated_model, copied, then)


def test_verification_says_recalibrate_after_a_drift_of_0_3_mm_and_within_otherwise(campaign):
    model, true, result = campaign
    then = rc.accuracy_at_calibration(_store.result_to_dict(result))
    drifted = _drifted(true)
    rng = np.random.default_rng(11)
    verdicts = {"true": [], "drifted": []}
    for _seed in range(100):
        q = rc.random_configurations(model, 20, rng)
        for key, robot in (("true", true), ("drifted", drifted)):
            data = rc.measure(robot, q, noise=2e-5, rng=rng)
            verdicts[key].append(rc.verify(result.calibrated_model, data, then).verdict)
    assert verdicts["true"].count("within accuracy") >= 95
    assert verdicts["drifted"].count("recalibrate") >= 95


def test_a_robot_calibrated_from_seatings_is_verified_with_a_few_seatings():
    """Three sockets seated eight times each on a new placement of the plate, held against the
    calibration's held-out seatings (each one's distance from its socket's mean predicted centre).
    Placements seat with a scatter of their own (the configurations that reach them): an F test on
    the seatings alone told an unchanged robot to recalibrate in 13 of 100 verifications, one that
    takes the calibration's placements' scatter in 0 of 100; a link 0.3 mm longer, 100 of 100."""
    from robocal.sim import socket_campaign

    arm7 = rc.read_model(ROOT / "examples" / "arm7" / "model.yaml")
    true = rc.perturb_model(arm7, rc.identifiability(arm7, parameters=("frames", "markers")).identified, rng=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = rc.calibrate(arm7, contacts=socket_campaign(true, placements=4, poses_per_socket=20,
                                                              joint_noise=2e-5, rng=0))
    then = rc.accuracy_at_calibration(_store.result_to_dict(result))
    assert then.source == "held-out seatings, each from its socket's centre" and then.sets == 4
    # the RMS over the degrees of freedom the 12 sockets' centres leave
    d = np.concatenate([np.asarray(v) for v in result.contacts.held_out.seatings.values()])
    assert d.size == 240 and then.n == 228 and then.rms == pytest.approx(np.sqrt(np.sum(d ** 2) / 228))
    p = rc.parameter_vector(true)
    p[rc.parameter_names(true).index("j3.r")] += 3e-4
    drifted = rc.model_from_vector(true, p)
    verdicts = {"true": [], "drifted": []}
    for k in range(40):
        for key, robot in (("true", true), ("drifted", drifted)):
            seated = socket_campaign(robot, placements=1, poses_per_socket=8, joint_noise=2e-5,
                                     rng=1000 * (key == "true") + k)
            v = rc.verify(result.calibrated_model, seated, then)
            verdicts[key].append(v.verdict)
    assert v.sockets == 3 and v.n_points == 24 and len(v.poses) == 3
    assert verdicts["true"].count("within accuracy") >= 38 and verdicts["drifted"].count("recalibrate") >= 38
    with pytest.raises(rc.InputError, match="no base to register"):
        rc.verify(result.calibrated_model, seated, then, register=True)
    # beside robots of its type its accuracy says what it is of
    from robocal.report import type_summary

    alone = rc.compare_type("arm7", [replace(rc.stored_calibration(result, "A7"), id=1)])
    assert f"{then.rms * 1e3:.4f} mm RMS (held-out seatings" in type_summary(alone)


def test_a_socket_seated_once_is_named_as_left_out_of_a_verification(cli, tmp_path):
    """A socket seated once cannot show consistency (its one seating is its socket's centre), and
    verify left it out without a word: three sockets seated, a verdict on two, nothing said."""
    import shutil

    store = tmp_path / "s.sqlite"
    code, _, _ = cli("calibrate", ROOT / "examples/arm7/model.yaml", "--contacts", ROOT / "examples/arm7/seatings",
                     "--out", tmp_path / "kit", "--record", "A7", "--store", store)
    assert code == 0
    check = tmp_path / "check"
    shutil.copytree(ROOT / "examples/arm7/seatings_check", check)
    hole = check / "P4" / "hole_2.csv"
    seatings = hole.read_text().splitlines()
    assert len(seatings) == 8
    hole.write_text(seatings[0] + "\n")
    code, out, _ = cli("verify", "A7", "--contacts", check, "--store", store, "--no-record")
    lines = out.splitlines()
    assert code == 0 and "16 seatings in 2 sockets" in lines[0]
    assert lines[1] == ("  left out: socket P4/hole_2, seated once: one seating cannot show consistency (it is its "
                        "socket's centre)")
    assert sum("left out" in line for line in lines) == 1


@pytest.fixture(scope="module")
def arm7_kit():
    """A simulated 7-joint arm (examples/arm7), a socket plate at 4 placements (20 seatings per
    socket) and 30 tracker points of it: (model, true robot, sockets, points)."""
    from robocal.sim import socket_campaign

    arm7 = rc.read_model(ROOT / "examples" / "arm7" / "model.yaml")
    rng = np.random.default_rng(5)
    true = rc.perturb_model(arm7, rc.identifiability(arm7).identified, rng=rng)
    points = rc.measure(true, rc.random_configurations(arm7, 30, rng), noise=2e-5, rng=rng)
    sockets = socket_campaign(true, placements=4, poses_per_socket=20, joint_noise=2e-5, rng=rng)
    return arm7, true, sockets, points


def _verdicts(store, robot, true, changed, model, n=40, **kwargs):
    """(within accuracy of the unchanged robot, recalibrate of the changed one) over ``n`` verifications
    of 20 tracker poses each."""
    rng = np.random.default_rng(21)
    counts = [0, 0]
    for _ in range(n):
        q = rc.random_configurations(model, 20, rng)
        for k, (robot_now, says) in enumerate(((true, "within accuracy"), (changed, "recalibrate"))):
            v, _ = rc.verify_robot(store, robot, rc.measure(robot_now, q, noise=2e-5, rng=rng), save=False, **kwargs)
            counts[k] += v.verdict == says
    return counts


def test_tracker_points_and_seatings_together_are_verified_each_against_its_own_accuracy(arm7_kit, tmp_path):
    """A calibration from tracker points and a socket plate together: its accuracy in use mixes the
    240 held-out seatings' distances with the 30 points' errors. Held against that mixture, 20 new
    tracker poses of the same robot said "recalibrate" (ratio 1.35 against 1.22); held against the
    points' own cross-validated errors they are within accuracy, and the seatings against the
    seatings' own."""
    from robocal.sim import socket_campaign

    arm7, true, sockets, points = arm7_kit
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = rc.calibrate(arm7, points, contacts=sockets)
    rec = rc.stored_calibration(result, "T-02")
    assert rec.accuracy.n == 30 and rec.accuracy.source == "fitted poses held out, 5 folds drawn at random"
    assert rec.accuracy.rms == pytest.approx(result.in_use.measured_points.rms)
    assert rec.seatings_accuracy == rc.accuracy_at_calibration(rc.io.result_to_dict(result), seatings=True)
    assert rec.seatings_accuracy.source == "held-out seatings, each from its socket's centre"
    with rc.open_store(tmp_path / "s.sqlite", create=True) as store:
        back = replace(store.record(result, "T-02"), recorded_at=rec.recorded_at)
        (read,) = store.calibrations("T-02")
        assert (read.accuracy, read.seatings_accuracy) == (rec.accuracy, rec.seatings_accuracy) == \
            (back.accuracy, back.seatings_accuracy)
        within, named = _verdicts(store, "T-02", true, _drifted(true, "j3.r"), arm7)
        assert within >= 38 and named >= 38, (within, named)
        seated = socket_campaign(true, placements=1, poses_per_socket=8, joint_noise=2e-5, rng=99)
        v, kept = rc.verify_robot(store, "T-02", seated)
        assert v.verdict == "within accuracy" and v.then == rec.seatings_accuracy and kept.sockets == 3
        text = rc.history_summary(rc.history(store, "T-02"))
    assert "worst socket spread" in text and f"{rec.seatings_accuracy.rms * 1e3:.4f} mm RMS (held-out seatings" in text


def test_a_figure_within_the_instruments_noise_is_said_so_and_a_tracker_validation_verifies(arm7_kit, tmp_path):
    """Sockets to calibrate, 30 tracker points to judge it, base and tool registered on them: their
    errors are within the instrument's noise, which the accuracy in use once said as "0 mm after (95 %
    within 0 mm, max 0 mm)", the store as "in use 0.0000 mm RMS", and verify with tracker points was
    refused ("the calibration's accuracy is of seatings") although the points judged it."""
    arm7, true, sockets, points = arm7_kit
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = rc.calibrate(arm7, contacts=sockets, validation=points)
    use = result.in_use
    assert use.method == "validation, base and tool registered on it" and use.position_after.rms == 0
    noise = f"within the instrument's noise of {use.noise * 1e3:.4g} mm RMS"
    assert use.noise == pytest.approx(np.sqrt(3) * 2e-5, rel=0.3)
    check = next(c for c in result.checks if c.name == "accuracy in use")
    assert f"{noise} after on 30 held-out point(s)" in check.summary and " 0 mm" not in check.summary
    from robocal.report import calibration_summary

    assert any(line.split() == ["after", *noise.split()] for line in calibration_summary(result).splitlines())
    rec = rc.stored_calibration(result, "T-01")
    # the held-out points' errors as measured, over the degrees of freedom base and tool left (9 of 90)
    assert rec.accuracy.source.startswith("held-out poses with base and tool registered on them")
    assert rec.accuracy.rms == pytest.approx(result.stats.validation_after.rms * np.sqrt(90 / 81))
    assert rec.accuracy.n == 27 and rec.seatings_accuracy.source == "held-out seatings, each from its socket's centre"
    with rc.open_store(tmp_path / "s.sqlite", create=True) as store:
        store.record(result, "T-01")
        # the base the sockets leave free is the tracker's to place: registered on the poses
        assert store.calibrations("T-01")[0].frame_unfixed
        within, named = _verdicts(store, "T-01", true, _drifted(true, "j3.r"), arm7)
        assert within >= 38 and named >= 38, (within, named)
        text = rc.history_summary(rc.history(store, "T-01"))
    assert f"in use {noise}" in text and "0.0000 mm" not in text


def test_fitted_points_within_the_instruments_noise_are_said_so(campaign):
    """Simulated points fitted below their stated noise: "0 mm on the fitted ones" read as a perfect fit."""
    use = campaign[2].in_use
    assert use.fit_after.rms == 0 and use.noise > 0
    check = next(c for c in campaign[2].checks if c.name == "accuracy in use")
    assert f"; within the instrument's noise of {use.noise * 1e3:.4g} mm RMS on the fitted ones" in check.summary


def test_verification_with_the_base_re_registered_and_iso_terms(campaign):
    model, true, result = campaign
    then = rc.accuracy_at_calibration(_store.result_to_dict(result))
    moved = true.replace(base_position=tuple(np.add(true.base_position, (0.01, -0.02, 0.005))))
    q = rc.random_configurations(model, 20, np.random.default_rng(2))
    data = rc.measure(moved, np.repeat(q, 2, axis=0), noise=2e-5, rng=3, labels=[f"P{i // 2}" for i in range(40)])
    assert rc.verify(result.calibrated_model, data, then).verdict == "recalibrate"   # the tracker moved
    v = rc.verify(result.calibrated_model, data, then, register=True)
    assert v.verdict == "within accuracy" and v.registered_base and len(v.poses) == 20
    # AP_p: each pose's barycentre of its two visits against the commanded point
    reg = rc.register_base(result.calibrated_model, data)
    pred = rc.evaluate(reg, data.q).positions[:, 0]
    bary = (data.positions[0::2, 0] + data.positions[1::2, 0]) / 2
    assert v.ap == pytest.approx(np.linalg.norm(bary - pred[0::2], axis=1), abs=1e-9)
    assert v.ap_max == pytest.approx(v.ap.max())


# -- the commands -----------------------------------------------------------------------------------

def _measure_csv(tmp_path, robot, model, n=20, seed=4):
    q = rc.random_configurations(model, n, np.random.default_rng(seed))
    path = tmp_path / f"check-{seed}.csv"
    rc.write_measurements(rc.measure(robot, q, noise=2e-5, rng=seed), path, model=model)
    return path


def test_record_history_and_verify_from_the_command_line(cli, location, campaign, result_file, tmp_path):
    model, true, result = campaign
    code, out, err = cli("record", result_file, "--robot", "SN-1", "--type", "arm", "--store", location,
                         "--at", "2026-03-02T10:00:00Z")
    assert code == 0 and "recorded calibration #1 of SN-1" in out, err
    code, out, err = cli("record", result_file, "--robot", "SN-1", "--store", location, "--at", "2026-09-01")
    assert code == 0 and "changes since the previous calibration: none beyond" in out, err
    code, out, err = cli("verify", "SN-1", _measure_csv(tmp_path, true, model), "--store", location)
    assert code == 0 and out.strip().endswith("verdict: within accuracy"), out + err
    code, out, err = cli("verify", "SN-1", _measure_csv(tmp_path, _drifted(true), model, seed=5), "--store", location)
    assert code == 3 and out.strip().endswith("verdict: recalibrate"), out + err
    code, out, err = cli("history", "SN-1", "--store", location)
    assert code == 0 and "2 calibration(s), 2 verification(s)" in out and "ISO 9283 AP" in out
    assert "j3.d" in out and "none" in out.split("changes between consecutive")[1]
    code, out, err = cli("history", "--type", "arm", "--store", location)
    assert code == 0 and "type arm: 1 robot(s)" in out


def test_calibrate_record_keeps_the_result(cli, tmp_path, campaign):
    model, true, _ = campaign
    rc.write_model(model, tmp_path / "model.yaml")
    q = rc.random_configurations(model, 40, np.random.default_rng(9))
    rc.write_measurements(rc.measure(true, q, noise=2e-5, rng=9), tmp_path / "m.csv", model=model)
    store = tmp_path / "s.sqlite"
    code, out, err = cli("calibrate", tmp_path / "model.yaml", tmp_path / "m.csv", "--out", tmp_path / "o",
                         "--record", "SN-9", "--type", "arm", "--store", store)
    assert code == 0 and "recorded calibration #1 of SN-9" in out, err
    with rc.open_store(store) as s:
        (c,) = s.calibrations("SN-9")
    written = rc.read_result(tmp_path / "o" / "result.json")
    assert [e.estimate for e in c.estimates] == [p.estimate for p in written.parameters]


def test_history_report_shows_drift_and_verifications(cli, tmp_path, campaign, result_file):
    pytest.importorskip("matplotlib")
    model, true, _ = campaign
    store = tmp_path / "s.sqlite"
    for at in ("2026-01-01", "2026-02-01"):
        assert cli("record", result_file, "--robot", "R", "--store", store, "--at", at)[0] == 0
    assert cli("verify", "R", _measure_csv(tmp_path, true, model), "--store", store)[0] == 0
    code, out, err = cli("history", "R", "--store", store, "--report", tmp_path / "h.html")
    assert code == 0, err
    page = (tmp_path / "h.html").read_text()
    assert 'data-plot="drift"' in page and 'data-plot="verifications"' in page and "j3.d" in page
    assert page.count("<tr><td>#") == 2


def test_bad_input_to_the_commands_is_one_line(cli, tmp_path, result_file):
    store = tmp_path / "s.sqlite"
    code, out, err = cli("history", "R", "--store", store)
    assert_one_line_error(code, err, [str(store), "no store"], command="history")
    assert not store.exists()
    code, out, err = cli("record", result_file, "--robot", "\x07bell", "--store", store)
    assert code == 2 and len(err.strip().splitlines()) == 1 and not store.exists()
    assert cli("record", result_file, "--robot", "R", "--store", store)[0] == 0
    code, out, err = cli("history", "nobody", "--store", store)
    assert_one_line_error(code, err, ["no calibration of 'nobody'"], command="history")
    code, out, err = cli("history", "R", "--type", "t", "--store", store)
    assert_one_line_error(code, err, ["give a robot or --type"], command="history")
    (tmp_path / "bad.sqlite").write_bytes(b"SQLite format 3\x00" + b"\x13" * 3000)
    code, out, err = cli("history", "R", "--store", tmp_path / "bad.sqlite")
    assert_one_line_error(code, err, ["bad.sqlite"], command="history")
    code, out, err = cli("record", result_file, "--robot", "R", "--at", "yesterday", "--store", store)
    assert code == 2 and "--at" in err and len(err.strip().splitlines()) == 1


def test_a_postgresql_store_without_psycopg_says_which_extra(cli, monkeypatch, result_file):
    monkeypatch.setitem(sys.modules, "psycopg", None)
    code, out, err = cli("record", result_file, "--robot", "R", "--store", "postgresql://u:secret@nowhere/db")
    assert code == 1 and "store-pg" in err and "secret" not in err


def test_the_store_location_comes_from_option_environment_or_default(tmp_path):
    env = {"HOME": str(tmp_path), "XDG_DATA_HOME": str(tmp_path / "data")}
    assert rc.store_location(None, env) == str(tmp_path / "data" / "robocal" / "store.sqlite")
    assert rc.store_location(None, {**env, "ROBOCAL_STORE": "x.sqlite"}) == "x.sqlite"
    assert rc.store_location("y.sqlite", {**env, "ROBOCAL_STORE": "x.sqlite"}) == "y.sqlite"
    assert _store.shown_location("postgresql://u:pw@h/db") == "postgresql://u:***@h/db"


def test_a_verification_holds_the_robot_against_its_latest_calibration_that_did_not_fail(location, campaign):
    model, true, result = campaign
    rec, models = _record_and_models(result)
    with rc.open_store(location, create=True) as store:
        good, bad = store.add([rec, replace(rec, verdict="fail", calibrated_at="2026-02-01T00:00:00+00:00",
                                            calibrated_model=rec.nominal_model)], models)
        assert rc.latest_usable(store, "SN-1").id == good
        data = rc.measure(true, rc.random_configurations(model, 20, np.random.default_rng(1)), noise=2e-5, rng=1)
        v, stored = rc.verify_robot(store, "SN-1", data)
        assert stored.calibration_id == good and v.verdict == "within accuracy"
        (back,) = store.verifications("SN-1")
        assert back == replace(stored, id=back.id) and back.id is not None
        store.add([replace(rec, robot="SN-2", verdict="fail")], models)
        with pytest.raises(rc.InputError, match="failed its checks"):
            rc.latest_usable(store, "SN-2")


def test_contacts_of_other_kinds_are_named_as_left_out_of_a_verification(cli, tmp_path):
    """A verification judges socket seatings only: plane contacts recorded beside them were dropped
    without a word; now each group left out is named with its kind and its contacts."""
    code, _, _ = cli("calibrate", ROOT / "examples/arm7/model.yaml", "--contacts", ROOT / "examples/arm7/seatings",
                     "--out", tmp_path / "kit")
    assert code == 0
    model = rc.read_model(tmp_path / "kit" / "calibrated.yaml")
    then = rc.accuracy_at_calibration(json.loads((tmp_path / "kit" / "result.json").read_text()))
    check = rc.io.read_contacts(ROOT / "examples/arm7/seatings_check", model)
    table = check.q[:3]
    with_plane = replace(check, q=np.vstack([check.q, table]), marker=check.marker + ("ball",) * 3,
                         kind=check.kind + ("plane",) * 3, target=check.target + ("table",) * 3,
                         placement=check.placement + ("",) * 3, sigma=np.r_[check.sigma, check.sigma[:3]],
                         labels=check.labels + ("t1", "t2", "t3"))
    alone, both = rc.verify(model, check, then), rc.verify(model, with_plane, then)
    assert alone.left_out == ()
    assert both.left_out == ("plane table, 3 contact(s): a verification judges socket seatings only",)
    assert both.ratio == alone.ratio and both.n_points == alone.n_points
