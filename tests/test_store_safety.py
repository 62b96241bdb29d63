"""The store as a neighbour: a command that records checks the store before it writes anything and
writes its files and its record as one outcome; the store opens only its own databases, reads
without write access and changes no other file; unknown URL schemes are refused."""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import select
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_one_line_error
from robots import arm6r

import robocal as rc


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    """A model file, a measurement file and a result file of a simulated arm."""
    folder = tmp_path_factory.mktemp("safety")
    model = arm6r()
    true, data = rc.simulate(model, 30, seed=3, noise=2e-5)
    rc.write_model(model, folder / "model.yaml")
    rc.write_measurements(data, folder / "m.csv", model=model)
    rc.io.write_result(rc.calibrate(model, data), folder / "result.json")
    return folder


def _count(store: Path) -> int:
    c = sqlite3.connect(store)
    try:
        return c.execute("SELECT count(*) FROM robocal_calibrations").fetchone()[0]
    finally:
        c.close()


def _damage(store: Path, sql: str) -> None:
    c = sqlite3.connect(store)
    try:
        c.execute(sql)
        c.commit()
    finally:
        c.close()


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _beside(path: Path) -> list[str]:
    return sorted(p.name for p in path.parent.iterdir() if p.name.startswith(path.name))


@contextlib.contextmanager
def _read_only(path: Path):
    """``path`` (a file or a folder) that this process cannot write: its write bits off, and for
    root, who writes anyway, the immutable attribute."""
    mode = path.stat().st_mode
    path.chmod(mode & 0o555)
    marked = os.geteuid() == 0 and subprocess.run(["chattr", "+i", str(path)], capture_output=True).returncode == 0
    try:
        if os.access(path, os.W_OK):
            pytest.skip("this system lets the test's user write a read-only path")
        yield path
    finally:
        if marked:
            subprocess.run(["chattr", "-i", str(path)], check=True)
        path.chmod(mode)


def _calibrate(cli, folder, out, store, *more):
    return cli("calibrate", folder / "model.yaml", folder / "m.csv", "--out", out, "--record", "SN-1",
               "--store", store, *more)


# -- item 2: the files and the record, both or neither ---------------------------------------------------

def test_an_unusable_store_leaves_no_calibration_files(cli, campaign, tmp_path):
    foreign = tmp_path / "other.db"
    _damage(foreign, "CREATE TABLE accounts (id INTEGER)")
    code, _, err = _calibrate(cli, campaign, tmp_path / "run", foreign)
    assert_one_line_error(code, err, [str(foreign), "something else"], tmp_path / "run")
    code, _, err = _calibrate(cli, campaign, tmp_path / "run", "mysql://cal@plant/robocal")
    assert_one_line_error(code, err, ["mysql", "postgresql://"], tmp_path / "run")


def test_a_store_that_cannot_take_the_record_fails_calibrate_before_its_work(cli, campaign, tmp_path):
    """A result file or another application's database given as the store: calibrate --record ran
    the whole calibration and printed its summary, then failed; now it fails before the work."""
    foreign = tmp_path / "other.db"
    _damage(foreign, "CREATE TABLE accounts (id INTEGER)")
    before = _digest(foreign)
    for store, words in ((foreign, "something else"), (campaign / "result.json", "a robocal result file")):
        code, out, err = _calibrate(cli, campaign, tmp_path / "run", store)
        assert_one_line_error(code, err, [str(store), words], tmp_path / "run")
        assert out == "", out       # no calibration ran
    assert _digest(foreign) == before
    # a store not made yet is made by the record; --at dates it
    code, out, err = _calibrate(cli, campaign, tmp_path / "run", tmp_path / "new" / "s.sqlite", "--at", "2026-03-02")
    assert code == 0 and "recorded calibration #1 of SN-1 (2026-03-02T00:00:00+00:00" in out, err
    for option, value in (("--at", "2026-03-02"), ("--type", "arm"), ("--store", str(foreign))):
        code, _, err = cli("calibrate", campaign / "model.yaml", campaign / "m.csv", "--out", tmp_path / "x",
                           option, value)
        assert_one_line_error(code, err, [option, "needs --record"], tmp_path / "x")


