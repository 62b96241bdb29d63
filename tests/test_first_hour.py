"""A newcomer's first hour: what stumbled on a fresh clone (the store's speed, its file's mode, models
that call themselves what they are not, a verification that gives no hint, help that leaves options
unexplained). The examples and documents themselves are run by tests/test_docs_commands.py."""

from __future__ import annotations

import argparse
import json
import os
import stat
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import assert_one_line_error

import robocal as rc
from robocal.cli import build_parser

ROOT = Path(__file__).resolve().parent.parent
TH8 = ROOT / "examples" / "th8"


@pytest.fixture(scope="module")
def th8_result(tmp_path_factory):
    """The TH8 example calibrated from the command line: its result file."""
    from robocal.cli import main

    out = tmp_path_factory.mktemp("th8") / "run"
    assert main(["calibrate", str(TH8 / "model.yaml"), str(TH8 / "measurements.csv"), "--out", str(out),
                 "--known", "markers"]) == 0
    return out / "result.json"


def test_record_verify_and_history_judge_without_importing_scipy_stats(th8_result, tmp_path):
    # the normal, chi-square and F quantiles come from scipy.special: scipy.stats took 1.8 s of the
    # 3 s these commands took on a tiny store
    store = tmp_path / "s.sqlite"
    code = f"""
import sys
from robocal.cli import main
for argv in (["record", {str(th8_result)!r}, "--robot", "R", "--store", {str(store)!r}],
             ["record", {str(th8_result)!r}, "--robot", "R", "--store", {str(store)!r}, "--at", "2027-01-01"],
             ["verify", "R", {str(TH8 / "verification.csv")!r}, "--store", {str(store)!r}],
             ["history", "R", "--store", {str(store)!r}]):
    assert main(argv) == 0, argv
assert "scipy.stats" not in sys.modules, "scipy.stats was imported"
"""
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert "verdict: within accuracy" in run.stdout and "2 calibration(s), 1 verification(s)" in run.stdout


def test_a_missing_input_is_refused_before_scipy_is_imported(tmp_path):
    # the refusal of a file that is not there needs the reader and no analysis: scipy (the
    # optimizer, the special functions, the rotations' spatial package) took about 2 s of CPU
    # under load before `robocal calibrate` said the file was missing
    code = f"""
import sys
from robocal.cli import main
for argv in (["calibrate", {str(tmp_path / "m.yaml")!r}, {str(tmp_path / "d.csv")!r}, "--out", {str(tmp_path / "o")!r}],
             ["identifiability", {str(tmp_path / "m.yaml")!r}]):
    assert main(argv) == 2, argv
assert not [m for m in sys.modules if m.startswith("scipy")], "scipy was imported"
"""
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert run.stderr.count("m.yaml: cannot read: file not found") == 2, run.stderr


def test_the_quantiles_are_the_distributions_ones():
    from scipy.stats import norm

    for alpha, m in ((0.05, 1), (0.05, 20), (1e-6, 300)):
        per = -np.expm1(np.log1p(-alpha) / m)  # Sidak's share per test, without cancellation
        assert rc.sidak_threshold(alpha, m) == pytest.approx(norm.isf(per / 2), rel=1e-12)


def test_a_new_sqlite_store_gets_the_mode_the_umask_gives_every_output(th8_result, tmp_path, cli):
    old = os.umask(0o002)
    try:
        code, out, err = cli("record", th8_result, "--robot", "R", "--store", tmp_path / "s.sqlite")
        rc.write_model(rc.read_model(TH8 / "model.yaml"), tmp_path / "m.yaml")
    finally:
        os.umask(old)
    assert code == 0, err
    modes = {p.name: stat.S_IMODE(p.stat().st_mode) for p in tmp_path.iterdir()}
    assert modes["m.yaml"] == 0o664
    assert {name: mode for name, mode in modes.items() if name.startswith("s.sqlite")} == \
        {name: 0o664 for name in modes if name.startswith("s.sqlite")}


