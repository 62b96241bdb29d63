"""The command line, through ``main(argv)``: outputs, summaries, and one clear line per bad input."""

import json
import re
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import assert_one_line_error
from robots import TORSO, arm6r, torso
from test_files import _cell, _drop

import robocal as rc
from robocal.io import model_to_dict, read_model, write_measurements, write_model


@pytest.fixture
def campaign(tmp_path):
    """A nominal model file, a measurement file of a perturbed robot, and the true robot."""
    model = arm6r(masses=True)
    true, data = rc.simulate(model, 40, seed=4)
    write_model(model, tmp_path / "model.yaml")
    write_measurements(data, tmp_path / "data.csv", model=model)
    return tmp_path, model, true, data


def test_calibrate_writes_model_and_result(campaign, cli):
    d, model, true, data = campaign
    code, out, err = cli("calibrate", d / "model.yaml", d / "data.csv", "--out", d / "run",
                         "--holdout", "0.25", "--seed", "1")
    assert code == 0, err
    assert "fit, before" in out and "validation, after" in out and "j2.alpha" in out
    assert "eliminated parameters" in out and "j1.theta" in out and "converged" in out
    cal = read_model(d / "run" / "calibrated.yaml")
    result = json.loads((d / "run" / "result.json").read_text())
    assert result["schema"] == "robocal.result/1"
    assert result["stats"]["validation_after"]["n"] == 10
    # the calibrated robot predicts the true robot far better than the nominal one
    q = rc.random_configurations(model, 20, 2)
    err_cal = np.linalg.norm(rc.forward_kinematics(cal, q).positions - rc.forward_kinematics(true, q).positions,
                             axis=-1)
    err_nom = np.linalg.norm(rc.forward_kinematics(model, q).positions - rc.forward_kinematics(true, q).positions,
                             axis=-1)
    assert err_cal.mean() < 0.05 * err_nom.mean()
    assert sorted(p.name for p in (d / "run").iterdir()) == ["calibrated.yaml", "result.json", "result.npz"]


ROOT = Path(__file__).resolve().parent.parent
TH8_MODEL, TH8_DATA = str(ROOT / "examples/th8/model.yaml"), str(ROOT / "examples/th8/measurements.csv")


def test_a_base_40_mm_off_shows_what_the_nominal_as_given_missed_beside_the_registered_before(tmp_path, cli):
    """The TH8's measured points 40 mm further along x (the robot's base 40 mm off the model's):
    "before" is the nominal model with its base registered on the data, 3.3 mm, and nothing showed
    that the nominal as given missed by 40 mm. The summary shows both, result.json keeps both, and a
    file written before the nominal's figures reads without them."""
    from robocal.report import calibration_summary

    lines = Path(TH8_DATA).read_text().splitlines()
    x = lines[0].split(",").index("tool_x_mm")
    rows = [r.split(",") for r in lines[1:]]
    for r in rows:
        r[x] = repr(float(r[x]) + 40.0)
    moved = tmp_path / "moved.csv"
    moved.write_text("\n".join([lines[0]] + [",".join(r) for r in rows]) + "\n")
    code, out, err = cli("calibrate", TH8_MODEL, moved, "--out", tmp_path / "run", "--known", "markers")
    assert code == 0, err
    stats = json.loads((tmp_path / "run" / "result.json").read_text())["stats"]

    def row(text, label):
        """The n and mean of the row ``label`` of ``text``'s error table."""
        return next(line.strip()[len(label):].split()[:2] for line in text.splitlines()
                    if line.strip().startswith(label + "  "))

    model = rc.read_model(TH8_MODEL)
    for poses, data in zip(("fit", "validation"), rc.split_sets(rc.read_measurements(moved, model))):
        raw, before = stats[f"{poses}_nominal"], stats[f"{poses}_before"]
        # the model as given at the readings, against the points as measured
        missed = np.linalg.norm(rc.forward_kinematics(model, data.q).positions[:, :1] - data.positions, axis=-1)
        assert raw["mean"] == pytest.approx(missed.mean(), abs=1e-9) and 0.039 < raw["mean"] < 0.042
        assert before["mean"] < 0.004
        assert row(out, f"{poses}, nominal as given") == [str(raw["n"]), f"{raw['mean'] * 1e3:.3f}"]
        assert row(out, f"{poses}, before, registered") == [str(before["n"]), f"{before['mean'] * 1e3:.3f}"]
    assert re.search(r"^  before, registered +3\.2", out, re.M)          # the accuracy in use's before
    # a result file written before the nominal's figures: read without them, "before" as it was
    doc = json.loads((tmp_path / "run" / "result.json").read_text())
    for key in ("fit_nominal", "validation_nominal"):
        del doc["stats"][key]
    (tmp_path / "run" / "result.json").write_text(json.dumps(doc))
    old = rc.read_result(tmp_path / "run" / "result.json")
    assert old.stats.fit_nominal is None and old.stats.validation_nominal is None
    text = calibration_summary(old)
    assert "nominal as given" not in text and row(text, "fit, before") == [str(stats["fit_before"]["n"]),
                                                                           f"{stats['fit_before']['mean'] * 1e3:.3f}"]