def test_a_result_that_cannot_be_recorded_leaves_no_new_store(cli, campaign, tmp_path):
    """A result whose date is no date is refused before the store is made: 5855dae left a new, empty
    store behind the error (found by fuzzing record)."""
    doc = json.loads((campaign / "result.json").read_text())
    doc["provenance"]["date"] = -1
    (tmp_path / "result.json").write_text(json.dumps(doc))
    (tmp_path / "result.npz").write_bytes((campaign / "result.npz").read_bytes())
    store = tmp_path / "new" / "s.sqlite"
    code, _, err = cli("record", tmp_path / "result.json", "--robot", "SN-1", "--store", store)
    assert_one_line_error(code, err, ["provenance.date", "ISO 8601"], tmp_path / "new", command="record")


def test_a_damaged_earlier_record_is_reported_and_nothing_is_written(cli, campaign, tmp_path):
    store = tmp_path / "s.sqlite"
    assert cli("record", campaign / "result.json", "--robot", "SN-1", "--store", store, "--at", "2026-01-01")[0] == 0
    _damage(store, "UPDATE robocal_calibrations SET checks = '{not json' WHERE id = 1")
    before = _digest(store)
    code, _, err = _calibrate(cli, campaign, tmp_path / "run", store)
    assert_one_line_error(code, err, [str(store), "calibration #1", "damaged"], tmp_path / "run")
    code, _, err = cli("record", campaign / "result.json", "--robot", "SN-1", "--store", store)
    assert_one_line_error(code, err, [str(store), "calibration #1", "damaged"], command="record")
    assert _digest(store) == before and _count(store) == 1


@pytest.mark.parametrize("command", ["record", "calibrate", "calibrate failing"])
def test_earlier_records_unreadable_after_the_commit_only_warn(cli, campaign, tmp_path, monkeypatch, command):
    """Reading the robot's history after the record commits (for the changes since the previous
    calibration) can no longer fail the command: the record stays, a warning says why the changes
    are not shown, and the exit is the calibration's (0 passed, 3 failed its checks)."""
    store = tmp_path / "s.sqlite"
    assert cli("record", campaign / "result.json", "--robot", "R", "--store", store, "--at", "2026-01-01")[0] == 0

    def damaged(*args, **kwargs):       # what a concurrent writer's damage between commit and read looks like
        raise rc.InputError("calibration #1: damaged record", source=str(store))

    monkeypatch.setattr(sys.modules[rc.store.history.__module__], "history", damaged)
    data = campaign / "m.csv"
    if command == "calibrate failing":  # one joint's readings in radians under a degree header: the checks fail
        lines = data.read_text().splitlines()
        k = lines[0].split(",").index("j4_deg")
        rows = [r.split(",") for r in lines[1:]]
        for r in rows:
            r[k] = repr(float(np.radians(float(r[k]))))
        data = tmp_path / "m.csv"
        data.write_text("\n".join([lines[0]] + [",".join(r) for r in rows]) + "\n")
    if command == "record":
        code, out, err = cli("record", campaign / "result.json", "--robot", "R", "--store", store, "--at",
                             "2026-02-01")
    else:
        code, out, err = cli("calibrate", campaign / "model.yaml", data, "--out", tmp_path / "run", "--record", "R",
                             "--store", store)
        assert (tmp_path / "run" / "result.json").exists(), out + err
    assert code == (3 if command == "calibrate failing" else 0), err
    assert "recorded calibration #2" in out and "Traceback" not in err
    said = [ln for ln in err.splitlines() if "earlier records" in ln]   # (a failed calibration warns of its checks)
    assert len(said) == 1 and said[0].startswith("robocal: warning: recorded, but the earlier records of R cannot "
                                                 "be read") and "damaged record" in said[0], err
    assert all(ln.startswith("robocal: warning: ") for ln in err.splitlines()), err
    assert _count(store) == 2


def test_a_stored_calibration_refused_again_leaves_no_files_and_a_retry_records(cli, campaign, tmp_path):
    store = tmp_path / "s.sqlite"
    code, out, err = _calibrate(cli, campaign, tmp_path / "a", store)
    assert code == 0 and "recorded calibration #1" in out, err
    # the same result again, into another folder: stored already, so no files either
    code, _, err = cli("record", tmp_path / "a" / "result.json", "--robot", "SN-1", "--store", store)
    assert_one_line_error(code, err, ["stored already"], command="record")
    assert _count(store) == 1