def test_a_calibrated_model_written_from_python_says_what_it_is(tmp_path):
    nominal = rc.read_model(TH8 / "model.yaml")
    assert "NOMINAL model" in nominal.description
    fit, held_out = rc.split_sets(rc.read_measurements(TH8 / "measurements.csv", nominal))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rc.RobocalWarning)
        result = rc.calibrate(nominal, fit, validation=held_out, parameters=("geometric",), known=("markers",))
    rc.write_model(result.calibrated_model, tmp_path / "calibrated.yaml")
    text = (tmp_path / "calibrated.yaml").read_text()
    assert "NOMINAL" not in text
    assert rc.read_model(tmp_path / "calibrated.yaml").description.startswith(
        "calibrated model: nominal model th8-like, geometric parameters identified from 48 poses of ")
    assert result.nominal_model.description == nominal.description


def test_simulated_true_robots_do_not_call_themselves_nominal(tmp_path, cli):
    doc = yaml.safe_load((TH8 / "true_model.yaml").read_text())
    assert "NOMINAL" not in doc["description"] and "SIMULATED real" in doc["description"]
    true, _ = rc.simulate(rc.read_model(TH8 / "model.yaml"), 10, seed=1)
    assert "NOMINAL" not in true.description and "simulated robot" in true.description
    code, out, err = cli("simulate", TH8 / "model.yaml", "--out", tmp_path / "s.csv", "--poses", "10",
                         "--true-model", tmp_path / "true.yaml")
    assert code == 0, err
    assert "NOMINAL" not in (tmp_path / "true.yaml").read_text()


def _moved(data: rc.Measurements, degrees: float, shift) -> rc.Measurements:
    """``data`` as an instrument set up again would see it: turned about z and shifted."""
    a = np.deg2rad(degrees)
    R = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
    return rc.Measurements(q=data.q, positions=data.positions @ R.T + np.asarray(shift), marker_names=data.marker_names,
                           joint_names=data.joint_names, labels=data.labels)


def test_verify_after_the_instrument_was_set_up_again_names_register_base(th8_result, tmp_path, cli):
    store = tmp_path / "s.sqlite"
    assert cli("record", th8_result, "--robot", "R", "--store", store)[0] == 0
    nominal = rc.read_model(TH8 / "model.yaml")
    moved = _moved(rc.read_measurements(TH8 / "verification.csv", nominal), 0.5, [0.004, -0.002, 0.001])
    rc.write_measurements(moved, tmp_path / "moved.csv", model=nominal)
    code, out, err = cli("verify", "R", tmp_path / "moved.csv", "--store", store, "--no-record")
    assert code == 3 and "verdict: recalibrate" in out, out + err
    assert "with the base re-registered on these poses the ratio is" in out and "--register-base" in out
    code, out, err = cli("verify", "R", tmp_path / "moved.csv", "--store", store, "--no-record", "--register-base")
    assert code == 0 and "verdict: within accuracy" in out, out + err
    # a robot that changed is not explained by a new set-up: no hint to register
    changed = rc.read_measurements(TH8 / "verification.csv", nominal)
    bent = rc.Measurements(q=changed.q, positions=changed.positions + 0.002 * np.sin(changed.q[:, :1, None] * 3),
                           marker_names=changed.marker_names, joint_names=changed.joint_names, labels=changed.labels)
    rc.write_measurements(bent, tmp_path / "bent.csv", model=nominal)
    code, out, err = cli("verify", "R", tmp_path / "bent.csv", "--store", store, "--no-record")
    assert code == 3 and "is still" in out and "not a new set-up of the instrument alone" in out, out + err


def _parsers():
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return [("robocal", parser), *sub.choices.items()]


def _unset(default) -> bool:
    return default in (None, False, argparse.SUPPRESS) or (isinstance(default, (list, tuple)) and not default)


def test_every_argument_is_described_and_every_default_stated():
    missing, unstated = [], []
    for name, parser in _parsers():
        for action in parser._actions:
            if isinstance(action, (argparse._HelpAction, argparse._VersionAction, argparse._SubParsersAction)):
                continue
            what = f"{name} {'/'.join(action.option_strings) or action.metavar or action.dest}"
            if not action.help:
                missing.append(what)
            elif action.option_strings and not _unset(action.default) and "default" not in action.help \
                    and not isinstance(action, argparse._StoreFalseAction):   # a flag: by default not given
                unstated.append(f"{what} (default {action.default!r})")
    assert missing == [] and unstated == [], (missing, unstated)


def test_the_top_level_help_ends_with_an_example(cli):
    code, out, err = cli("--help")
    assert code == 0
    example = out.split("example", 1)[1] if "example" in out else ""
    assert "  robocal calibrate " in example and "robocal COMMAND --help" in example


