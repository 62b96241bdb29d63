"""The limit of absolute accuracy: ISO 9283 repeatability, controller precision, the limit, the CLI."""

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_one_line_error

import robocal as rc
from robocal._accuracy.limit import parameter_displacement
from robocal._files.result import LIMIT_SCHEMA
from robocal._model.kinematics import kinematic_pass, layout
from robocal.io import limit_to_dict, read_repeatability_csv
from robocal.limit import (
    AccuracyLimit,
    RepeatabilityResult,
    accuracy_limit,
    controller_precision,
    iso9283_repeatability,
    predicted_controller_precision,
    rounded_parameters,
)

DEG = math.pi / 180
QUANTA = dict(encoder_resolution=0.01 * DEG, length_quantum=1e-4, angle_quantum=1e-3 * DEG)


def industrial_6r(markers=(("tool", (0.0, 0.0, 0.1)),)):
    """A 6R industrial arm with shoulder and elbow offsets (modified DH), about 1.1 m reach."""
    rows = [dict(r=0.40), dict(alpha=-90 * DEG, d=0.15, theta=-90 * DEG), dict(d=0.60),
            dict(alpha=-90 * DEG, d=0.12, r=0.62), dict(alpha=90 * DEG), dict(alpha=-90 * DEG)]
    limits = [(-185 * DEG, 185 * DEG), (-140 * DEG, -5 * DEG), (-120 * DEG, 155 * DEG),
              (-350 * DEG, 350 * DEG), (-125 * DEG, 125 * DEG), (-350 * DEG, 350 * DEG)]
    return rc.serial_model("ind6r", rows, markers=markers, joint_limits=limits, base_position=(0.8, 0.3, 0.0))


# -- ISO 9283 ----------------------------------------------------------------------------------

# Two poses x 5 cycles, millimetres.
# Pose A: x = 0, 1, 0, -1, 0 and y = 0, 0, 2, 0, -2 (z = 10): barycentre (0, 0, 10);
#   l = 0, 1, 2, 1, 2 -> l_mean = 6/5 = 1.2;
#   deviations -1.2, -0.2, 0.8, -0.2, 0.8 -> squares 1.44 + 0.04 + 0.64 + 0.04 + 0.64 = 2.8;
#   S_l = sqrt(2.8 / 4) = sqrt(0.7) = 0.836660; RP = 1.2 + 3 * 0.836660 = 3.709980 mm.
# Pose B: z = 500 + 0, 0.3, -0.3, 0.4, -0.4 (x = 100, y = 50): barycentre (100, 50, 500);
#   l = 0, 0.3, 0.3, 0.4, 0.4 -> l_mean = 1.4/5 = 0.28;
#   deviations -0.28, 0.02, 0.02, 0.12, 0.12 -> squares 0.0784 + 0.0004 + 0.0004 + 0.0144 + 0.0144
#   = 0.108; S_l = sqrt(0.027) = 0.164317; RP = 0.28 + 0.492950 = 0.772950 mm.
# Worst pose: A.
CSV = """pose,cycle,x,y,z
A,1,0,0,10
B,1,100,50,500
A,2,1,0,10
B,2,100,50,500.3
A,3,0,2,10
B,3,100,50,499.7
A,4,-1,0,10
B,4,100,50,500.4
A,5,0,-2,10
B,5,100,50,499.6
"""


