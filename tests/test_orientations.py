"""6D measurements: every orientation convention read as declared, a wrong declaration caught."""

import csv
import io
import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_one_line_error, z_scores
from robots import DEG, torso
from scipy.spatial.transform import Rotation

import robocal as rc
from robocal._identification.misfit import characteristic_length, misfit_notes

NOISE, NOISE_ROT = 2e-5, 1e-5


def residuals(result, data):
    """Position (n, 3) m and rotation-vector (n_rot, 3) rad residuals of the calibrated model, in W."""
    model = result.calibrated_model
    ev = rc.forward_kinematics(model, data.q)
    mi = [model.marker_names.index(n) for n in data.marker_names]
    dp = (ev.positions[:, mi] - data.positions)[data.mask]
    if not data.has_orientation:
        return dp, None
    Rp = ev.rotations[:, mi][data.rot_mask]
    Rm = data.rotations[data.rot_mask]
    return dp, Rotation.from_matrix(Rp @ np.swapaxes(Rm, -1, -2)).as_rotvec()


def notes_for(result, data):
    dp, dr = residuals(result, data)
    return misfit_notes(dp, dr, characteristic_length_m=characteristic_length(data.positions))


PARTS = {"quat_xyzw": ("qx", "qy", "qz", "qw"), "quat_wxyz": ("qw", "qx", "qy", "qz"),
         "rpy": ("roll_deg", "pitch_deg", "yaw_deg"), "euler": ("e1_deg", "e2_deg", "e3_deg")}


def _orientation_values(rot: Rotation, convention: str) -> np.ndarray:
    if convention == "quat_xyzw":
        return rot.as_quat()
    if convention == "quat_wxyz":
        return rot.as_quat(scalar_first=True)
    if convention == "rpy":
        return rot.as_euler("xyz", degrees=True)
    return rot.as_euler(convention.split(":", 1)[1], degrees=True)


def rewrite_orientation(src: Path, dst: Path, convention: str, *, declare: bool = True, sep=",", decimal="."):
    """The CSV ``src`` (written by rc.write_measurements: quaternions x, y, z, w) in ``convention``.

    Columns ``<marker>_qx..qw`` become that convention's columns (angles in degrees); ``declare``
    writes the ``# orientation:`` line, as instrument exports mostly do not.
    """
    lines = src.read_text().splitlines()
    assert lines[0] == "# orientation: quat_xyzw"
    rows = list(csv.reader(lines[1:]))
    head = rows[0]
    quat = {}
    for k, c in enumerate(head):
        marker, _, part = c.rpartition("_")
        if part in PARTS["quat_xyzw"]:
            quat.setdefault(marker, {})[part] = k
    parts = PARTS[convention.split(":")[0]]
    drop = {k for cols in quat.values() for k in cols.values()}
    out = [[c for k, c in enumerate(head) if k not in drop] + [f"{mk}_{p}" for mk in quat for p in parts]]
    for row in rows[1:]:
        new = [c for k, c in enumerate(row) if k not in drop]
        for cols in quat.values():
            cells = [row[cols[p]] for p in PARTS["quat_xyzw"]]
            if not cells[0]:
                new += [""] * len(parts)
            else:
                new += [repr(float(v)) for v in _orientation_values(Rotation.from_quat(np.array(cells, float)),
                                                                      convention)]
        out.append(new)
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerows(out)
    text = buf.getvalue()
    if decimal != ".":
        text = text.replace(",", sep).replace(".", decimal)
    dst.write_text((f"# orientation: {convention}\n" if declare else "") + text)


@pytest.fixture(scope="module")
def six_d(tmp_path_factory):
    """A 6D campaign on the torso, written by rc.write_measurements (quat_xyzw)."""
    d = tmp_path_factory.mktemp("six_d")
    m = torso()
    true, data = rc.simulate(m, 40, orientation=True, noise=NOISE, noise_rot=NOISE_ROT, seed=3)
    rc.write_measurements(data, d / "quat_xyzw.csv", model=m)
    return d, m, true, data


CONVENTIONS = ["quat_xyzw", "quat_wxyz", "rpy", "euler:XYZ", "euler:xyz", "euler:ZYX", "euler:zyx", "euler:YXZ"]


