"""Measurement files as instruments and controllers export them, read without conversion scripts.

The fixtures are made here by simulation, in the shapes real exports take (made up by us, not
copied from anyone): a ';'/decimal-comma tracker file with timestamps, temperatures, commanded
goals, per-axis standard deviations and 6D columns named its own way; a whitespace-separated
instrument file beside a controller's joint-readings file; a file with a separator at the end of
every line. Each calibrates from the command line with at most a column map (given on the command
line or as an instrument profile) and gives the same result as the clean file.
"""

import json

import numpy as np
import pytest
from conftest import assert_one_line_error
from robots import arm6r
from scipy.spatial.transform import Rotation

import robocal as rc
from robocal.io import ColumnMap, read_measurements, read_profile, write_measurements

N = 24


def _model_file(tmp_path):
    model = arm6r()
    rc.write_model(model, tmp_path / "model.yaml")
    return rc.read_model(tmp_path / "model.yaml")


def _num(v: float, decimal: str = ".") -> str:
    return repr(float(v)).replace(".", decimal)


def _estimates(out_dir) -> dict:
    d = json.loads((out_dir / "result.json").read_text())
    return {p["name"]: p["estimate"] for p in d["parameters"]}


def _same_result(cli, tmp_path, model_file, clean, export, *options):
    runs = []
    for name, path, opts in (("clean", clean, ()), ("export", export, options)):
        code, out, err = cli("calibrate", model_file, path, "--out", tmp_path / name, *opts)
        assert code == 0, err
        runs.append((_estimates(tmp_path / name), out))
    (a, _), (b, out) = runs
    assert a.keys() == b.keys()
    for k in a:
        assert b[k] == pytest.approx(a[k], rel=1e-9, abs=1e-12), k
    return out


def test_tracker_export_with_a_profile(tmp_path, cli):
    """';' and decimal comma, extra columns, per-axis deviations, 6D as Rx Ry Rz, a trailing ';'."""
    model = _model_file(tmp_path)
    rng = np.random.default_rng(3)
    true, data = rc.simulate(model, N, orientation=True, noise_rot=1e-4, seed=3)
    std = rng.uniform(0.01, 0.03, (N, 3))                   # mm, per axis
    rms = np.sqrt(np.mean(std ** 2, axis=1)) / 1e3
    clean = rc.Measurements(q=data.q, positions=data.positions, rotations=data.rotations,
                            marker_names=data.marker_names, joint_names=data.joint_names,
                            sigma=rms[:, None], sigma_rot=np.full((N, 1), 2e-4))
    write_measurements(clean, tmp_path / "clean.csv", model=model, orientation="euler:XYZ")

    angles = Rotation.from_matrix(data.rotations[:, 0]).as_euler("XYZ", degrees=True)
    head = (["Index", "Timestamp", "Temp_C"] + [f"goal_{j}" for j in model.joint_names] + list(model.joint_names)
            + ["measurement_x", "measurement_y", "measurement_z", "std_x", "std_y", "std_z", "Rx", "Ry", "Rz",
               "std_rot"])
    lines = [";".join(head) + ";"]
    for i in range(N):
        goal = np.rad2deg(data.q[i]) + rng.normal(0, 0.01, 6)
        cells = ([str(i + 1), f"2026-11-25 10:{i:02d}:00", _num(21.3 + 0.01 * i, ",")]
                 + [_num(v, ",") for v in goal] + [_num(v, ",") for v in np.rad2deg(data.q[i])]
                 + [_num(v * 1e3, ",") for v in data.positions[i, 0]] + [_num(v, ",") for v in std[i]]
                 + [_num(v, ",") for v in angles[i]] + [_num(np.rad2deg(2e-4), ",")])
        lines.append(";".join(cells) + ";")
    (tmp_path / "export.csv").write_text("\n".join(lines) + "\n")
    (tmp_path / "tracker.yaml").write_text(
        "robocal_profile: 1\nname: a tracker's export\nunits: mm-deg\norientation: euler:XYZ\n"
        "columns: {Index: pose, measurement_x: tool_x, measurement_y: tool_y, measurement_z: tool_z,\n"
        "          std_x: tool_sigma_x, std_y: tool_sigma_y, std_z: tool_sigma_z,\n"
        "          Rx: tool_e1, Ry: tool_e2, Rz: tool_e3, std_rot: tool_sigma_rot}\n"
        "unknown: ignore\n")
    out = _same_result(cli, tmp_path, tmp_path / "model.yaml", tmp_path / "clean.csv", tmp_path / "export.csv",
                       "--profile", tmp_path / "tracker.yaml")
    assert "separator ';' (detected)" in out and "decimal mark ',' (detected)" in out
    assert "ignored: Timestamp, Temp_C, goal_j1" in out

    back = read_measurements(tmp_path / "export.csv", model, profile=tmp_path / "tracker.yaml")
    np.testing.assert_allclose(back.sigma[:, 0], rms, rtol=1e-12)
    np.testing.assert_allclose(back.rotations, data.rotations, atol=1e-12)
    # the same reading from the API without the profile file
    prof = read_profile(tmp_path / "tracker.yaml")
    again = read_measurements(tmp_path / "export.csv", model, units="mm-deg", orientation="euler:XYZ",
                              columns=dict(prof.columns.rename), unknown="ignore")
    np.testing.assert_array_equal(again.positions, back.positions)