def test_the_comparison_shows_the_nominal_as_given_beside_the_registered_before(tmp_path, cli):
    """--compare's table had the registered "before" alone, labelled as if it were the nominal's error:
    it shows the rows the calibration's summary shows, the nominal as given among them."""
    code, out, err = cli("calibrate", TH8_MODEL, TH8_DATA, "--out", tmp_path / "run", "--compare")
    assert code == 0, err
    kept = json.loads((tmp_path / "run" / "result.json").read_text())["stats"]
    cells_of = [re.split(r"\s{2,}", line.strip()) for line in out.splitlines() if line.endswith(tuple("0123456789"))]
    table = {c[0]: c[1:] for c in cells_of}
    for poses in ("fit", "validation"):
        for when, key in (("nominal as given", "nominal"), ("before, registered", "before"), ("after", "after")):
            cells = table[f"{poses}, {when} rms (mm)"]
            assert len(cells) == 3 and f"{kept[f'{poses}_{key}']['rms'] * 1e3:.3f}" in cells, (poses, when, cells)
    assert float(table["fit, nominal as given rms (mm)"][0]) > 2 * float(table["fit, before, registered rms (mm)"][0])

def test_calibrated_model_says_it_is_calibrated_from_what_and_when(tmp_path, cli):
    nominal = tmp_path / "model.yaml"
    nominal.write_text(Path(TH8_MODEL).read_text())
    assert "NOMINAL" in rc.read_model(nominal).description
    code, _, err = cli("calibrate", nominal, TH8_DATA, "--out", tmp_path / "run", "--known", "markers")
    assert code == 0, err
    cal = rc.read_model(tmp_path / "run" / "calibrated.yaml")
    result = json.loads((tmp_path / "run" / "result.json").read_text())
    assert "NOMINAL" not in cal.description and cal.description.startswith("calibrated model")
    for said in (result["nominal_model"]["name"], TH8_DATA, result["provenance"]["date"][:10], result["verdict"],
                 f"{result['provenance']['data']['n_poses']} poses"):
        assert str(said) in cal.description, (said, cal.description)


