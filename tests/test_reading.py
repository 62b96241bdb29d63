"""Measurement files as real campaigns come: whitespace separators, maps over a profile, unnamed and
spaced header cells, files without a header line, per-axis rotation deviations, positions stored as
target plus deviation, the joint file's own notes, and per-pose series labels."""

import csv
import io
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_one_line_error
from fuzz_cases import MEASUREMENTS, MODEL

import robocal as rc

REAL = Path(__file__).parent / "data" / "real" / "serial_robots_datasets"
UR5_GRID = REAL / "UR5" / "3D_UR5_uncalibrated_grid_cleaned.csv"


@pytest.fixture
def files(tmp_path):
    (tmp_path / "model.yaml").write_text(MODEL)
    (tmp_path / "data.csv").write_text(MEASUREMENTS)
    return tmp_path


def table(text=MEASUREMENTS):
    rows = list(csv.reader(io.StringIO(text)))
    return rows[0], rows[1:]


def write(path, header, rows, sep=","):
    path.write_text("".join(sep.join(r) + "\n" for r in ([header] if header else []) + rows))
    return path


@pytest.fixture
def reference(files):
    return rc.read_measurements(files / "data.csv", rc.read_model(files / "model.yaml"))


def same(a, b):
    np.testing.assert_array_equal(a.q, b.q)
    np.testing.assert_array_equal(a.positions, b.positions)
    assert a.labels == b.labels


def test_whitespace_separator_on_the_command_line_and_in_a_profile(files, cli, reference):
    header, rows = table()
    write(files / "ws.txt", header, rows, sep="  ")
    model = rc.read_model(files / "model.yaml")
    same(rc.read_measurements(files / "ws.txt", model, sep="whitespace"), reference)
    (files / "p.yaml").write_text("robocal_profile: 1\nsep: whitespace\n")
    same(rc.read_measurements(files / "ws.txt", model, profile=files / "p.yaml"), reference)
    for k, extra in enumerate((("--sep", "whitespace"), ("--profile", files / "p.yaml"))):
        code, _, err = cli("calibrate", files / "model.yaml", files / "ws.txt", "--out", files / f"o{k}", *extra)
        assert code in (0, 3), err


def test_command_line_map_wins_over_the_profile_ignore(files, cli, reference):
    header, rows = table()
    header = ["Index" if c == "pose" else c for c in header]
    write(files / "d.csv", header, rows)
    (files / "p.yaml").write_text("robocal_profile: 1\nignore: [Index]\n")
    model = rc.read_model(files / "model.yaml")
    assert rc.read_measurements(files / "d.csv", model, profile=files / "p.yaml").labels[0] == "line 2"
    data = rc.read_measurements(files / "d.csv", model, profile=files / "p.yaml", columns={"Index": "pose"})
    same(data, reference)
    # and the other way round: a column the profile maps, ignored on the call
    (files / "p.yaml").write_text("robocal_profile: 1\ncolumns: {Index: pose}\n")
    data = rc.read_measurements(files / "d.csv", model, profile=files / "p.yaml", columns={"Index": None})
    assert data.labels[0] == "line 2"
    code, _, err = cli("calibrate", files / "model.yaml", files / "d.csv", "--out", files / "o",
                       "--profile", files / "p.yaml", "--map", "Index=pose")
    assert code in (0, 3), err


def test_an_empty_header_cell_mapped_on_the_command_line(files, cli, reference):
    header, rows = table()
    header = ["" if c == "pose" else c for c in header]
    write(files / "d.csv", header, rows)
    code, _, err = cli("calibrate", files / "model.yaml", files / "d.csv", "--out", files / "o")
    assert_one_line_error(code, err, ["d.csv", "no name"])
    code, _, err = cli("calibrate", files / "model.yaml", files / "d.csv", "--out", files / "o", "--map", "=pose")
    assert code in (0, 3), err
    same(rc.read_measurements(files / "d.csv", rc.read_model(files / "model.yaml"), columns={"": "pose"}), reference)