def test_record_and_report_take_the_folder_calibrate_wrote(th8_result, tmp_path, cli):
    # `robocal record runs/first` failed with "is a folder, not a file": the folder is what a user
    # has in hand after `calibrate --out runs/first`
    code, out, err = cli("record", th8_result.parent, "--robot", "R", "--store", tmp_path / "s.sqlite")
    assert code == 0, err
    assert "recorded calibration #1 of R" in out
    code, out, err = cli("record", tmp_path, "--robot", "R", "--store", tmp_path / "s.sqlite")
    assert code == 2 and "is a folder without a result.json" in err and str(tmp_path) in err
    assert "Traceback" not in err


def test_a_folder_of_seatings_given_as_the_measurement_file_names_contacts(tmp_path, cli):
    seatings = ROOT / "examples" / "arm7" / "seatings"
    code, out, err = cli("calibrate", ROOT / "examples" / "arm7" / "model.yaml", seatings, "--out", tmp_path / "o")
    assert code == 2 and "is a folder of seatings" in err and "--contacts" in err and str(seatings) in err
    assert not (tmp_path / "o").exists()


def test_history_names_only_the_families_it_compared(th8_result, tmp_path, cli):
    # a geometric calibration recorded twice: the header said "comparisons of frames, compliance,
    # backlash, transmission parameters" whatever was compared
    store = tmp_path / "s.sqlite"
    for at in ("2026-03-02T10:00:00Z", "2026-04-02T10:00:00Z"):
        assert cli("record", th8_result, "--robot", "R", "--store", store, "--at", at)[0] == 0
    code, out, err = cli("history", "R", "--store", store)
    assert code == 0, err
    header = next(line for line in out.splitlines() if line.startswith("changes between"))
    assert "comparisons of frames parameters;" in header and "compliance" not in header
    # the page says the same, and shows the accuracy in use the text shows beside the measured one
    with rc.open_store(store) as opened:
        page = rc.render_history(rc.history(opened, "R"))
    assert "comparisons of frames parameters;" in page and "<th>in use RMS (mm)</th>" in page


def test_a_robot_calibrated_from_contacts_is_verified_with_seatings(tmp_path, cli):
    """Verification said a calibration from contacts alone had nothing to verify against. It now
    holds new seatings against the calibration's held-out ones; measured points against it are
    refused with what to verify with instead."""
    arm7 = ROOT / "examples" / "arm7"
    lines = (arm7 / "sockets.csv").read_text().splitlines(keepends=True)
    head = [line for line in lines if line.startswith(("#", "placement,"))]
    (tmp_path / "fit.csv").write_text("".join(head + [x for x in lines if x.startswith(("P1,", "P2,", "P3,"))]))
    (tmp_path / "again.csv").write_text("".join(head + [x for x in lines if x.startswith("P4,")]))
    assert cli("calibrate", arm7 / "model.yaml", "--contacts", tmp_path / "fit.csv", "--out", tmp_path / "kit",
               "--record", "A7", "--store", tmp_path / "s.sqlite")[0] == 0
    code, out, err = cli("verify", "A7", "--contacts", tmp_path / "again.csv", "--store", tmp_path / "s.sqlite")
    assert code == 0 and "seatings in 3 sockets" in out and "verdict: within accuracy" in out, err
    model = rc.read_model(arm7 / "model.yaml")
    _, data = rc.simulate(model, 12, seed=1)
    rc.io.write_measurements(data, tmp_path / "check.csv", model=model)
    code, _, err = cli("verify", "A7", tmp_path / "check.csv", "--store", tmp_path / "s.sqlite")
    assert code == 2 and "accuracy is of seatings" in err and "these are measured points" in err
    code, _, err = cli("verify", "A7", "--store", tmp_path / "s.sqlite")
    assert code == 2 and "one of them" in err