def test_calibrate_semicolon_decimal_comma_missing_marker(tmp_path, cli):
    model = arm6r(markers=(("tool", (0.05, 0.02, 0.12)), ("t2", (0.1, 0.0, 0.1))))
    true, data = rc.simulate(model, 30, seed=5)
    write_model(model, tmp_path / "model.yaml", units="m-rad")
    lines = ["# units: length=mm angle=deg",
             ";".join(["pose"] + list(model.joint_names) + [f"{m}_{c}" for m in model.marker_names for c in "xyz"])]
    for i in range(data.n_poses):
        cells = [f"P{i}"] + [f"{v:.9f}" for v in np.rad2deg(data.q[i])]
        for m in range(2):
            missing = m == 1 and i % 5 == 0  # t2 not seen in every fifth pose
            cells += ["" if missing else f"{v * 1e3:.6f}" for v in data.positions[i, m]]
        lines.append(";".join(c.replace(".", ",") for c in cells))
    (tmp_path / "d.csv").write_text("\n".join(lines) + "\n")
    code, out, err = cli("calibrate", tmp_path / "model.yaml", tmp_path / "d.csv", "--out", tmp_path / "o",
                         "--sep", ";", "--decimal", ",")
    assert code == 0, err
    result = json.loads((tmp_path / "o" / "result.json").read_text())
    assert result["stats"]["fit_after"]["n"] == 30 + 24
    assert result["stats"]["fit_after"]["rms"] < 1e-4
    # the result says which pose of the file each row of its errors is
    assert result["provenance"]["data"]["labels"] == [f"P{i}" for i in range(data.n_poses)]
    assert rc.read_result(tmp_path / "o" / "result.json").fit.errors_after.shape[0] == data.n_poses


def test_calibrate_validation_file_and_limit(campaign, cli):
    d, model, true, data = campaign
    val = rc.measure(true, rc.random_configurations(model, 10, 9), rng=9)  # the same robot, other poses
    write_measurements(val, d / "val.csv", model=model)
    code, out, err = cli("calibrate", d / "model.yaml", d / "data.csv", "--out", d / "run",
                         "--validation", d / "val.csv", "--limit-mm", "0.1", "--known", "markers")
    assert code == 0, err
    assert "limit of absolute accuracy 0.100 mm" in out and "reached" in out
    result = json.loads((d / "run" / "result.json").read_text())
    assert result["provenance"]["validation"]["n_poses"] == 10
    assert result["provenance"]["validation"]["labels"] == list(rc.read_measurements(d / "val.csv", model).labels)
    stored = rc.read_result(d / "run" / "result.json")
    assert len(result["provenance"]["validation"]["labels"]) == stored.validation.errors_after.shape[0] == 10
    assert not any(p["name"].startswith("tool.") for p in result["parameters"])


def test_calibrate_compare(tmp_path, cli):
    d = tmp_path
    model = arm6r(masses=True)
    # centres of mass off the last axes: a moment that is zero up to rounding is not a parameter
    frames = model.frames[:4] + tuple(replace(f, com=(0.01, 0.02, 0.03)) for f in model.frames[4:])
    model = model.replace(frames=frames)
    true, data = rc.simulate(model, 60, parameters=("geometric", "compliance"), compliance_error=(1e-6, 5e-6),
                             seed=4)
    write_model(model, d / "model.yaml")
    write_measurements(data, d / "data.csv", model=model)
    code, out, err = cli("calibrate", d / "model.yaml", d / "data.csv", "--out", d / "cmp", "--compare",
                         "--holdout", "0.3")
    assert code == 0, err
    assert "geometric+compliance" in out and "compliance helped" in out
    # transmission terms tried on the better, and (the robot has none) not kept
    tried = out.split("transmission (up to the ", 1)
    assert "+transmission" in out and len(tried) == 2 and tried[1].split(":", 1)[0].endswith("did not help")
    assert "calibrated model chosen: geometric+compliance" in out
    # a note every identification has is said once, not once per identification
    notes = [line for line in out.splitlines() if line.startswith("note")]
    assert len(notes) == len(set(n.split(": ", 1)[1] for n in notes))
    assert "note: errors before calibration are those of the nominal geometry" in out
    assert sorted(p.name for p in (d / "cmp").iterdir()) == [
        "calibrated.yaml", "result-compliance.json", "result-compliance.npz", "result-geometric.json",
        "result-geometric.npz", "result-transmission.json", "result-transmission.npz", "result.json", "result.npz"]


def test_force_overwrites(campaign, cli):
    d, *_ = campaign
    args = ["calibrate", d / "model.yaml", d / "data.csv", "--out", d / "run"]
    assert cli(*args)[0] == 0
    code, out, err = cli(*args)
    assert code == 2 and "exists; pass --force" in err
    assert cli(*args, "--force")[0] == 0