def test_header_names_with_spaces(files, reference):
    header, rows = table()
    spaced = [{"tool_x_mm": "Tool X", "tool_y_mm": "Tool Y", "tool_z_mm": "Tool Z"}.get(c, c) for c in header]
    names = {"Tool X": "tool_x_mm", "Tool Y": "tool_y_mm", "Tool Z": "tool_z_mm"}
    model = rc.read_model(files / "model.yaml")
    write(files / "d.csv", spaced, rows)
    same(rc.read_measurements(files / "d.csv", model, columns=names), reference)
    # separated by whitespace: names with one space, columns apart by two or more, or a tab
    write(files / "d.txt", spaced, rows, sep="   ")
    data = rc.read_measurements(files / "d.txt", model, columns=names)
    same(data, reference)
    assert any("hold spaces" in n for n in data.extra["notes"])
    write(files / "d.tsv", spaced, rows, sep="\t")
    same(rc.read_measurements(files / "d.tsv", model, columns=names, sep="whitespace"), reference)


def test_a_file_without_a_header_line(files, cli, reference):
    header, rows = table()
    write(files / "d.csv", None, rows)
    code, _, err = cli("calibrate", files / "model.yaml", files / "d.csv", "--out", files / "o")
    assert_one_line_error(code, err, ["d.csv", "line 1", "no header line", "--header"])
    code, _, err = cli("calibrate", files / "model.yaml", files / "d.csv", "--out", files / "o",
                       "--header", ",".join(header))
    assert code in (0, 3), err
    model = rc.read_model(files / "model.yaml")
    data = rc.read_measurements(files / "d.csv", model, header=header)
    same(data, reference)
    (files / "p.yaml").write_text(f"robocal_profile: 1\nheader: [{', '.join(header)}]\n")
    same(rc.read_measurements(files / "d.csv", model, profile=files / "p.yaml"), reference)
    # messages name the line of the file, the first line being data
    rows[4][1] = "x"
    write(files / "d.csv", None, rows)
    with pytest.raises(rc.InputError, match="line 5, column 'j1_deg'"):
        rc.read_measurements(files / "d.csv", model, header=header)
    with pytest.raises(rc.InputError, match="header"):
        rc.read_measurements(files / "d.csv", model, header=header[:-2])


def test_per_axis_rotation_deviations(files):
    from scipy.spatial.transform import Rotation

    header, rows = table()
    header = header[:-1] + ["tool_qx", "tool_qy", "tool_qz", "tool_qw", "std_rx", "std_ry", "std_rz"]
    rng = np.random.default_rng(1)
    quats = Rotation.random(len(rows), random_state=2).as_quat()
    stds = rng.uniform(0.01, 0.05, (len(rows), 3))
    rows = [r[:-1] + [repr(float(v)) for v in q] + [repr(float(v)) for v in s] for r, q, s in zip(rows, quats, stds)]
    write(files / "d.csv", header, rows)
    model = rc.read_model(files / "model.yaml")
    with pytest.raises(rc.InputError, match="std_rx"):
        rc.read_measurements(files / "d.csv", model)
    ignored = rc.read_measurements(files / "d.csv", model, columns={"std_rx": None, "std_ry": None, "std_rz": None})
    assert ignored.sigma_rot is None and ignored.rotations is not None
    used = rc.read_measurements(files / "d.csv", model, units="mm-deg",
                                columns={f"std_r{a}": f"tool_sigma_r{a}" for a in "xyz"})
    np.testing.assert_allclose(used.sigma_rot[:, 0], np.deg2rad(np.sqrt(np.mean(stds ** 2, axis=1))), rtol=1e-12)
    with pytest.raises(rc.InputError, match="all of"):
        rc.read_measurements(files / "d.csv", model, units="mm-deg",
                             columns={"std_rx": "tool_sigma_rx", "std_ry": None, "std_rz": None})


