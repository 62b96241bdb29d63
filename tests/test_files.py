"""File formats: model YAML, measurement CSV and result JSON round trips, and their error messages."""

import json

import numpy as np
import pytest
import yaml
from robots import arm6r, cylindrical
from scipy.spatial.transform import Rotation

import robocal as rc
from robocal.io import (
    measurements_to_csv,
    model_from_dict,
    model_to_dict,
    read_measurements,
    read_model,
    read_result,
    result_to_dict,
    split_sets,
    write_measurements,
    write_model,
    write_result,
)
from robocal.kinematics import Frame, Marker, Payload, RobotModel

DEG = np.pi / 180


def tree_model():
    """Coupled joint, a fixed frame, a frame hanging off the base, a rotated marker, a payload."""
    R = Rotation.from_rotvec([0.1, -0.2, 0.3]).as_matrix()
    frames = (
        Frame("f1", "revolute", -1, r=0.4, coupling=((0, 1.0),), has_beta=True, mass=10.0, com=(0, 0, 0.1)),
        Frame("f2", "prismatic", 0, alpha=-90 * DEG, d=0.05, coupling=((1, 1.0),), mass=4.0, k_theta=2e-6),
        Frame("f3", "revolute", 1, alpha=90 * DEG, coupling=((1, -1.0), (2, 1.0)), k_alpha=1e-6),
        Frame("f4", "fixed", 2, d=0.1, theta=0.3),
        Frame("aux", "revolute", -1, gamma=0.2, b=0.7, d=0.3, coupling=((3, 1.0),)),
    )
    return RobotModel(
        name="tree", frames=frames, joint_names=("a", "b", "c", "d"),
        joint_limits=((-3.0, 3.0), (0.0, 0.5), (-2.0, 2.0), (-np.inf, np.inf)),
        markers=(Marker("tool", 3, (0.01, 0.02, 0.15), tuple(map(tuple, R))), Marker("m2", 4, (0.1, 0, 0))),
        base_position=(1.0, -0.5, 0.2), base_rotation=tuple(map(tuple, R.T)), gravity=(0.0, 0.1, -9.8),
        payload=Payload(2.0, (0, 0, 0.05), 3), description="a test tree",
    )


def assert_same_model(a: RobotModel, b: RobotModel, tol=1e-12):
    np.testing.assert_allclose(rc.parameter_vector(a), rc.parameter_vector(b), atol=tol, rtol=0)
    np.testing.assert_allclose(a.base_rotation, b.base_rotation, atol=tol, rtol=0)
    for ma, mb in zip(a.markers, b.markers):
        np.testing.assert_allclose(ma.rotation, mb.rotation, atol=tol, rtol=0)
        assert (ma.name, ma.frame) == (mb.name, mb.frame)
    for fa, fb in zip(a.frames, b.frames):
        assert (fa.name, fa.joint, fa.parent, fa.has_beta, fa.coupling) == (fb.name, fb.joint, fb.parent,
                                                                           fb.has_beta, fb.coupling)
        assert fa.mass == pytest.approx(fb.mass, abs=tol)
        np.testing.assert_allclose(fa.com, fb.com, atol=tol, rtol=0)
    assert a.joint_names == b.joint_names
    np.testing.assert_allclose(a.joint_limits, b.joint_limits, atol=tol, rtol=0)
    assert a.payload.frame == b.payload.frame and a.payload.mass == b.payload.mass
    np.testing.assert_allclose(a.payload.com, b.payload.com, atol=tol, rtol=0)
    assert (a.name, a.description, a.gravity, a.marker_names) == (b.name, b.description, b.gravity, b.marker_names)


# ------------------------------------------------------------------------------------------------
# model file

@pytest.mark.parametrize("units", ["mm-deg", "m-rad", "mm-rad", "m-deg"])
@pytest.mark.parametrize("make", [tree_model, lambda: arm6r(masses=True), lambda: cylindrical(masses=True)])
def test_model_round_trip(tmp_path, units, make):
    m = make()
    write_model(m, tmp_path / "m.yaml", units=units)
    assert_same_model(m, read_model(tmp_path / "m.yaml"))