def test_a_failed_run_with_force_leaves_no_earlier_model_beside_its_result(campaign, cli):
    d, model, _, data = campaign
    run = d / "run"
    assert cli("calibrate", d / "model.yaml", d / "data.csv", "--out", run, "--compare")[0] == 0
    assert cli("report", run / "result.json", "--out", run / "report.html")[0] == 0
    # the readings of each pose given to another: the calibration fails
    write_measurements(replace(data, q=np.roll(data.q, 7, axis=0)), d / "shuffled.csv", model=model)
    args = ["calibrate", d / "model.yaml", d / "shuffled.csv", "--out", run]
    code, _, err = cli(*args)
    assert code == 2 and f"{run / 'calibrated.yaml'}: exists; pass --force" in err
    code, out, _ = cli(*args, "--force")
    assert code == 3 and "removed" in out and "an earlier run's" in out
    assert sorted(p.name for p in run.iterdir()) == ["result.json", "result.npz"]
    assert json.loads((run / "result.json").read_text())["verdict"] == "fail"


def test_report_missing_extra(campaign, monkeypatch, cli):
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # as if the report extra were not installed
    d, *_ = campaign
    code, out, err = cli("calibrate", d / "model.yaml", d / "data.csv", "--out", d / "run", "--report")
    assert code == 1 and "report extra not installed" in err
    assert not (d / "run").exists()


def test_simulate_then_identifiability(tmp_path, cli):
    write_model(arm6r(), tmp_path / "m.yaml")
    code, out, err = cli("simulate", tmp_path / "m.yaml", "--out", tmp_path / "s.csv", "--poses", 15,
                         "--seed", 3, "--noise-mm", 0.01, "--length-error-mm", "0.5,1", "--true-model",
                         tmp_path / "true.yaml")
    assert code == 0, err
    data = rc.read_measurements(tmp_path / "s.csv", read_model(tmp_path / "m.yaml"))
    assert data.n_poses == 15
    true = read_model(tmp_path / "true.yaml")
    q = data.q
    assert np.abs(rc.forward_kinematics(true, q).positions - data.positions).max() < 1e-4  # noise 0.01 mm
    code, out, err = cli("identifiability", tmp_path / "m.yaml", tmp_path / "s.csv")
    assert code == 0, err
    table = {line.split()[0]: line.split()[1:] for line in out.splitlines() if line.startswith("  j")}
    assert table["j1"][:5] == ["E", "E", "E", "E", "E"]       # frame 1 goes to the base
    assert table["j3"][:5] == ["I", "I", "I", "I", "E"]       # r of the second parallel axis
    assert re.search(r"j3\.r +1 mm = \+1 mm j2\.r", out)
    assert "condition number" in out and "O1" in out
    code, out2, err = cli("identifiability", tmp_path / "m.yaml", "--poses", 30, "--seed", 1)
    assert code == 0 and "30 random poses" in out2


def test_identifiability_of_a_file_analyses_the_poses_calibrate_fits(cli):
    # the TH8 file holds 48 poses to fit and 48 marked validation: what these data can identify is
    # what calibrate identifies from the 48 it fits, not from all 96
    th8 = Path(__file__).resolve().parents[1] / "examples" / "th8"
    nominal = read_model(th8 / "model.yaml")
    fit, held = rc.split_sets(rc.read_measurements(th8 / "measurements.csv", nominal))
    res = rc.identifiability(nominal, fit)
    code, out, err = cli("identifiability", th8 / "model.yaml", th8 / "measurements.csv")
    assert code == 0, err
    assert f"at the {fit.n_poses} poses of " in out and f"the {held.n_poses} validation rows left out" in out
    assert f"(rank {res.rank}, {res.n_rows} equations)" in out and res.n_rows == 3 * fit.n_poses == 144


def test_help_for_every_command(cli):
    for cmd in ("calibrate", "simulate", "identifiability", "report", "limit", "import-urdf"):
        code, out, err = cli(cmd, "--help")
        assert code == 0 and f"usage: robocal {cmd}" in out