def test_position_as_target_plus_deviation(files, cli, reference):
    header, rows = table()
    k = [header.index(f"tool_{a}_mm") for a in "xyz"]
    header = header[:k[0]] + ["x_t", "y_t", "z_t", "x_dif", "y_dif", "z_dif"] + header[k[2] + 1:]
    dif = np.random.default_rng(3).normal(0, 2, (len(rows), 3)).round(6)
    out = []
    for r, d in zip(rows, dif):
        target = [float(r[j]) - v for j, v in zip(k, d)]
        out.append(r[:k[0]] + [repr(float(v)) for v in target] + [repr(float(v)) for v in d] + r[k[2] + 1:])
    write(files / "d.csv", header, out)
    sums = {f"{a}_t+{a}_dif": f"tool_{a}_mm" for a in "xyz"}
    data = rc.read_measurements(files / "d.csv", rc.read_model(files / "model.yaml"), columns=sums)
    np.testing.assert_allclose(data.positions, reference.positions, rtol=0, atol=1e-12)
    (files / "p.yaml").write_text("robocal_profile: 1\ncolumns:\n" + "".join(f"  {k}: {v}\n" for k, v in sums.items()))
    code, _, err = cli("calibrate", files / "model.yaml", files / "d.csv", "--out", files / "o", "--profile",
                       files / "p.yaml")
    assert code in (0, 3), err
    code, _, err = cli("calibrate", files / "model.yaml", files / "d.csv", "--out", files / "o2", "--map",
                       ",".join(f"{k}={v}" for k, v in sums.items()))
    assert code in (0, 3), err
    out[6][k[0] + 3] = ""
    write(files / "d.csv", header, out)
    with pytest.raises(rc.InputError, match="line 8, column 'x_dif'"):
        rc.read_measurements(files / "d.csv", rc.read_model(files / "model.yaml"), columns=sums)


def test_a_bad_cell_of_a_mapped_column_names_the_files_own_column(files, cli):
    """The names a map gives are not in the user's file: a cell's fault names the file's column."""
    header, rows = table()
    header = ["step_order" if c == "pose" else "joint_1" if c == "j1_deg" else c for c in header]
    k = header.index("tool_x_mm")
    header[k:k + 1] = ["x_t", "x_dif"]
    rows = [r[:k] + [r[k], "0.0"] + r[k + 1:] for r in rows]
    rows[4][1] = "12.5abc"
    rows[7][k + 1] = "1e13"
    write(files / "d.csv", header, rows)
    mapping = "step_order=pose,x_t+x_dif=tool_x_mm,joint_1=j1_deg"
    code, _, err = cli("calibrate", files / "model.yaml", files / "d.csv", "--out", files / "o", "--map", mapping)
    assert_one_line_error(code, err, ["d.csv: line 6, column 'joint_1' (mapped to 'j1_deg'): expected a number, "
                                      "got '12.5abc'"], files / "o")
    rows[4][1] = "12.5"
    write(files / "d.csv", header, rows)
    code, _, err = cli("calibrate", files / "model.yaml", files / "d.csv", "--out", files / "o", "--map", mapping)
    assert_one_line_error(code, err, ["d.csv: line 9, column 'x_t+x_dif' (mapped to 'tool_x_mm'): "
                                      "'10000000001624.93' is too large for a measurement"], files / "o")


@pytest.mark.skipif(not UR5_GRID.exists(), reason="the real UR5 campaign is not here")
def test_the_real_ur5_campaign_reads_with_a_map_alone():
    columns = {"step_order": "pose", **{f"joint_{i}": f"j{i}_deg" for i in range(1, 7)},
               **{f"{a}_t+{a}_dif": f"tool_{a}_mm" for a in "xyz"}}
    data = rc.read_measurements(UR5_GRID, columns=columns)
    raw = np.genfromtxt(UR5_GRID, delimiter=",", names=True)
    assert data.n_poses == len(raw) == 1000
    measured = np.stack([raw[f"{a}_t"] + raw[f"{a}_dif"] for a in "xyz"], axis=1) * 1e-3
    np.testing.assert_allclose(data.positions[:, 0], measured, rtol=0, atol=1e-15)
    np.testing.assert_allclose(data.q, np.deg2rad(np.stack([raw[f"joint_{i}"] for i in range(1, 7)], axis=1)))