def test_whitespace_instrument_file_joined_to_joint_readings(tmp_path, cli):
    model = _model_file(tmp_path)
    true, data = rc.simulate(model, N, seed=5)
    write_measurements(rc.Measurements(q=data.q[1:], positions=data.positions[1:], marker_names=data.marker_names,
                                       joint_names=data.joint_names, labels=tuple(str(i) for i in range(1, N))),
                       tmp_path / "clean.csv", model=model)
    # the instrument missed pose 0; the controller log has no pose 99; rows in another order
    pts = ["Point      X          Y          Z"]
    for i in list(range(1, N))[::-1] + [99]:
        p = data.positions[min(i, N - 1), 0] * 1e3
        pts.append(f"{i:<6d} " + "  ".join(_num(v) for v in p))
    (tmp_path / "points.txt").write_text("\n".join(pts) + "\n")
    joints = ["pose," + ",".join(f"{j}_deg" for j in model.joint_names)]
    joints += [f"{i}," + ",".join(_num(v) for v in np.rad2deg(data.q[i])) for i in range(N)]
    (tmp_path / "joints.csv").write_text("\n".join(joints) + "\n")
    out = _same_result(cli, tmp_path, tmp_path / "model.yaml", tmp_path / "clean.csv", tmp_path / "points.txt",
                       "--joints", tmp_path / "joints.csv", "--map", "Point=pose,X=tool_x_mm,Y=tool_y_mm,Z=tool_z_mm")
    assert "separator whitespace (detected)" in out
    assert "points.txt have no joint readings" in out and "pose 99" in out
    assert "joints.csv have no measurement" in out and "pose 0" in out


def test_trailing_separator_calibrates_as_the_clean_file(tmp_path, cli):
    model = _model_file(tmp_path)
    true, data = rc.simulate(model, N, seed=6)
    write_measurements(data, tmp_path / "clean.csv", model=model)
    text = (tmp_path / "clean.csv").read_text().splitlines()
    (tmp_path / "trailing.csv").write_text("\n".join(line + "," for line in text) + "\n")
    _same_result(cli, tmp_path, tmp_path / "model.yaml", tmp_path / "clean.csv", tmp_path / "trailing.csv")


def test_tab_as_written_and_column_map_ignores(tmp_path):
    model = _model_file(tmp_path)
    _, data = rc.simulate(model, 8, seed=7)
    write_measurements(data, tmp_path / "clean.csv", model=model)
    text = (tmp_path / "clean.csv").read_text().replace(",", "\t")
    (tmp_path / "tab.txt").write_text(text)
    for sep in ("\\t", "\t", "tab", None):
        back = read_measurements(tmp_path / "tab.txt", model, sep=sep)
        np.testing.assert_allclose(back.positions, data.positions, atol=1e-15)
    # a head joint that does not move the markers, ignored by name
    lines = text.splitlines()
    lines = [lines[0] + "\thead_deg"] + [ln + "\t12.5" for ln in lines[1:]]
    (tmp_path / "head.txt").write_text("\n".join(lines) + "\n")
    with pytest.raises(rc.InputError, match="unknown column 'head_deg'.*--ignore 'head_deg'"):
        read_measurements(tmp_path / "head.txt", model)
    back = read_measurements(tmp_path / "head.txt", model, columns=ColumnMap(ignore={"head_deg"}))
    assert "columns ignored as asked: head_deg" in back.extra["notes"][-1]


HEADER = "pose;j1_deg;j2_deg;j3_deg;j4_deg;j5_deg;j6_deg;tool_x_mm;tool_y_mm;tool_z_mm\n"
# decimal commas, and one row of decimal points (line 4)
MIXED = HEADER + "1;0,5;1,5;2,5;3;4;5;1000;200;300\n2;0,6;1,5;2,5;3;4;5;1000;200;300\n3;0.7;1;2;3;4;5;1000;200;300\n"
BOTH_MARKS = ("the file writes both decimal marks (numbers of its first rows: 1 with '.' from line 4, 6 with ',' "
              "from line 2): a file holds one; correct the ones with '.', from line 4")