def test_python_dash_m(tmp_path):
    out = subprocess.run([sys.executable, "-m", "robocal", "--version"], capture_output=True, text=True)
    assert out.returncode == 0 and "robocal" in out.stdout


# ------------------------------------------------------------------------------------------------
# every bad input: exit 2, one line naming the file and the place, no traceback, nothing written

def _edit_csv(path, edit):
    lines = path.read_text().splitlines()
    edit(lines)
    path.write_text("\n".join(lines) + "\n")


def _set(lines, row, col_name, value):
    _cell(lines, row, lines[0].split(",").index(col_name), value)


def _edit_model(path, edit):
    d = yaml.safe_load(path.read_text())
    edit(d)
    path.write_text(yaml.safe_dump(d, sort_keys=False))


CSV_CASES = {
    "missing column": (lambda ls: _drop(ls, "tool_y_mm"), ["missing column tool_y"]),
    "non-numeric cell": (lambda ls: _set(ls, 4, "j3_deg", "12.5x"), ["line 5", "'j3_deg'", "expected a number"]),
    "NaN": (lambda ls: _set(ls, 6, "tool_z_mm", "nan"), ["line 7", "'tool_z_mm'", "not a measurement"]),
    "wrong number of joints": (lambda ls: _drop(ls, "j6_deg"), ["line 1", "missing column 'j6'", "6 joints"]),
    "unknown unit": (lambda ls: _set(ls, 0, "tool_x_mm", "tool_x_cm"), ["line 1", "'tool_x_cm'",
                                                                         "unknown length unit 'cm'"]),
    "cell count": (lambda ls: ls.__setitem__(9, ls[9] + ",3"), ["line 10", "cells where the header has"]),
    "fewer poses than parameters": (lambda ls: ls.__delitem__(slice(6, None)), ["5 poses", "identifiable parameters"]),
}

MODEL_CASES = {
    "misspelt key": (lambda d: d["frames"][2].update(thetta=d["frames"][2].pop("theta")),
                     ["frames[2].thetta", "did you mean 'theta'"]),
    "missing key": (lambda d: d["markers"][0].pop("frame"), ["markers[0].frame", "missing required key"]),
    "marker on an unknown frame": (lambda d: d["markers"][0].update(frame="f6"), ["markers[0].frame",
                                                                                 "unknown frame 'f6'"]),
    "joint named twice": (lambda d: d["joints"][4].update(name="j2"), ["joints[4].name", "'j2' is named twice"]),
    "unknown unit": (lambda d: d["units"].update(angle="grad"), ["units.angle", "unknown angle unit 'grad'"]),
    "non-numeric value": (lambda d: d["frames"][3].update(d="long"), ["frames[3].d", "expected a number"]),
}


def assert_clean_failure(code, err, cmd, words, out_dir):
    assert code == 2
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"robocal {cmd}: error: "), err
    for w in words:
        assert w in lines[0], (w, lines[0])
    assert not out_dir.exists() or not any(out_dir.iterdir())


@pytest.mark.parametrize("kind, case", [("csv", c) for c in sorted(CSV_CASES)] +
                         [("model", c) for c in sorted(MODEL_CASES)])
def test_bad_input_file(campaign, kind, case, cli):
    d, *_ = campaign
    if kind == "csv":
        bad, (edit, words) = d / "data.csv", CSV_CASES[case]
        _edit_csv(bad, edit)
    else:
        bad, (edit, words) = d / "model.yaml", MODEL_CASES[case]
        _edit_model(bad, edit)
    code, out, err = cli("calibrate", d / "model.yaml", d / "data.csv", "--out", d / "run")
    assert_clean_failure(code, err, "calibrate", [str(bad)] + words, d / "run")