@pytest.mark.parametrize("convention", CONVENTIONS)
def test_6d_campaign_in_each_convention_recovers(six_d, convention):
    d, m, true, data = six_d
    path = d / "quat_xyzw.csv"
    if convention != "quat_xyzw":
        path = d / f"{convention.replace(':', '_')}.csv"
        rewrite_orientation(d / "quat_xyzw.csv", path, convention, declare=False)
    back = rc.read_measurements(path, m, orientation=convention)
    np.testing.assert_allclose(back.rotations, data.rotations, atol=1e-12)
    with warnings.catch_warnings():
        warnings.simplefilter("error", rc.MisfitWarning)  # no alarm on a correct declaration
        result = rc.calibrate(m, back)
    names = result.parameter_names
    assert {"lhand.rx", "lhand.ry", "lhand.rz", "rhand.rx", "rhand.ry", "rhand.rz"} <= set(names)
    assert len(names) == 50
    z = z_scores(result, true, m)
    assert np.abs(z).max() < 3.0, dict(zip(names, z.round(2)))
    assert notes_for(result, back) == []


def test_quaternion_declarations_follow_the_column_names(six_d):
    """quat_xyzw and quat_wxyz name the same thing: the columns say which component is which."""
    d, m, true, data = six_d
    a = rc.read_measurements(d / "quat_xyzw.csv", m, orientation="quat_wxyz")
    np.testing.assert_array_equal(a.rotations, rc.read_measurements(d / "quat_xyzw.csv", m).rotations)


def _mislabelled_quaternions(src: Path, dst: Path):
    """Components written w, x, y, z under the header qx, qy, qz, qw (a wrongly renamed export)."""
    rewrite_orientation(src, dst, "quat_wxyz", declare=False)
    lines = dst.read_text().splitlines()
    for mk in ("lhand", "rhand"):
        lines[0] = lines[0].replace(f"{mk}_qw,{mk}_qx,{mk}_qy,{mk}_qz", f"{mk}_qx,{mk}_qy,{mk}_qz,{mk}_qw")
    dst.write_text("\n".join(lines) + "\n")


WRONG = [("euler:XYZ", "euler:xyz"), ("euler:ZYX", "euler:zyx"), ("quat_wxyz", "quat_xyzw")]


def _wrong_file(six_d, written, declared):
    d, m, true, data = six_d
    path = d / f"wrong_{written.replace(':', '_')}.csv"
    if written.startswith("quat"):
        _mislabelled_quaternions(d / "quat_xyzw.csv", path)
    else:
        rewrite_orientation(d / "quat_xyzw.csv", path, written, declare=False)
    return rc.read_measurements(path, m, orientation=declared)


@pytest.mark.parametrize("written, declared", WRONG)
def test_wrong_orientation_convention_is_a_misfit(six_d, written, declared):
    d, m, true, data = six_d
    wrong = _wrong_file(six_d, written, declared)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rc.MisfitWarning)  # once calibrate warns itself
        result = rc.calibrate(m, wrong)
    assert result.solver.success  # the solver alone does not notice
    notes = notes_for(result, wrong)
    assert len(notes) == 1 and "orientation convention" in notes[0] and "degrees RMS" in notes[0]


@pytest.mark.parametrize("written, declared", WRONG)
def test_calibrate_warns_on_wrong_orientation_convention(six_d, written, declared):
    d, m, true, data = six_d
    wrong = _wrong_file(six_d, written, declared)
    with pytest.warns(rc.MisfitWarning, match="orientation"):
        result = rc.calibrate(m, wrong)
    check = next(c for c in result.checks if c.name == "orientation fit")
    assert result.verdict == "fail" and check.status == "fail" and "orientation convention" in check.summary


def test_misfit_notes_rules():
    rng = np.random.default_rng(0)
    pos = rng.normal(0, 2e-5, (80, 3))
    good = rng.normal(0, 1e-5, (80, 3))
    assert misfit_notes(pos, None, characteristic_length_m=1.0) == []
    assert misfit_notes(pos, good, characteristic_length_m=1.0) == []
    # a camera tracker: 0.1 mm and 0.1 degree, no alarm
    assert misfit_notes(10 * pos, rng.normal(0, 1e-3, (80, 3)), characteristic_length_m=1.0) == []
    # 1 degree RMS: no instrument
    assert "degrees RMS" in misfit_notes(pos, rng.normal(0, 1 * DEG, (80, 3)), characteristic_length_m=1.0)[0]
    # 0.4 degree while positions fit to 20 um over a 1 m robot: the two parts disagree
    msg = misfit_notes(pos, rng.normal(0, 0.4 * DEG / np.sqrt(3), (80, 3)), characteristic_length_m=1.0)
    assert len(msg) == 1 and "disagree with the positions" in msg[0]
    # noise-free data: round-off is not a misfit
    assert misfit_notes(pos * 1e-12, good * 1e-9, characteristic_length_m=1.0) == []
    # stated standard deviations decide when given
    assert misfit_notes(pos, good, characteristic_length_m=1.0, sigma_rot_rad=1e-5) == []
    assert "stated standard deviations" in misfit_notes(pos, 5 * good, characteristic_length_m=1.0,
                                                        sigma_rot_rad=np.full(80, 1e-5))[0]