def test_a_damaged_page_no_record_reads_is_found_before_anything_is_written(cli, campaign, tmp_path):
    store = tmp_path / "s.sqlite"
    assert cli("record", campaign / "result.json", "--robot", "R", "--store", store, "--at", "2026-01-01")[0] == 0
    c = sqlite3.connect(store)
    page = c.execute("SELECT rootpage FROM sqlite_master WHERE name = 'robocal_verifications'").fetchone()[0]
    size = c.execute("PRAGMA page_size").fetchone()[0]
    c.close()
    with open(store, "r+b") as fh:       # the verifications' table page: a record writes nowhere near it
        fh.seek((page - 1) * size)
        fh.write(b"\xff")
    before = _digest(store)
    code, _, err = cli("record", campaign / "result.json", "--robot", "R", "--store", store, "--at", "2026-02-01")
    assert_one_line_error(code, err, [str(store), "damaged store", "nothing recorded"], command="record")
    assert _digest(store) == before


def test_an_earlier_record_with_a_deviation_of_1e300_neither_fails_a_record_nor_its_history(cli, campaign,
                                                                                              tmp_path):
    store = tmp_path / "s.sqlite"
    assert cli("record", campaign / "result.json", "--robot", "R", "--store", store, "--at", "2026-01-01")[0] == 0
    c = sqlite3.connect(store)
    v = np.frombuffer(c.execute("SELECT estimates FROM robocal_calibrations").fetchone()[0], "<f8").reshape(-1, 3)
    v = v.copy()
    v[:, 2] = 1e300
    c.execute("UPDATE robocal_calibrations SET estimates = ?", (v.tobytes(),))
    c.commit()
    c.close()
    code, out, err = cli("record", campaign / "result.json", "--robot", "R", "--store", store, "--at", "2026-02-01")
    assert code == 0 and "recorded calibration #2" in out and "changes since the previous calibration" in out, err
    code, out, err = cli("history", "R", "--store", store)
    assert code == 0 and "changes between consecutive calibrations" in out, err


# -- item 3: only its own databases, changed only by its own writes ------------------------------------

def test_a_foreign_database_is_left_byte_for_byte(cli, campaign, tmp_path):
    foreign = tmp_path / "app.db"
    _damage(foreign, "CREATE TABLE accounts (id INTEGER)")
    before = _digest(foreign)
    for argv in (("record", campaign / "result.json", "--robot", "R"), ("history", "R"),
                 ("verify", "R", campaign / "m.csv")):
        code, _, err = cli(*argv, "--store", foreign)
        assert code == 2 and "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert _digest(foreign) == before and _beside(foreign) == ["app.db"]
    c = sqlite3.connect(foreign)
    assert c.execute("PRAGMA journal_mode").fetchone()[0] == "delete"
    c.close()


def test_a_refused_write_on_a_read_only_store_leaves_nothing_beside_it(cli, campaign, tmp_path):
    store = tmp_path / "s.sqlite"
    assert cli("record", campaign / "result.json", "--robot", "R", "--store", store, "--at", "2026-01-01")[0] == 0
    before = _digest(store)
    with _read_only(store):
        code, _, err = cli("record", campaign / "result.json", "--robot", "R", "--store", store)
        assert_one_line_error(code, err, [str(store), "read-only"], command="record")
        code, _, err = _calibrate(cli, campaign, tmp_path / "run", store)
        assert_one_line_error(code, err, [str(store), "read-only"], tmp_path / "run")
    assert _beside(store) == ["s.sqlite"] and _digest(store) == before


def test_a_damaged_date_is_reported_not_shown_as_a_number(cli, campaign, tmp_path):
    store = tmp_path / "s.sqlite"
    assert cli("record", campaign / "result.json", "--robot", "R", "--store", store)[0] == 0
    _damage(store, "UPDATE robocal_calibrations SET calibrated_at = 'Inf'")
    code, out, err = cli("history", "R", "--store", store)
    assert_one_line_error(code, err, ["calibration #1", "damaged", "'Inf'"], command="history")
    assert "Inf" not in out


# -- item 4: a store in a folder one cannot write is read ---------------------------------------------