def test_zero_quaternion(tmp_path, cli):
    model = arm6r()
    true, data = rc.simulate(model, 20, seed=2, orientation=True, noise_rot=1e-5)
    write_model(model, tmp_path / "model.yaml")
    write_measurements(data, tmp_path / "data.csv", model=model)
    lines = (tmp_path / "data.csv").read_text().splitlines()
    comment, rest = lines[0], lines[1:]
    for c in ("tool_qx", "tool_qy", "tool_qz", "tool_qw"):
        _set(rest, 3, c, "0.0")
    (tmp_path / "data.csv").write_text("\n".join([comment] + rest) + "\n")
    code, out, err = cli("calibrate", tmp_path / "model.yaml", tmp_path / "data.csv", "--out", tmp_path / "o")
    assert_clean_failure(code, err, "calibrate", [str(tmp_path / "data.csv"), "line 5", "'tool_qx'",
                                                  "quaternion of zero norm"], tmp_path / "o")


def test_no_units_declared(campaign, cli):
    d, *_ = campaign
    _edit_csv(d / "data.csv", lambda ls: ls.__setitem__(0, ls[0].replace("_mm", "").replace("_deg", "")))
    code, out, err = cli("calibrate", d / "model.yaml", d / "data.csv", "--out", d / "run")
    assert_clean_failure(code, err, "calibrate", [str(d / "data.csv"), "line 1", "'j1'", "--units mm-deg"],
                         d / "run")
    code, out, err = cli("calibrate", d / "model.yaml", d / "data.csv", "--out", d / "run",
                         "--units", "mm-deg")
    assert code == 0, err


def test_existing_output_without_force(campaign, cli):
    d, *_ = campaign
    (d / "run").mkdir()
    (d / "run" / "result.json").write_text("mine")
    code, out, err = cli("calibrate", d / "model.yaml", d / "data.csv", "--out", d / "run")
    assert code == 2 and "Traceback" not in err
    assert f"{d / 'run' / 'result.json'}: exists; pass --force" in err
    assert sorted(p.name for p in (d / "run").iterdir()) == ["result.json"]
    assert (d / "run" / "result.json").read_text() == "mine"


@pytest.mark.parametrize("second", ["sim.csv", "./sub/../sim.csv"])
def test_one_file_given_for_two_outputs_is_refused(campaign, cli, second):
    d, *_ = campaign
    (d / "sub").mkdir()
    code, _, err = cli("simulate", d / "model.yaml", "--out", d / "sim.csv", "--poses", "10",
                       "--true-model", d / second, "--force")
    assert_one_line_error(code, err, ["given for two outputs", f"also as {d / 'sim.csv'}"], d / "sim.csv",
                          command="simulate")


def test_simulate_refuses_existing_output(tmp_path, cli):
    write_model(arm6r(), tmp_path / "m.yaml")
    (tmp_path / "s.csv").write_text("keep")
    code, out, err = cli("simulate", tmp_path / "m.yaml", "--out", tmp_path / "s.csv", "--poses", 5)
    assert code == 2 and "exists" in err and (tmp_path / "s.csv").read_text() == "keep"


def test_missing_files_and_bad_options(tmp_path, cli):
    code, out, err = cli("calibrate", tmp_path / "none.yaml", tmp_path / "none.csv", "--out", tmp_path / "o")
    assert code == 2 and "none.yaml: cannot read: file not found" in err and "Traceback" not in err
    code, out, err = cli("calibrate", "m.yaml", "d.csv", "--out", "o", "--holdout", "1.5")
    assert code == 2 and "fraction" in err
    code, out, err = cli("calibrate", "m.yaml", "d.csv", "--out", "o", "--units", "mm-grad")
    assert code == 2 and "unknown angle unit 'grad'" in err


def test_unknown_parameter_family(campaign, cli):
    d, *_ = campaign
    code, out, err = cli("calibrate", d / "model.yaml", d / "data.csv", "--out", d / "run",
                         "--parameters", "geometric,geometry")
    assert_clean_failure(code, err, "calibrate", ["parameters", "'geometry'"], d / "run")


def test_model_dict_matches_written_file(campaign):
    d, model, *_ = campaign
    assert yaml.safe_load((d / "model.yaml").read_text()) == model_to_dict(model)