@pytest.mark.parametrize("text, argv, words", [
    (HEADER + "1;0,5;1;2;3;4;5;1000;200;300\n", ("--sep", ","),
     ["line 1", "one column", "looks separated by ';'", "--sep ';'"]),
    (HEADER + "1;0,5;1;2;3;4;5;1000;200;300\n", ("--decimal", "."),
     ["line 2", "column 'j1_deg'", "'0,5'", "decimal comma", "--decimal ,", "or leave the decimal mark out"]),
    # the detected mark blamed line 2 and told to leave the mark out to have it detected, which it was
    (MIXED, (), ["line 4, column 'j1_deg'", "'0.7'", BOTH_MARKS]),
    (MIXED, ("--decimal", ","), ["line 4, column 'j1_deg'", BOTH_MARKS]),
    (MIXED, ("--decimal", "."), ["line 2, column 'j1_deg'", BOTH_MARKS]),
    # a quoted decimal comma in a comma-separated file was told to use --decimal , (then refused)
    (HEADER.replace(";", ",") + '1,"0,5",1.5,2,3,4,5,1000,200,300\n', (),
     ["line 2, column 'j1_deg'", "'0,5'", "the file's other numbers write '.' (1 in its first rows, from line 2): a "
                                          "file holds one decimal mark; correct this cell"]),
    (HEADER.replace(";", ",") + '1,"0,5",1,2,3,4,5,1000,200,300\n', (),
     ["line 2, column 'j1_deg'", "a decimal comma cannot be read where commas separate the columns: write the number "
                                 "with a decimal point"]),
])
def test_hints_name_the_likely_fix(tmp_path, cli, text, argv, words):
    _model_file(tmp_path)
    (tmp_path / "d.csv").write_text(text)
    code, out, err = cli("calibrate", tmp_path / "model.yaml", tmp_path / "d.csv", "--out", tmp_path / "o", *argv)
    assert_one_line_error(code, err, words, tmp_path / "o")
    assert "--decimal ," not in err or "--decimal ," in " ".join(words)


def test_bad_column_map_option(tmp_path, cli):
    _model_file(tmp_path)
    code, out, err = cli("calibrate", tmp_path / "model.yaml", tmp_path / "d.csv", "--out", tmp_path / "o",
                         "--map", "X")
    assert code == 2 and "argument --map: expected FILE_COLUMN=ROBOCAL_COLUMN[,...], got 'X'" in err


def test_join_and_profile_errors(tmp_path):
    model = _model_file(tmp_path)
    (tmp_path / "p.txt").write_text("pose tool_x_mm tool_y_mm tool_z_mm\n1 1 2 3\n1 1 2 3\n")
    (tmp_path / "j.csv").write_text("pose," + ",".join(f"{j}_deg" for j in model.joint_names) + "\n2,1,2,3,4,5,6\n")
    with pytest.raises(rc.InputError, match=r"p.txt: line 3: pose '1' appears twice \(also line 2\)"):
        read_measurements(tmp_path / "p.txt", model, joints=tmp_path / "j.csv")
    (tmp_path / "p.txt").write_text("pose tool_x_mm tool_y_mm tool_z_mm\n1 1 2 3\n")
    with pytest.raises(rc.InputError, match="no pose value is in both files"):
        read_measurements(tmp_path / "p.txt", model, joints=tmp_path / "j.csv")
    with pytest.raises(rc.InputError, match="no key column 'Point'"):
        read_measurements(tmp_path / "p.txt", model, joints=tmp_path / "j.csv", key="Point")
    for text, words in (("robocal_profile: 1\nsepp: ';'\n", "unknown key 'sepp'; did you mean 'sep'"),
                        ("robocal_profile: 1\nunknown: skip\n", "unknown: "),
                        ("robocal_profile: 1\ndecimal: ';'\n", "decimal"),
                        ("robocal_profile: 2\n", "robocal_profile")):
        (tmp_path / "prof.yaml").write_text(text)
        with pytest.raises(rc.InputError, match=words):
            read_profile(tmp_path / "prof.yaml")


def test_per_axis_deviations_need_all_three(tmp_path):
    model = _model_file(tmp_path)
    (tmp_path / "d.csv").write_text("pose," + ",".join(f"{j}_deg" for j in model.joint_names)
                                    + ",tool_x_mm,tool_y_mm,tool_z_mm,tool_sigma_x_mm,tool_sigma_y_mm\n"
                                      "1,1,2,3,4,5,6,1000,200,300,0.01,0.02\n")
    with pytest.raises(rc.InputError, match="give tool_sigma or all of tool_sigma_x"):
        read_measurements(tmp_path / "d.csv", model)