def test_calibrated_model_round_trips_exactly(tmp_path):
    """A calibrated model has full rotation matrices and odd values: they survive the file to 1e-12."""
    nominal = arm6r(markers=(("tool", (0.05, 0.02, 0.12)), ("t2", (0.1, 0.0, 0.1))))
    true, data = rc.simulate(nominal, 40, seed=3)
    result = rc.calibrate(nominal, data)
    write_model(result.calibrated_model, tmp_path / "cal.yaml")
    back = read_model(tmp_path / "cal.yaml")
    assert_same_model(result.calibrated_model, back)
    q = rc.random_configurations(nominal, 5, 1)
    np.testing.assert_allclose(rc.forward_kinematics(back, q).positions,
                               rc.forward_kinematics(result.calibrated_model, q).positions, atol=1e-12)


def test_model_file_defaults_and_conventions():
    d = {
        "robocal_model": 1, "units": {"length": "mm", "angle": "deg"},
        "base": {"position": [100, 0, 0], "rotation": {"rpy": [10, 20, 30]}},
        "joints": ["j1", {"name": "jB", "limits": [0, 400]}, "j3"],
        "frames": [
            {"name": "j1", "joint": "revolute"},
            {"name": "x2", "joint": "prismatic", "alpha": 90, "r": "1e2"},   # reads the next unused joint
            {"name": "x3", "joint": "revolute", "alpha": 90, "parent": "j1"},
        ],
        "markers": [{"name": "tool", "frame": "x3", "rotation": {"quaternion_xyzw": [0, 0, 1, 1]}}],
    }
    m = model_from_dict(d)
    assert [f.coupling for f in m.frames] == [((0, 1.0),), ((1, 1.0),), ((2, 1.0),)]
    assert [f.parent for f in m.frames] == [-1, 0, 0]
    assert [f.has_beta for f in m.frames] == [True, False, False]   # auto: parallel axes within 1 degree
    assert m.frames[1].r == pytest.approx(0.1)
    assert m.joint_limits[1] == pytest.approx((0.0, 0.4))           # prismatic: length unit
    assert m.joint_limits[0] == pytest.approx((-np.pi, np.pi))
    # rpy is fixed-axis: R = Rz(yaw) Ry(pitch) Rx(roll)
    r, p, y = np.deg2rad([10, 20, 30])
    Rz = Rotation.from_rotvec([0, 0, y]).as_matrix()
    Ry = Rotation.from_rotvec([0, p, 0]).as_matrix()
    Rx = Rotation.from_rotvec([r, 0, 0]).as_matrix()
    np.testing.assert_allclose(m.base_rotation, Rz @ Ry @ Rx, atol=1e-15)
    np.testing.assert_allclose(m.markers[0].rotation, Rotation.from_rotvec([0, 0, np.pi / 2]).as_matrix(),
                               atol=1e-15)
    assert m.name == "<dict>" or m.name  # a name is always there
    assert model_to_dict(m)["frames"][1]["reading"] == "jB"


def good_dict():
    return model_to_dict(arm6r())


@pytest.mark.parametrize("edit, where, words", [
    (lambda d: d["frames"][1].update(alpah=d["frames"][1].pop("alpha")), "frames[1].alpah", "did you mean 'alpha'"),
    (lambda d: d["frames"][2].pop("joint"), "frames[2].joint", "missing required key"),
    (lambda d: d["frames"][2].update(alpha="abc"), "frames[2].alpha", "expected a number, got 'abc'"),
    (lambda d: d["units"].update(length="inch"), "units.length", "unknown length unit 'inch'"),
    (lambda d: d.pop("units"), "units", "missing required key"),
    (lambda d: d.update(robocal_model=7), "robocal_model", "unsupported format version"),
    (lambda d: d["markers"][0].update(frame="j9"), "markers[0].frame", "unknown frame 'j9'"),
    (lambda d: d["joints"][3].update(name="j2"), "joints[3].name", "'j2' is named twice"),
    (lambda d: d["frames"][3].update(name="j1"), "frames[3].name", "'j1' is named twice"),
    (lambda d: d["frames"][0].update(joint="rotary"), "frames[0].joint", "revolute, prismatic, fixed"),
    (lambda d: d["frames"][1].update(parent="j5"), "frames[1].parent", "not a frame defined before"),
    (lambda d: d["frames"][1].update(reading="j7"), "frames[1].reading", "unknown joint 'j7'"),
    (lambda d: d["base"].update(rotation={"matrix": [[1, 0, 0], [0, 1, 0], [0, 0, 2]]}), "base.rotation.matrix",
     "an entry is 1 from the nearest rotation; printed matrices are accepted within 0.005"),
    (lambda d: d["base"].update(rotation={"matrix": [[1, 0, 0], [0, 1, 0], [0, 0, -1]]}), "base.rotation.matrix",
     "a reflection"),
    (lambda d: d["markers"][0].update(rotation={"quaternion_xyzw": [0, 0, 0, 0]}),
     "markers[0].rotation.quaternion_xyzw", "zero norm"),
    (lambda d: d["joints"][0].update(limits=[10, -10]), "joints[0].limits", "lower limit exceeds"),
    # a joint of no range, and one that drives no frame, were read as if they could be calibrated
    (lambda d: d["joints"][4].update(limits=[10, 10]), "joints[4].limits",
     "lower and upper limit are both 10: a joint that cannot move can be neither moved nor calibrated"),
    (lambda d: d["joints"].append({"name": "j7", "limits": [-180, 180]}), "joints[6]",
     "joint 'j7' drives no frame (no frame's reading or coupling names it): add the frame it moves, or leave the "
     "joint out"),
    (lambda d: d.update(colour="red"), "colour", "unknown key"),
    (lambda d: d["frames"][0].update(name="base"), "frames[0].name", "reserved"),
])
def test_model_file_errors(tmp_path, edit, where, words):
    d = good_dict()
    edit(d)
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(d, sort_keys=False))
    with pytest.raises(rc.InputError) as err:
        read_model(path)
    assert err.value.source == str(path)
    assert err.value.where == where
    assert words in str(err.value)
    assert str(err.value).startswith(f"{path}: {where}: ")