def test_a_store_in_a_read_only_folder_is_read(cli, campaign, tmp_path):
    folder = tmp_path / "shared"
    folder.mkdir()
    store = folder / "s.sqlite"
    for at in ("2026-01-01", "2026-02-01"):
        assert cli("record", campaign / "result.json", "--robot", "R", "--type", "arm", "--store", store,
                   "--at", at)[0] == 0
    before = _digest(store)
    with _read_only(folder):
        code, out, err = cli("history", "R", "--store", store)
        assert code == 0 and "changes between consecutive calibrations" in out, err
        code, out, err = cli("history", "--type", "arm", "--store", store)
        assert code == 0 and "R: #2" in out, err
        code, out, err = cli("verify", "R", campaign / "m.csv", "--no-record", "--store", store)
        assert code in (0, 3) and "verdict" in out and "Traceback" not in err, err
        code, _, err = cli("verify", "R", campaign / "m.csv", "--store", store)
        assert_one_line_error(code, err, [str(store), "read-only folder"], command="verify")
    assert _beside(store) == ["s.sqlite"] and _digest(store) == before


def test_reading_a_read_only_store_in_a_writable_folder_leaves_nothing_beside_it(cli, campaign, tmp_path):
    store = tmp_path / "s.sqlite"
    assert cli("record", campaign / "result.json", "--robot", "R", "--type", "arm", "--store", store)[0] == 0
    before = _digest(store)
    with _read_only(store):
        code, out, err = cli("history", "R", "--store", store)
        assert code == 0 and "1 calibration(s)" in out, err
        assert cli("history", "nobody", "--store", store)[0] == 2
        code, out, err = cli("verify", "R", campaign / "m.csv", "--no-record", "--store", store)
        assert code in (0, 3) and "verdict" in out, err
    assert _beside(store) == ["s.sqlite"] and _digest(store) == before


def test_reading_a_store_leaves_nothing_beside_it(cli, campaign, tmp_path):
    store = tmp_path / "s.sqlite"
    assert cli("record", campaign / "result.json", "--robot", "R", "--type", "arm", "--store", store)[0] == 0
    before = _digest(store)
    for argv in (("history", "R"), ("history", "nobody"), ("history", "--type", "arm"),
                 ("verify", "R", campaign / "m.csv", "--no-record")):
        cli(*argv, "--store", store)
        assert _beside(store) == ["s.sqlite"], argv
    assert _digest(store) == before


# -- item 5: URL schemes ------------------------------------------------------------------------------

@pytest.mark.parametrize("url", ["mysql://cal@plant/robocal", "sqlite:///tmp/x.sqlite", "https://host/s"])
def test_an_unknown_url_scheme_is_refused_and_makes_nothing(cli, campaign, tmp_path, monkeypatch, url):
    monkeypatch.chdir(tmp_path)
    code, _, err = cli("record", campaign / "result.json", "--robot", "R", "--store", url)
    assert_one_line_error(code, err, [url.split(":")[0], "postgresql://"], command="record")
    assert list(tmp_path.iterdir()) == []


# -- item 8: a lock waited on says so --------------------------------------------------------------------

def test_a_record_waiting_for_another_writer_says_so(campaign, tmp_path):
    store = tmp_path / "s.sqlite"
    with rc.open_store(store, create=True):
        pass
    holder = sqlite3.connect(store, isolation_level=None)
    holder.execute("BEGIN IMMEDIATE")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    proc = subprocess.Popen([sys.executable, "-m", "robocal", "record", str(campaign / "result.json"), "--robot",
                             "R", "--store", str(store)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=env)
    said: list[str] = []
    try:
        # the notice comes once the command reaches the store (its start-up may take seconds on a busy machine)
        deadline = time.monotonic() + 120.0
        while not any("another process is writing the store; waiting" in line for line in said):
            assert proc.poll() is None and time.monotonic() < deadline, "".join(said)
            if select.select([proc.stderr], [], [], 0.5)[0]:
                said.append(proc.stderr.readline())
        time.sleep(1.0)
        assert proc.poll() is None      # still waiting
    finally:
        holder.execute("ROLLBACK")
        holder.close()
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 0 and "recorded calibration #1" in out, err
    assert str(store) in "".join(said)


def test_the_store_reads_its_records_back_after_these_checks(campaign, tmp_path):
    store = tmp_path / "s.sqlite"
    result = rc.read_result(campaign / "result.json")
    with rc.open_store(store, create=True) as s:
        rec = s.record(result, "R", at="2026-01-01")
    with rc.open_store(store) as s:
        (back,) = s.calibrations("R")
    assert back.id == rec.id and np.allclose([e.estimate for e in back.estimates], [p.estimate for p in
                                                                                     result.parameters])