def test_iso9283_hand_computed(tmp_path):
    f = tmp_path / "rep.csv"
    f.write_text(CSV)
    data = read_repeatability_csv(f, units="mm")
    r = iso9283_repeatability(data.pose_ids, data.points)
    a, b = r.poses
    assert (a.pose, b.pose, a.n_cycles, b.n_cycles) == ("A", "B", 5, 5)
    np.testing.assert_allclose(a.barycentre, (0.0, 0.0, 0.010), atol=1e-15)
    np.testing.assert_allclose(b.barycentre, (0.100, 0.050, 0.500), rtol=1e-14)
    np.testing.assert_allclose(a.l, np.array([0, 1, 2, 1, 2]) * 1e-3, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose([a.l_mean, a.s_l, a.rp], [1.2e-3, math.sqrt(0.7) * 1e-3, 3.709980e-3], rtol=1e-6)
    np.testing.assert_allclose([b.l_mean, b.s_l, b.rp], [0.28e-3, math.sqrt(0.027) * 1e-3, 0.772950e-3],
                               rtol=1e-5)
    assert r.worst_pose == "A" and r.rp == a.rp


def test_csv_units_metres_match_millimetres(tmp_path):
    f = tmp_path / "m.csv"
    lines = CSV.splitlines()
    f.write_text("\n".join([lines[0]] + [
        ",".join(row.split(",")[:2] + [repr(float(v) / 1000) for v in row.split(",")[2:]]) for row in lines[1:]]))
    g = tmp_path / "mm.csv"
    g.write_text(CSV)
    np.testing.assert_allclose(read_repeatability_csv(f, units="m").points,
                               read_repeatability_csv(g, units="mm").points, rtol=1e-15)


@pytest.mark.parametrize("text, where, words", [
    ("pose,x,y,z\nA,0,0,0\nA,1,0,0\n", "line 1", "cycle"),
    ("pose,cycle,x,y,z\nA,1,0,0,0\nA,2,0,abc,0\n", "line 3, column 'y'", "abc"),
    ("pose,cycle,x,y,z\nA,1,0,0,0\nA,2,0,0,nan\n", "line 3, column 'z'", "'nan' is not a measurement"),
    ("pose,cycle,x,y,z\nA,1,0,0,0\nA,2,0,0,1\nB,1,0,0,0\n", "line 4", "single cycle"),
    ("pose,cycle,x,y,z\nA,1,0,0,0\nA,1,0,0,1\n", "line 3", "already"),
    ("pose,cycle,x,y,z\nA,one,0,0,0\nA,2,0,0,1\n", "line 2, column 'cycle'", "integer"),
    # the file's column names, as written
    ("Pose,Cycle,X_mm,Y_mm,Z_mm\nA,1,0,0,0\nA,2,0,0,\n", "line 3, column 'Z_mm'", "empty cell"),
    # every cycle of every pose at one position read 'repeatability 0.0000 mm'
    ("pose,cycle,x,y,z\nA,1,1,2,3\nA,2,1,2,3\nB,1,0,0,0\nB,2,0,0,0\n", "lines 2-5",
     "the cycles of each of the 2 poses read the same x, y, z to the last digit"),
])
def test_csv_bad_input(tmp_path, text, where, words):
    f = tmp_path / "bad.csv"
    f.write_text(text)
    with pytest.raises(rc.InputError) as exc:
        read_repeatability_csv(f, units="mm")
    assert exc.value.source == str(f) and exc.value.where == where and words in exc.value.detail


def test_csv_separator_and_decimal_mark_are_detected(tmp_path):
    """A ';' file with decimal commas read as 'missing column 'pose''."""
    f, g = tmp_path / "comma.csv", tmp_path / "semicolon.csv"
    f.write_text(CSV)
    g.write_text(CSV.replace(",", ";").replace(".", ","))
    np.testing.assert_array_equal(read_repeatability_csv(g, units="mm").points,
                                  read_repeatability_csv(f, units="mm").points)
    g.write_text(CSV.replace(",", "\t"))
    np.testing.assert_array_equal(read_repeatability_csv(g, units="mm").points,
                                  read_repeatability_csv(f, units="mm").points)


def test_csv_units_must_be_explicit_and_known(tmp_path):
    f = tmp_path / "rep.csv"
    f.write_text(CSV)
    with pytest.raises(rc.InputError, match="units"):
        read_repeatability_csv(f, units="inch")
    # plain x, y, z without a declared unit: refused, not assumed
    with pytest.raises(rc.InputError, match="unit of column 'x' is not declared") as exc:
        read_repeatability_csv(f)
    assert exc.value.where == "line 1"
    # units in the column names need nothing else, and must agree with any units given
    g = tmp_path / "suffixed.csv"
    g.write_text(CSV.replace("x,y,z", "x_m,y_m,z_m", 1))
    np.testing.assert_allclose(read_repeatability_csv(g).points, read_repeatability_csv(f, units="mm").points * 1e3)
    with pytest.raises(rc.InputError, match="says m but units 'mm'"):
        read_repeatability_csv(g, units="mm")


# -- controller precision ----------------------------------------------------------------------

def test_parameter_displacement_matches_engine_jacobian():
    # the fast J_p @ dp from the step geometry against the public Jacobian
    model = industrial_6r(markers=(("tool", (0.02, 0.01, 0.1)), ("m2", (0.1, 0.0, 0.0))))
    rp = rounded_parameters(model, 1e-4, 1e-5)
    rng = np.random.default_rng(5)
    q = rng.uniform(-2, 2, (7, model.n_joints))
    dp = rng.uniform(-1, 1, (7, len(rp.params))) * rp.quanta
    lay = layout(model)
    p = rc.parameter_vector(model)
    ps = kinematic_pass(model, lay, p, q @ model.coupling_matrix.T)
    J = rc.evaluate(model, q, p, jacobian=True).jacobian
    for k in range(2):
        fast = parameter_displacement(ps, lay.step_is_rot[rp.steps], rp.steps,
                                       lay.marker_path[k, rp.steps], dp, ps.P[k])
        np.testing.assert_allclose(fast, np.einsum("nak,nk->na", J[:, k, :3][:, :, rp.params], dp), atol=1e-15)


def test_rounded_parameters_of_a_serial_arm():
    model = industrial_6r()
    rp = rounded_parameters(model, 1e-4, 1e-5)
    # d, r, alpha, theta per frame + beta of the two frames parallel to their predecessor + base, tool
    assert len(rp.names) == 6 * 4 + 2 + 3 + 3
    assert {"j1.beta", "j3.beta", "base.x", "tool.z"} <= set(rp.names)
    assert not any(n.endswith((".gamma", ".b", ".rx", ".k_theta")) for n in rp.names)
    assert np.all(rp.quanta[[n.endswith((".d", ".r", ".x", ".y", ".z")) for n in rp.names]] == 1e-4)


def test_monte_carlo_agrees_with_first_order_prediction():
    model = industrial_6r()
    mc = controller_precision(model, n_samples=200_000, rng=11, **QUANTA)
    pred = predicted_controller_precision(model, n_configurations=50_000, rng=12, **QUANTA)
    # RMS to RMS: first-order exact, so only sampling error separates them
    assert abs(mc.rms - pred.rms) < 4 * math.hypot(mc.rms_standard_error, pred.rms_standard_error)
    # the mean against the Gaussian approximation of the first-order distribution
    assert abs(mc.mean - pred.mean_gaussian) < 0.05 * pred.mean_gaussian
    assert 50e-6 < mc.mean < 300e-6   # a tenth of a millimetre is the expected order of magnitude


def test_standard_error_covers_seed_to_seed_difference():
    model = industrial_6r()
    a = controller_precision(model, n_samples=40_000, rng=1, **QUANTA)
    b = controller_precision(model, n_samples=40_000, rng=2, **QUANTA)
    assert a.mean != b.mean
    assert abs(a.mean - b.mean) < 3 * math.hypot(a.standard_error, b.standard_error)
    np.testing.assert_allclose(a.standard_error, a.std / math.sqrt(40_000))


def test_chunking_does_not_change_the_statistics():
    model = industrial_6r()
    whole = controller_precision(model, n_samples=5000, chunk_size=5000, rng=3, **QUANTA)
    seen = []
    parts = controller_precision(model, n_samples=5000, chunk_size=777, rng=3,
                                 progress=lambda d, t: seen.append((d, t)), **QUANTA)
    for f in ("mean", "std", "rms", "max"):
        np.testing.assert_allclose(getattr(parts, f), getattr(whole, f), rtol=1e-12)
    np.testing.assert_allclose(parts.percentiles, whole.percentiles, rtol=1e-12)
    assert seen[-1] == (5000, 5000) and len(seen) == 7


def test_joint_errors_alone_are_exact_kinematics():
    # with no parameter round-off the deviation is plain forward kinematics at q and q + dq
    model = industrial_6r()
    r = controller_precision(model, encoder_resolution=0.1 * DEG, length_quantum=0.0, angle_quantum=0.0,
                             n_samples=300, rng=np.random.default_rng(9))
    rng = np.random.default_rng(9)
    u = rng.random((300, 2 * 6 + len(rounded_parameters(model, 0, 0).params)))
    q = model.lower_limits + (model.upper_limits - model.lower_limits) * u[:, :6]
    dq = (u[:, 6:12] - 0.5) * 0.1 * DEG
    ref = rc.forward_kinematics(model, q).positions[:, 0]
    moved = rc.forward_kinematics(model, q + dq).positions[:, 0]
    exact = np.linalg.norm(moved - ref, axis=1)
    np.testing.assert_allclose([r.mean, r.max, r.rms], [exact.mean(), exact.max(), np.sqrt(np.mean(exact ** 2))],
                               rtol=1e-9)
    # percentiles come from a histogram of 0.14 % wide bins
    for pct, v in r.percentiles:
        np.testing.assert_allclose(v, np.percentile(exact, pct), rtol=4e-3)


def test_all_markers_takes_the_worst():
    model = industrial_6r(markers=(("tool", (0.0, 0.0, 0.1)), ("far", (0.5, 0.0, 0.1))))
    first = controller_precision(model, n_samples=2000, rng=4, markers="first", **QUANTA)
    both = controller_precision(model, n_samples=2000, rng=4, markers="all", **QUANTA)
    assert both.max >= first.max and both.mean > first.mean
    assert all(b >= f for (_, b), (_, f) in zip(both.percentiles, first.percentiles))


@pytest.mark.parametrize("change, where", [
    (dict(encoder_resolution=-0.001), "encoder_resolution"),
    (dict(encoder_resolution=[0.001] * 5), "encoder_resolution"),
    (dict(length_quantum=float("nan")), "length_quantum"),
    (dict(angle_quantum=-1.0), "angle_quantum"),
    (dict(n_samples=1), "n_samples"),
    (dict(chunk_size=0), "chunk_size"),
    (dict(rng=None), "rng"),
    (dict(markers="last"), "markers"),
])
def test_precision_bad_arguments(change, where):
    kw = dict(QUANTA, n_samples=10, rng=0)
    kw.update(change)
    with pytest.raises(rc.InputError) as exc:
        controller_precision(industrial_6r(), **kw)
    assert exc.value.where == where


# -- the limit ---------------------------------------------------------------------------------

def test_accuracy_limit_adds_repeatability_and_mean_precision(tmp_path):
    model = industrial_6r()
    prec = controller_precision(model, n_samples=2000, rng=0, **QUANTA)
    f = tmp_path / "rep.csv"
    f.write_text(CSV)
    data = read_repeatability_csv(f, units="mm")
    rep = iso9283_repeatability(data.pose_ids, data.points)
    lim = accuracy_limit(rep, prec)
    assert isinstance(lim, AccuracyLimit) and isinstance(lim.repeatability_detail, RepeatabilityResult)
    assert lim.limit == rep.rp + prec.mean and lim.limit_p95 == rep.rp + prec.percentile(95)
    d = json.loads(json.dumps(limit_to_dict(lim)))
    assert d["schema"] == LIMIT_SCHEMA and d["precision_statistic"] == "mean"
    assert d["repeatability_detail"]["worst_pose"] == "A"
    plain = accuracy_limit(0.03e-3, prec)
    assert plain.limit == 0.03e-3 + prec.mean and limit_to_dict(plain)["repeatability_detail"] is None
    with pytest.raises(rc.InputError):
        accuracy_limit(-1.0, prec)


# -- CLI ---------------------------------------------------------------------------------------



def cli(argv):
    from robocal.cli import main

    return main(argv)


@pytest.fixture
def model_file(tmp_path):
    """The test arm written as a model file by the project's writer (read back by the CLI)."""
    from robocal.io import write_model

    path = tmp_path / "arm.yaml"
    write_model(industrial_6r(), path)
    return path


def test_cli_writes_the_limit(model_file, tmp_path, cli):
    out = tmp_path / "limit.json"
    csv_file = tmp_path / "rep.csv"
    csv_file.write_text(CSV)
    argv = ["limit", str(model_file), "--repeatability-csv", str(csv_file), "--csv-units", "mm", "--encoder-resolution",
            "0.01deg,0.01deg,0.01deg,1.745e-4rad,0.01deg,0.01deg", "--length-quantum-mm", "0.1",
            "--angle-quantum-deg", "0.001", "--samples", "3000", "--seed", "5", "--out", str(out)]
    assert cli(*argv)[0] == 0
    d = json.loads(out.read_text())
    assert d["schema"] == LIMIT_SCHEMA
    np.testing.assert_allclose(d["repeatability"], 3.709980e-3, rtol=1e-6)
    np.testing.assert_allclose(d["precision_detail"]["encoder_resolution"][3], 1.745e-4)
    np.testing.assert_allclose(d["precision_detail"]["length_quantum"], 1e-4)
    from robocal.io import read_model

    direct = controller_precision(read_model(model_file), n_samples=3000, rng=5,
                                  encoder_resolution=[0.01 * DEG] * 3 + [1.745e-4] + [0.01 * DEG] * 2,
                                  length_quantum=1e-4, angle_quantum=1e-3 * DEG)
    np.testing.assert_allclose(d["precision"], direct.mean, rtol=1e-12)
    # no overwrite without --force
    code, _, err = cli(*argv)
    assert code == 2 and "exists" in err
    assert cli(*argv, "--force")[0] == 0


@pytest.mark.parametrize("resolution, words", [
    ("0.01deg,0.01deg", "6 joints"),
    ("0.01deg,0.01deg,0.01deg,0.01deg,0.01deg,0.1mm", "joint 6"),
    ("0.01deg,0.01deg,0.01deg,0.01deg,0.01deg,0.01", "unit"),
    ("0.01deg,0.01deg,0.01deg,0.01deg,0.01deg,-0.01deg", "joint 6: '-0.01deg' is not a resolution"),
    # a step past a whole turn, no step at all, an infinite one
    ("1000deg,0.01deg,0.01deg,0.01deg,0.01deg,0.01deg", "joint 1: '1000deg' is not a resolution: expected above 0 "
                                                        "and up to 1 degree"),
    ("0.01deg,0.01deg,0rad,0.01deg,0.01deg,0.01deg", "joint 3: '0rad'"),
    ("0.01deg,0.01deg,0.01deg,0.01deg,1e400deg,0.01deg", "joint 5"),
])
def test_cli_bad_resolution_is_one_line(model_file, tmp_path, resolution, words, cli):
    out = tmp_path / "x.json"
    code, _, err = cli("limit", model_file, "--repeatability-mm", "0.03", "--encoder-resolution", resolution,
                       "--length-quantum-mm", "0.1", "--angle-quantum-deg", "0.001", "--samples", "100", "--out", out)
    assert_one_line_error(code, err, [words], out, command="limit")


@pytest.mark.parametrize("resolution, words", [
    # a unit slip: 1e9 mm gave a limit of 249,433,807 mm, exit 0
    ("0.01deg,1e9mm,0.12mm,0.005deg,0.002deg,0.002deg", "joint 2: '1e9mm' is not a resolution: expected above 0 and "
                                                        "up to 1 mm"),
    ("0.01deg,0.1mm,0.12m,0.005deg,0.002deg,0.002deg", "joint 3: '0.12m'"),
])
def test_cli_a_prismatic_resolution_beyond_a_millimetre_is_refused(tmp_path, resolution, words, cli):
    out = tmp_path / "x.json"
    th8 = Path(__file__).resolve().parents[1] / "examples" / "th8" / "model.yaml"
    code, _, err = cli("limit", th8, "--repeatability-mm", "0.3", "--encoder-resolution", resolution,
                       "--length-quantum-mm", "0.1", "--angle-quantum-deg", "0.001", "--samples", "100", "--out", out)
    assert_one_line_error(code, err, ["--encoder-resolution", words], out, command="limit")


@pytest.mark.parametrize("option, unit", [("--length-quantum-mm", "1 mm"), ("--angle-quantum-deg", "1 degree")])
@pytest.mark.parametrize("quantum, code", [("0", 0), ("1", 0), ("1.5", 2), ("10", 2), ("180", 2), ("1000", 2)])
def test_cli_a_quantum_coarser_than_an_encoder_count_is_refused(tmp_path, option, unit, quantum, code, cli):
    """A length quantum of 1000 mm gave a limit of 1133 mm, an angle quantum of 180 degrees one of
    2434 mm, exit 0: no controller rounds its dimensions so, and 10 typed for 10 um is a slip of unit."""
    out = tmp_path / "x.json"
    th8 = Path(__file__).resolve().parents[1] / "examples" / "th8" / "model.yaml"
    quanta = {"--length-quantum-mm": "0.1", "--angle-quantum-deg": "0.001", option: quantum}
    got, _, err = cli("limit", th8, "--repeatability-mm", "0.3", "--encoder-resolution",
                      "0.01deg,0.1mm,0.12mm,0.005deg,0.002deg,0.002deg", *[a for kv in quanta.items() for a in kv],
                      "--samples", "100", "--out", out)
    if code == 0:
        stored = json.loads(out.read_text())["precision_detail"]
        assert got == 0 and stored[option[2:].split("-")[0] + "_quantum"] == pytest.approx(
            float(quantum) * (1e-3 if "mm" in option else math.pi / 180), rel=1e-15)
    else:
        assert_one_line_error(got, err, [option, f"expected a number from 0 to {unit}", f"got '{quantum}'"],
                              out, command="limit")


@pytest.mark.parametrize("edit, words", [
    # every cycle a copy of the first: 'repeatability 0.0000 mm', exit 0
    (lambda rows: [rows[0]] + [",".join(r.split(",")[:2] + rows[int(r.split(",")[0])].split(",")[2:])
                               for r in rows[1:]],
     ["rep.csv: lines 2-151: the cycles of each of the 5 poses read the same x_mm, y_mm, z_mm"]),
    # y in metres beside x and z in mm: 'repeatability 260.3 mm', exit 0
    (lambda rows: [rows[0].replace("y_mm", "y_m")] + rows[1:], ["rep.csv: line 1: columns 'x_mm', 'y_m', 'z_mm'"]),
])
def test_cli_a_repeatability_file_that_cannot_be_measured_is_refused(tmp_path, edit, words, cli):
    th8 = Path(__file__).resolve().parents[1] / "examples" / "th8"
    rows = (th8 / "repeatability.csv").read_text().splitlines()
    (tmp_path / "rep.csv").write_text("\n".join(edit(rows)) + "\n")
    out = tmp_path / "x.json"
    code, _, err = cli("limit", th8 / "model.yaml", "--repeatability-csv", tmp_path / "rep.csv", "--encoder-resolution",
                       "0.01deg,0.1mm,0.12mm,0.005deg,0.002deg,0.002deg", "--length-quantum-mm", "0.1",
                       "--angle-quantum-deg", "0.001", "--samples", "100", "--out", out)
    assert_one_line_error(code, err, words, out, command="limit")


def test_cli_main_with_progress_on_a_terminal(model_file, tmp_path, capsys, monkeypatch):
    from robocal.cli import main

    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    out = tmp_path / "limit.json"
    code = main(["limit", str(model_file), "--repeatability-mm", "0.03", "--encoder-resolution",
                 ",".join(["0.01deg"] * 6), "--length-quantum-mm", "0.1", "--angle-quantum-deg", "0.001",
                 "--samples", "3000", "--chunk-size", "1000", "--out", str(out)])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert "3000/3000" in captured.err and "limit of absolute accuracy" in captured.out
    d = json.loads(out.read_text())
    assert d["repeatability"] == pytest.approx(0.03e-3, rel=1e-12) and d["run"]["seed"] == 0


def test_a_monte_carlo_beyond_its_work_is_refused_before_it_starts():
    """The work is samples x frames x (1 + markers evaluated / 5): ten markers on a six-joint arm
    make 10^7 samples about 45 s (over the 30 s bound), one marker 18 s (within it)."""
    many = industrial_6r(markers=tuple((f"m{i}", (0.0, 0.0, 0.01 * i)) for i in range(10)))
    with pytest.raises(rc.InputError) as exc:
        controller_precision(many, n_samples=10 ** 7, rng=0, markers="all", **QUANTA)
    assert exc.value.where == "n_samples"
    assert "about 45 s; robocal runs up to about 30 s, 6,666,666 samples of this model" in str(exc.value)


def test_cli_refuses_the_samples_of_hours(model_file, tmp_path):
    """10^8 samples (what --samples allowed) ran over 120 s: refused at once, in one line."""
    import subprocess
    out = tmp_path / "x.json"
    run = subprocess.run([sys.executable, "-m", "robocal", "limit", str(model_file), "--repeatability-mm", "0.03",
                          "--encoder-resolution", "0.01deg,0.01deg,0.01deg,0.01deg,0.01deg,0.01deg",
                          "--length-quantum-mm", "0.1", "--angle-quantum-deg", "0.001", "--samples", "100000000",
                          "--out", str(out)], capture_output=True, text=True, timeout=60)
    assert_one_line_error(run.returncode, run.stderr, ["--samples", "from 1 to 10,000,000"], out, command="limit")