def test_orientation_declaration_errors_through_cli(six_d, tmp_path, cli):
    src, m, true, data = six_d
    rc.write_model(m, tmp_path / "m.yaml")
    rewrite_orientation(src / "quat_xyzw.csv", tmp_path / "e.csv", "euler:ZYX", declare=False)
    code, out, err = cli("calibrate", tmp_path / "m.yaml", tmp_path / "e.csv", "--out", tmp_path / "o")
    assert_one_line_error(code, err, [str(tmp_path / "e.csv"), "line 1", "lhand_e1", "--orientation euler:ZYX"],
                    tmp_path / "o")
    code, out, err = cli("calibrate", tmp_path / "m.yaml", src / "quat_xyzw.csv", "--out", tmp_path / "o",
                         "--orientation", "rpy")
    assert_one_line_error(code, err, [f"{src / 'quat_xyzw.csv'}: orientation: the file declares orientation quat_xyzw "
                                "(line 1), the option says rpy"], tmp_path / "o")
    # a zero quaternion in a decimal-comma file names the file, the line and the column
    rewrite_orientation(src / "quat_xyzw.csv", tmp_path / "z.csv", "quat_xyzw", declare=True, sep=";", decimal=",")
    lines = (tmp_path / "z.csv").read_text().splitlines()
    head = lines[1].split(";")
    cells = lines[4].split(";")
    for p in ("qx", "qy", "qz", "qw"):
        cells[head.index(f"rhand_{p}")] = "0,0"
    lines[4] = ";".join(cells)
    (tmp_path / "z.csv").write_text("\n".join(lines) + "\n")
    code, out, err = cli("calibrate", tmp_path / "m.yaml", tmp_path / "z.csv", "--out", tmp_path / "o",
                         "--sep", ";", "--decimal", ",")
    assert_one_line_error(code, err, [f"{tmp_path / 'z.csv'}: line 5, column 'rhand_qx': quaternion of zero norm"],
                    tmp_path / "o")


def test_tool_turned_120_degrees_is_reported_without_gimbal_lock():
    """Rotation corrections are rotation vectors (axis times angle): a tool 120 deg from its guess,
    about an axis near none of its own, comes back as that one turn within 0.01 deg."""
    from robots import arm6r

    from robocal._base.spatial import small_rotation
    from robocal._presentation.text import calibration_summary

    model = arm6r()
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    truth = np.deg2rad(120.0) * axis
    mk = model.markers[0]
    true = model.replace(markers=(rc.Marker(mk.name, mk.frame, mk.position,
                                            tuple(map(tuple, small_rotation(*truth)))),))
    q = rc.random_configurations(model, 30, np.random.default_rng(1))
    data = rc.sim.measure(true, q, noise=1e-5, noise_rot=1e-5, orientation=True, rng=2)
    # the model says how far a tool may plausibly turn: the guess is known to be coarse
    model = model.replace(tolerances=(("markers", "angle", None),))
    result = rc.calibrate(model, data)
    v = np.array([result.estimate(f"tool.r{c}").change for c in "xyz"])
    stds = np.array([result.estimate(f"tool.r{c}").std for c in "xyz"])
    assert np.rad2deg(np.abs(v - truth)).max() < 0.01
    assert np.rad2deg(stds).max() < 0.01           # no gimbal lock inflating the uncertainty
    line = next(ln for ln in calibration_summary(result).splitlines() if "tool rotation" in ln)
    angle = float(line.split("turned ")[1].split(" deg")[0])
    shown_axis = np.array([float(c) for c in line.split("about (")[1].rstrip(")").split(",")])
    assert abs(angle - 120.0) < 0.01 and np.abs(shown_axis - axis).max() < 1e-3
    # the calibrated file holds the turn: read against the guess it gives the same rotation vector
    k = rc.parameter_names(model).index("tool.rx")
    np.testing.assert_allclose(rc.parameter_vector(result.calibrated_model, model)[k:k + 3], v, atol=1e-12)