def test_joint_file_notes_under_its_own_name(files):
    header, rows = table()
    joint_cols = [k for k, c in enumerate(header) if c.startswith("j")]
    keep = [k for k in range(len(header)) if k not in joint_cols]
    write(files / "points.csv", [header[k] for k in keep], [[r[k] for k in keep] for r in rows])
    write(files / "joints.txt", ["pose"] + [header[k] for k in joint_cols] + ["Temp_C", "Odd"],
          [[r[0]] + [r[k] for k in joint_cols] + ["21.5", "1"] for r in rows], sep=";")
    data = rc.read_measurements(files / "points.csv", rc.read_model(files / "model.yaml"), joints=files / "joints.txt",
                                columns={"Temp_C": None}, unknown="ignore")
    notes = data.extra["notes"]
    joint_notes = [n for n in notes if n.startswith(f"reading {files / 'joints.txt'}: ")]
    assert any("separator ';'" in n for n in joint_notes), notes
    assert any("ignored as asked: Temp_C" in n for n in joint_notes), notes
    assert any("does not know, ignored: Odd" in n for n in joint_notes), notes
    assert not any(w in n for n in notes if n.startswith(f"reading {files / 'points.csv'}: ")
                   for w in ("';'", "Temp_C", "Odd")), notes


def test_a_bad_cell_of_a_mapped_column_of_the_joint_file_names_its_own_column(files):
    header, rows = table()
    joint_cols = [k for k, c in enumerate(header) if c.startswith("j")]
    keep = [k for k in range(len(header)) if k not in joint_cols]
    write(files / "points.csv", [header[k] for k in keep], [[r[k] for k in keep] for r in rows])
    jrows = [[r[0]] + [r[k] for k in joint_cols] for r in rows]
    jrows[4][1] = "12.5abc"
    jheader = ["Index", "joint_1"] + [header[k] for k in joint_cols[1:]]
    write(files / "joints.txt", jheader, jrows, sep=";")
    model, columns = rc.read_model(files / "model.yaml"), {"Index": "pose", "joint_1": "j1_deg"}
    with pytest.raises(rc.InputError) as e:
        rc.read_measurements(files / "points.csv", model, joints=files / "joints.txt", columns=columns)
    assert e.value.where == f"line 6 ({files / 'joints.txt'} line 6), column 'joint_1' (mapped to 'j1_deg')", e.value
    jrows[4][1], jrows[6][0] = "12.5", ""
    write(files / "joints.txt", jheader, jrows, sep=";")
    with pytest.raises(rc.InputError) as e:
        rc.read_measurements(files / "points.csv", model, joints=files / "joints.txt", columns=columns)
    assert (e.value.where, e.value.detail) == ("line 8, column 'Index' (mapped to 'pose')", "empty key cell"), e.value


def test_series_column_kept_per_pose_and_through_subsets(files, reference):
    header, rows = table()
    labels = [f"fold {i % 3}" if i % 5 else "" for i in range(len(rows))]
    for r in rows[::4]:
        r[-1] = "validation"
    write(files / "d.csv", header + ["series"], [r + [s] for r, s in zip(rows, labels)])
    model = rc.read_model(files / "model.yaml")
    data = rc.read_measurements(files / "d.csv", model)
    assert data.extra["series"].dtype.kind == "U" and list(data.extra["series"]) == labels
    assert list(data.subset([3, 1]).extra["series"]) == [labels[3], labels[1]]
    assert "validation" in data.extra  # the set column is still read
    from robocal.io import split_sets

    fit, val = split_sets(data)
    flags = data.extra["validation"]
    assert list(fit.extra["series"]) == [s for s, f in zip(labels, flags) if not f]
    assert list(val.extra["series"]) == [s for s, f in zip(labels, flags) if f]
    rc.write_measurements(data, files / "back.csv", model=model)
    assert list(rc.read_measurements(files / "back.csv", model).extra["series"]) == labels