def test_a_calibrations_outputs_given_as_the_model_name_the_calibrated_one(th8_result, tmp_path, cli):
    """The result file or the folder calibrate wrote, given where a model goes (compensate's
    calibrated model), was refused for a key it does not know ('schema') or as a folder; each now
    names the calibrated model written beside it."""
    run = th8_result.parent
    targets = TH8 / "targets.csv"
    for given, words in ((th8_result, ["robocal result file", "calibrated.yaml, written beside it"]),
                         (run, ["folder of a calibration's outputs", str(run / "calibrated.yaml")])):
        code, _, err = cli("compensate", TH8 / "model.yaml", given, targets, "--out", tmp_path / "c.csv")
        assert_one_line_error(code, err, [str(given), *words], tmp_path / "c.csv", command="compensate")
    code, out, err = cli("compensate", TH8 / "model.yaml", run / "calibrated.yaml", targets, "--out",
                         tmp_path / "c.csv")
    assert code == 0 and (tmp_path / "c.csv").exists(), err
    # a failed calibration's result was said to have calibrated.yaml written beside it, which it has not
    d = json.loads(th8_result.read_text())
    d["checks"][0]["status"] = d["verdict"] = "fail"
    (tmp_path / "failed").mkdir()
    (tmp_path / "failed" / "result.json").write_text(json.dumps(d))
    code, _, err = cli("compensate", TH8 / "model.yaml", tmp_path / "failed" / "result.json", targets, "--out",
                       tmp_path / "f.csv")
    assert_one_line_error(code, err, ["a robocal result file, not a robocal model file: its calibration failed its "
                                      "checks (the verdict in the file): calibrated.yaml is written beside it only "
                                      "by `robocal calibrate --write-failed`"], tmp_path / "f.csv",
                          command="compensate")


def test_each_robocal_file_given_in_another_ones_place_is_named(th8_result, tmp_path, cli):
    """A model, a result or a contact file given where another kind goes was read as that kind and
    refused for its columns or keys ("unknown column 'robocal_model:'", "not valid JSON", "the units
    directive must give the angle unit"); each is now named for what it is."""
    model, measurements = TH8 / "model.yaml", TH8 / "measurements.csv"
    calibrated, sockets = th8_result.parent / "calibrated.yaml", ROOT / "examples" / "arm7" / "sockets.csv"
    cases = [
        (("calibrate", model, model), ["a robocal model file, not a measurement file"]),
        (("calibrate", model, th8_result), ["a robocal result file, not a measurement file"]),
        (("calibrate", model, sockets), ["a contact file, not a measurement file", "--contacts"]),
        (("calibrate", model, "--contacts", measurements),
         ["a measurement file, not a contact file", "given after the model (`robocal calibrate MODEL DATA`"]),
        # a measurement file as the model: 'expected a mapping (key: value)'
        (("simulate", measurements, "--poses", "5"),
         ["a measurement file, not a robocal model file: it is given after the model"]),
        (("calibrate", model, "--contacts", model), ["a robocal model file, not a contact file"]),
        (("report", calibrated), ["a robocal model file, not a calibration's result (result.json)"]),
        (("calibrate", model, measurements, "--limit", th8_result), ["a robocal result file, not a limit file"]),
        (("calibrate", model, measurements, "--profile", model), ["a robocal model file, not an instrument profile"]),
    ]
    for k, (args, words) in enumerate(cases):
        out = tmp_path / f"o{k}"
        code, _, err = cli(*args, "--out", out)
        assert_one_line_error(code, err, words, out, command=args[0])
    as_json = tmp_path / "model.json"      # a model written as JSON is still a model
    as_json.write_text(json.dumps(rc.io.model_to_dict(rc.read_model(model))))
    assert rc.read_model(as_json).joint_names == rc.read_model(model).joint_names


def test_a_binary_file_of_a_known_kind_given_where_text_goes_is_named(th8_result, tmp_path, cli):
    """A ROS bag given as the measurements (rather than to import-bag), or a result's .npz given as
    the result, was refused for "a NUL character" at some line; each is now named, with what to do."""
    model = TH8 / "model.yaml"
    cases = [(("calibrate", model, TH8 / "mocap.bag"), ["a ROS 1 bag", "robocal import-bag"]),
             (("report", th8_result.with_suffix(".npz")), ["a ZIP archive", "result.json is the result"])]
    for k, (args, words) in enumerate(cases):
        out = tmp_path / f"o{k}"
        code, _, err = cli(*args, "--out", out)
        assert_one_line_error(code, err, [str(args[-1]), *words], out, command=args[0])
    junk = tmp_path / "junk.csv"
    junk.write_bytes(b"pose,j1_deg\nP1,\x0012\n")
    code, _, err = cli("calibrate", model, junk, "--out", tmp_path / "o")
    assert_one_line_error(code, err, ["line 2", "a NUL character"], tmp_path / "o")