def test_calibrate_report_and_report_command(campaign, cli):
    d, *_ = campaign
    code, out, err = cli("calibrate", d / "model.yaml", d / "data.csv", "--out", d / "run", "--holdout",
                         "0.25", "--report")
    assert code == 0, err
    html = (d / "run" / "report.html").read_text()
    assert html.startswith("<!DOCTYPE html>") and "data-plot" in html
    code, out, err = cli("report", d / "run" / "result.json", "--out", d / "again.html")
    assert code == 0, err
    assert (d / "again.html").read_text().count("data-plot=") == html.count("data-plot=")
    code, out, err = cli("report", d / "run" / "result.json", "--out", d / "again.html")
    assert code == 2 and "exists" in err


def test_import_urdf_writes_a_model_with_the_same_kinematics(tmp_path, cli):
    from test_conversion import ARM7, _urdf_text
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(_urdf_text("arm", ARM7))
    code, out, err = cli("import-urdf", urdf, "--out", tmp_path / "arm.yaml", "--marker-mm", "tcp,0,10,120")
    assert code == 0 and err == "" and "7 joints" in out
    written = read_model(tmp_path / "arm.yaml")
    direct = rc.read_urdf(urdf, markers=[("tcp", (0.0, 0.01, 0.12))])
    assert written.marker_names == ("tcp",) and written.joint_names == direct.joint_names
    q = rc.random_configurations(direct, 20, rng=3)
    # the file holds mm and degrees at full precision: the same robot to round-off
    np.testing.assert_allclose(rc.forward_kinematics(written, q).positions,
                               rc.forward_kinematics(direct, q).positions, rtol=0, atol=1e-12)


@pytest.mark.parametrize("args, message", [
    (("missing.urdf",), "missing.urdf: no such file"),
    (("arm.urdf", "--tip-link", "nowhere"), "--tip-link 'nowhere' is not defined"),
    (("broken.urdf",), "broken.urdf"),
    (("arm.urdf", "--marker-mm", "tcp,1,2"), "expected NAME,X,Y,Z"),
])
def test_import_urdf_bad_input(tmp_path, args, message, cli):
    from test_conversion import ARM7, _urdf_text
    (tmp_path / "arm.urdf").write_text(_urdf_text("arm", ARM7))
    (tmp_path / "broken.urdf").write_text("<robot name='x'><link name='a'/><joint")
    argv = [tmp_path / a if a.endswith(".urdf") else a for a in args]
    code, out, err = cli("import-urdf", *argv, "--out", tmp_path / "out.yaml")
    assert code == 2 and message in err and len(err.strip().splitlines()) <= 5 and "Traceback" not in err
    assert not (tmp_path / "out.yaml").exists()


@pytest.fixture
def torso_campaign(tmp_path):
    m = torso()
    true, data = rc.simulate(m, 30, seed=1)
    text = yaml.safe_load(TORSO.read_text())
    rc.write_measurements(data, tmp_path / "data.csv", model=m)
    return tmp_path, text


TREE_CASES = {
    "coupling to an unknown joint": (lambda d: d["frames"][5]["coupling"].update(l9=1),
                                     ["frames[5].coupling.l9", "unknown key 'l9'"]),
    "parent defined later": (lambda d: d["frames"][6].update(parent="r2"),
                             ["frames[6].parent", "'r2' is not a frame defined before this one"]),
    "coupled frame made fixed": (lambda d: d["frames"][5].update(joint="fixed"),
                                 ["frames[5].coupling", "a fixed frame has no joint reading"]),
}


@pytest.mark.parametrize("case", sorted(TREE_CASES))
def test_bad_tree_model_file_through_cli(torso_campaign, case, cli):
    d, text = torso_campaign
    edit, words = TREE_CASES[case]
    edit(text)
    (d / "bad.yaml").write_text(yaml.safe_dump(text, sort_keys=False))
    with pytest.raises(rc.InputError) as err:
        rc.read_model(d / "bad.yaml")
    assert err.value.source == str(d / "bad.yaml")
    code, out, err = cli("calibrate", d / "bad.yaml", d / "data.csv", "--out", d / "run")
    assert_one_line_error(code, err, [f"{d / 'bad.yaml'}: "] + words, d / "run")