def test_a_subset_is_the_record_built_and_checked_from_its_rows():
    """subset() skips the checks its rows passed already: every field equals that of a record made
    from scratch from the same rows, read-only, for integer, boolean and slice selections."""
    import dataclasses

    rng = np.random.default_rng(3)
    n = 40
    data = rc.Measurements(q=rng.normal(size=(n, 3)), positions=rng.normal(size=(n, 2, 3)), marker_names=("a", "b"),
                           sigma=rng.uniform(1e-5, 1e-4, size=(n, 2)), payload_mass=rng.uniform(0, 2, n),
                           labels=tuple(f"row {i + 2}" for i in range(n)),
                           extra={"series": np.array([f"s{i % 3}" for i in range(n)]), "note": "kept"})
    data = rc.Measurements(**{**{f.name: getattr(data, f.name) for f in dataclasses.fields(data)},
                              "mask": data.mask & (rng.random((n, 2)) > 0.2)}).with_approach()
    for index in (np.array([7, 3, 3, 20]), np.arange(n) % 4 == 1, slice(5, 30, 2), np.array([], dtype=int)):
        part = data.subset(index)
        made = rc.Measurements(**{f.name: getattr(part, f.name) for f in dataclasses.fields(part)})
        for f in dataclasses.fields(part):
            got, want = getattr(part, f.name), getattr(made, f.name)
            if isinstance(got, np.ndarray):
                assert got.dtype == want.dtype and np.array_equal(got, want, equal_nan=True), f.name
                assert not got.flags.writeable, f.name
            elif f.name == "extra":
                assert got.keys() == want.keys() and got["note"] == "kept"
                for k in ("series", "approach"):
                    assert np.array_equal(got[k], want[k]) and not got[k].flags.writeable
            else:
                assert got == want, f.name
        picked = np.arange(n)[index]
        assert part.labels == tuple(f"row {i + 2}" for i in picked)
        assert np.array_equal(part.q, data.q[picked]) and np.array_equal(part.mask, data.mask[picked])


# -- DH tables: the convention of a theta, d, a, alpha table is stated, never guessed ----------------

CRAIG = """name,joint,alpha_deg,a_mm,theta_deg,d_mm
j1,revolute,0,0,10,300
j2,revolute,-90,50,-20,0
j3,revolute,0,400,5,0
j4,revolute,-90,30,0,420
tool,marker,,,,,
"""


def _craig_table(path, comment=""):
    header, *rows = CRAIG.splitlines()
    rows = [r for r in rows if not r.startswith("tool")]
    path.write_text(comment + header + ",x_mm,y_mm,z_mm\n" + "".join(r + ",,,\n" for r in rows)
                    + "tool,marker,,,,,10,0,80\n")
    return path


def test_a_modified_dh_table_with_unit_suffixes_is_not_read_as_classic(tmp_path, cli):
    from robocal.io import read_dh_table

    path = _craig_table(tmp_path / "craig.csv")
    code, _, err = cli("import-dh", path, "--out", tmp_path / "m.yaml")
    assert_one_line_error(code, err, ["craig.csv", "classic", "modified", "--convention"], command="import-dh")
    assert not (tmp_path / "m.yaml").exists()
    model = read_dh_table(path, convention="modified")
    # the same robot written by hand as robocal frames: alpha, d (Craig's a), theta, r (Craig's d)
    rows = [(0, 0, 10, 300), (-90, 50, -20, 0), (0, 400, 5, 0), (-90, 30, 0, 420)]
    truth = rc.serial_model("craig", [dict(joint="revolute", alpha=np.deg2rad(al), d=a * 1e-3, theta=np.deg2rad(th),
                                           r=d * 1e-3) for al, a, th, d in rows], markers=[("tool", (0.01, 0, 0.08))])
    q = np.random.default_rng(4).uniform(-1, 1, (20, 4))
    def points(m):
        return rc.forward_kinematics(m, q).positions

    np.testing.assert_allclose(points(model), points(truth), atol=1e-12)
    assert np.abs(points(read_dh_table(path, convention="classic")) - points(truth)).max() > 1e-3
    _craig_table(tmp_path / "said.csv", "# convention: modified\n")
    np.testing.assert_allclose(points(read_dh_table(tmp_path / "said.csv")), points(truth), atol=1e-12)
    with pytest.raises(rc.InputError, match="says convention modified"):
        read_dh_table(tmp_path / "said.csv", convention="classic")
    code, _, err = cli("import-dh", path, "--out", tmp_path / "m.yaml", "--convention", "modified")
    assert code == 0, err