def test_model_file_not_yaml(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("robocal_model: 1\nframes: [a, b\n")
    with pytest.raises(rc.InputError, match=r"bad.yaml: line \d+, column \d+: not valid YAML"):
        read_model(path)
    with pytest.raises(rc.InputError, match="file not found"):
        read_model(tmp_path / "missing.yaml")


def test_write_model_refuses_to_overwrite(tmp_path):
    path = tmp_path / "m.yaml"
    write_model(arm6r(), path)
    before = path.read_text()
    with pytest.raises(rc.InputError, match="exists"):
        write_model(cylindrical(), path)
    assert path.read_text() == before
    write_model(cylindrical(), path, force=True)
    assert read_model(path).name == "cylindrical" or read_model(path).n_joints == 6
    assert [p.name for p in tmp_path.iterdir()] == ["m.yaml"]  # no temporary files left


# ------------------------------------------------------------------------------------------------
# measurement CSV

def sim(n=30, orientation=False, markers=(("tool", (0.05, 0.02, 0.12)), ("t2", (0.1, 0.0, 0.1))), seed=0):
    model = arm6r(markers=markers)
    true, data = rc.simulate(model, n, seed=seed, orientation=orientation, noise_rot=1e-4 if orientation else None)
    return model, data


@pytest.mark.parametrize("units", ["mm-deg", "m-rad"])
def test_csv_round_trip(tmp_path, units):
    model = cylindrical()
    true, data = rc.simulate(model, 12, seed=1)
    write_measurements(data, tmp_path / "d.csv", units=units, model=model)
    header = (tmp_path / "d.csv").read_text().splitlines()[0]
    lu, au = units.split("-")
    assert f"j1_{au}" in header and f"j2_{lu}" in header and f"tool_x_{lu}" in header  # j2 is prismatic
    for back in (read_measurements(tmp_path / "d.csv", model), read_measurements(tmp_path / "d.csv")):
        np.testing.assert_allclose(back.q, data.q, rtol=1e-14, atol=1e-15)
        np.testing.assert_allclose(back.positions, data.positions, rtol=1e-14, atol=1e-15)
        assert back.labels == data.labels
        assert back.source == str(tmp_path / "d.csv") and len(back.sha256) == 64


def test_csv_orientation_sigma_missing_marker_round_trip(tmp_path):
    model, data = sim(10, orientation=True)
    pos = data.positions.copy()
    pos[2, 1] = np.nan
    data = rc.Measurements(q=data.q, positions=pos, marker_names=data.marker_names, joint_names=data.joint_names,
                           rotations=data.rotations, sigma=np.full((10, 2), 2e-5), sigma_rot=np.full((10, 2), 1e-4),
                           payload_mass=np.linspace(0, 2, 10))
    write_measurements(data, tmp_path / "d.csv", model=model)
    back = read_measurements(tmp_path / "d.csv", model)
    assert back.mask[2].tolist() == [True, False] and back.mask.sum() == 19
    np.testing.assert_allclose(back.positions[back.mask], data.positions[data.mask], atol=1e-15)
    np.testing.assert_allclose(back.rotations, data.rotations, atol=1e-14)
    np.testing.assert_allclose(back.sigma[back.mask], 2e-5)
    np.testing.assert_allclose(back.sigma_rot, 1e-4)
    np.testing.assert_allclose(back.payload_mass, data.payload_mass)


def _table(model, data, *, sep=",", decimal=".", header_units=True):
    """Hand-written CSV text of point data (mm, deg) the way an instrument exports it."""
    L, A = ("_mm", "_deg") if header_units else ("", "")
    cols = [f"{j}{A}" for j in model.joint_names]
    for m in data.marker_names:
        cols += [f"{m}_{c}{L}" for c in "xyz"]
    lines = [sep.join(["pose"] + cols)]
    for i in range(data.n_poses):
        cells = [f"P{i}"] + [repr(float(v)) for v in np.rad2deg(data.q[i])]
        for m in range(len(data.marker_names)):
            cells += ["" if np.isnan(v) else repr(float(v) * 1e3) for v in data.positions[i, m]]
        lines.append(sep.join(c.replace(".", decimal) for c in cells))
    return "\n".join(lines) + "\n"


def test_csv_semicolon_decimal_comma_missing_marker(tmp_path):
    model, data = sim(20)
    pos = data.positions.copy()
    pos[[3, 7], 0] = np.nan
    data = rc.Measurements(q=data.q, positions=pos, marker_names=data.marker_names)
    (tmp_path / "d.csv").write_text(_table(model, data, sep=";", decimal=","))
    back = read_measurements(tmp_path / "d.csv", model, sep=";", decimal=",")
    assert back.n_poses == 20 and back.mask.sum() == 38 and not back.mask[3, 0] and not back.mask[7, 0]
    np.testing.assert_allclose(back.positions[back.mask], pos[back.mask], atol=1e-15)
    assert back.labels[0] == "P0"
    result = rc.calibrate(model, back)
    assert result.stats.fit_after.rms < 1e-4


def test_csv_units_from_comment_line_or_option(tmp_path):
    model, data = sim(5)
    text = _table(model, data, header_units=False)
    (tmp_path / "plain.csv").write_text(text)
    (tmp_path / "comment.csv").write_text("# units: length=mm angle=deg\n" + text)
    a = read_measurements(tmp_path / "comment.csv", model)
    b = read_measurements(tmp_path / "plain.csv", model, units="mm-deg")
    np.testing.assert_allclose(a.positions, data.positions, atol=1e-15)
    np.testing.assert_allclose(b.q, data.q, atol=1e-15)
    with pytest.raises(rc.InputError, match=r"plain.csv: line 1, column 'j1': no angle unit declared.*# units:"):
        read_measurements(tmp_path / "plain.csv", model)
    with pytest.raises(rc.InputError, match="must agree"):
        read_measurements(tmp_path / "comment.csv", model, units="m-deg")
    # units stated in two lines are read together; a unit stated twice is refused, not the last one taken
    (tmp_path / "split.csv").write_text("# units: length=mm\n# units: angle=deg\n" + text)
    np.testing.assert_allclose(read_measurements(tmp_path / "split.csv", model).q, data.q, atol=1e-15)
    (tmp_path / "twice.csv").write_text("# units: length=mm angle=deg\n# units: angle=rad\n" + text)
    with pytest.raises(rc.InputError, match=r"twice.csv: line 2: units.angle stated twice \(line 1: deg, line 2: rad"):
        read_measurements(tmp_path / "twice.csv", model)


@pytest.mark.parametrize("convention, parts, columns", [
    ("euler:ZYX", ("ZYX", True), ("e1", "e2", "e3")),
    ("euler:zyx", ("zyx", True), ("e1", "e2", "e3")),
    ("rpy", ("xyz", True), ("roll", "pitch", "yaw")),
    ("quat_wxyz", (None, False), ("qw", "qx", "qy", "qz")),
])
def test_csv_orientation_conventions(tmp_path, convention, parts, columns):
    model, data = sim(6, orientation=True, markers=(("tool", (0.05, 0.02, 0.12)),))
    seq, euler = parts
    rot = Rotation.from_matrix(data.rotations[:, 0])
    vals = rot.as_euler(seq, degrees=True) if euler else rot.as_quat(scalar_first=True)
    header = ",".join([f"{j}_deg" for j in model.joint_names] + [f"tool_{c}_mm" for c in "xyz"]
                      + [f"tool_{c}" for c in columns])
    rows = [",".join(repr(float(v))
                     for v in list(np.rad2deg(data.q[i])) + list(data.positions[i, 0] * 1e3) + list(vals[i]))
            for i in range(6)]
    text = "# units: angle=deg\n" + header + "\n" + "\n".join(rows) + "\n"
    (tmp_path / "d.csv").write_text(text)
    back = read_measurements(tmp_path / "d.csv", model, orientation=convention)
    np.testing.assert_allclose(back.rotations[:, 0], data.rotations[:, 0], atol=1e-12)


@pytest.mark.parametrize("convention, columns", [
    ("quat_xyzw", ("qx", "qy", "qz", "qw")), ("quat_wxyz", ("qw", "qx", "qy", "qz")),
    ("rpy", ("roll_deg", "pitch_deg", "yaw_deg")), ("euler:ZYX", ("e1_deg", "e2_deg", "e3_deg")),
    ("euler:zxz", ("e1_deg", "e2_deg", "e3_deg")),
])
def test_csv_orientations_written_in_each_convention_read_back(tmp_path, convention, columns):
    model, data = sim(8, orientation=True)
    write_measurements(data, tmp_path / "d.csv", model=model, orientation=convention)
    lines = (tmp_path / "d.csv").read_text().splitlines()
    assert lines[0] == f"# orientation: {convention}"
    head = lines[1].split(",")
    assert [c for c in head if c.startswith("tool_") and c[5:] in columns] == [f"tool_{c}" for c in columns]
    back = read_measurements(tmp_path / "d.csv", model)   # the comment line declares the convention
    both = data.rot_mask & back.rot_mask
    np.testing.assert_array_equal(back.rot_mask, data.rot_mask)
    np.testing.assert_allclose(back.rotations[both], data.rotations[both], atol=1e-12)
    np.testing.assert_allclose(back.positions[data.mask], data.positions[data.mask], atol=1e-12)
    with pytest.raises(rc.InputError, match="unknown orientation convention"):
        write_measurements(data, tmp_path / "e.csv", model=model, orientation="quaternion")
    assert not (tmp_path / "e.csv").exists()


def test_csv_set_column_splits_fit_and_validation(tmp_path):
    model, data = sim(8)
    text = _table(model, data).splitlines()
    text = [text[0] + ",set"] + [row + ("," + ("validation" if i % 4 == 0 else "fit"))
                                 for i, row in enumerate(text[1:])]
    (tmp_path / "d.csv").write_text("\n".join(text) + "\n")
    fit, val = split_sets(read_measurements(tmp_path / "d.csv", model))
    assert (fit.n_poses, val.n_poses) == (6, 2)
    assert val.labels == ("P0", "P4")


def write_bad(tmp_path, model, data, edit):
    lines = _table(model, data).splitlines()
    edit(lines)
    path = tmp_path / "bad.csv"
    path.write_text("\n".join(lines) + "\n")
    return path


def _cell(lines, row, col, value):
    cells = lines[row].split(",")
    cells[col] = value
    lines[row] = ",".join(cells)


def _drop(lines, name):
    k = lines[0].split(",").index(name)
    for i, line in enumerate(lines):
        cells = line.split(",")
        del cells[k]
        lines[i] = ",".join(cells)


@pytest.mark.parametrize("edit, where, words", [
    (lambda ls: _drop(ls, "tool_z_mm"), "line 1", "missing column tool_z"),
    (lambda ls: _drop(ls, "j6_deg"), "line 1", "missing column 'j6': the model has 6 joints"),
    (lambda ls: _cell(ls, 3, 2, "abc"), "line 4, column 'j2_deg'", "expected a number, got 'abc'"),
    (lambda ls: _cell(ls, 2, 7, "NaN"), "line 3, column 'tool_x_mm'", "'NaN' is not a measurement"),
    (lambda ls: _cell(ls, 2, 7, "inf"), "line 3, column 'tool_x_mm'", "'inf' is not a measurement"),
    (lambda ls: _cell(ls, 2, 1, ""), "line 3, column 'j1_deg'", "empty cell"),
    (lambda ls: _cell(ls, 5, 8, ""), "line 6, column 'tool_y_mm'", "leave all of"),
    (lambda ls: _cell(ls, 0, 7, "tool_x_in"), "line 1, column 'tool_x_in'", "unknown length unit 'in'"),
    (lambda ls: _cell(ls, 0, 1, "j1_mm"), "line 1, column 'j1_mm'", "unknown angle unit 'mm' (that is a"),
    (lambda ls: _cell(ls, 0, 1, "j7_deg"), "line 1", "unknown column 'j7_deg'"),
    (lambda ls: ls.__setitem__(4, ls[4] + ",1"), "line 5", "cells where the header has"),
    (lambda ls: _cell(ls, 0, 7, "j1_deg"), "line 1", "appears twice"),
])
def test_csv_errors(tmp_path, edit, where, words):
    model, data = sim(6, markers=(("tool", (0.05, 0.02, 0.12)),))
    path = write_bad(tmp_path, model, data, edit)
    with pytest.raises(rc.InputError) as err:
        read_measurements(path, model)
    assert (err.value.source, err.value.where) == (str(path), where)
    assert words in str(err.value)


def test_csv_zero_quaternion_names_row_and_column(tmp_path):
    model, data = sim(4, orientation=True, markers=(("tool", (0.05, 0.02, 0.12)),))
    write_measurements(data, tmp_path / "d.csv", model=model)
    lines = (tmp_path / "d.csv").read_text().splitlines()   # line 1 is "# orientation: quat_xyzw"
    header = lines[1].split(",")
    cells = lines[3].split(",")
    for c in ("tool_qx", "tool_qy", "tool_qz", "tool_qw"):
        cells[header.index(c)] = "0"
    lines[3] = ",".join(cells)
    (tmp_path / "d.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(rc.InputError, match=r"d.csv: line 4, column 'tool_qx': quaternion of zero norm"):
        read_measurements(tmp_path / "d.csv", model)


def test_csv_without_model_needs_joint_units(tmp_path):
    model, data = sim(3)
    (tmp_path / "d.csv").write_text("# units: length=mm angle=deg\n" + _table(model, data, header_units=False))
    with pytest.raises(rc.InputError, match="column 'j1': without a model a joint column must carry its unit"):
        read_measurements(tmp_path / "d.csv")


def test_write_measurements_needs_joint_types(tmp_path):
    model, data = sim(3)
    with pytest.raises(rc.InputError, match="pass the model"):
        measurements_to_csv(data)


# ------------------------------------------------------------------------------------------------
# result JSON

def test_result_round_trip_and_schema(tmp_path):
    model, data = sim(25)
    result = rc.calibrate(model, data)
    write_result(result, tmp_path / "r.json")
    back = read_result(tmp_path / "r.json")
    # JSON keeps every float exactly: the record read back is the one written
    assert back.parameters == result.parameters and back.stats == result.stats
    assert back.identifiability.identified == result.identifiability.identified
    assert back.identifiability.eliminated == result.identifiability.eliminated
    for name in ("covariance", "correlation"):
        np.testing.assert_array_equal(getattr(back, name), getattr(result, name))
    for name in ("errors_before", "errors_after", "residual_vectors", "measured_positions", "readings"):
        np.testing.assert_array_equal(getattr(back.fit, name), getattr(result.fit, name))
    solver = ("success", "status", "message", "nfev", "loss", "sigma0")
    assert [getattr(back.solver, f) for f in solver] == [getattr(result.solver, f) for f in solver]
    assert back.notes == result.notes and back.validation is None and back.limit is None
    assert_same_model(back.calibrated_model, result.calibrated_model)
    assert result_to_dict(back)["schema"] == "robocal.result/1"
    json.loads((tmp_path / "r.json").read_text(), parse_constant=lambda c: pytest.fail(f"non-JSON {c}"))
    with pytest.raises(rc.InputError, match="exists"):
        write_result(result, tmp_path / "r.json")
    (tmp_path / "x.json").write_text('{"a": 1}')
    with pytest.raises(rc.InputError, match="x.json: schema: not a robocal result"):
        read_result(tmp_path / "x.json")
    (tmp_path / "y.json").write_text('{"schema": "robocal.result/9"}')
    with pytest.raises(rc.InputError, match="unknown schema"):
        read_result(tmp_path / "y.json")
