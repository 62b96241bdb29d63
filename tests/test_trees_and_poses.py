"""Kinematic trees, coupled joints, 6D poses in every orientation convention, a far base, locale CSVs.

The robot is examples/torso/model.yaml: a two-frame trunk, a left arm that follows the trunk's
last frame (with a passive parallelogram frame driven by -l2 - l3) and a right arm that hangs off
the same trunk frame (Khalil-Kleinfinger gamma/b). Recovery is judged by z = (estimate - truth) /
reported std over the identified parameters.
"""

import csv
import io
import warnings
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

import robocal as rc
from robocal._misfit import characteristic_length, misfit_notes
from robocal.cli import main

TORSO = Path(__file__).resolve().parents[1] / "examples" / "torso" / "model.yaml"
DEG = np.pi / 180
NOISE, NOISE_ROT = 2e-5, 1e-5


def torso() -> rc.RobotModel:
    return rc.read_model(TORSO)


def z_scores(result, true, reference) -> np.ndarray:
    """(estimate - truth) / std per identified parameter; rotation corrections relative to ``reference``."""
    p = rc.parameter_vector(true, reference)
    names = rc.parameter_names(reference)
    return np.array([(e.estimate - p[names.index(e.name)]) / e.std for e in result.parameters])


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


# ------------------------------------------------------------------------------------------------
# 1. the torso: a tree with a coupled joint

def test_torso_file_is_the_tree_it_claims():
    """The example file, read, equals the torso built from records: parents, couplings, gamma/b."""
    m = torso()
    J = {n: i for i, n in enumerate(m.joint_names)}

    def own(n):
        return ((J[n], 1.0),)

    frames = [
        rc.Frame("t1", parent=-1, r=0.3, coupling=own("t1"), has_beta=True),
        rc.Frame("t2", parent=0, alpha=-90 * DEG, theta=-90 * DEG, coupling=own("t2")),
        rc.Frame("l1", parent=1, d=0.5, r=0.2, coupling=own("l1"), has_beta=True),
        rc.Frame("l2", parent=2, alpha=-90 * DEG, d=0.05, coupling=own("l2")),
        rc.Frame("l3", parent=3, d=0.3, coupling=own("l3"), has_beta=True),
        rc.Frame("l4", parent=4, d=0.25, coupling=((J["l2"], -1.0), (J["l3"], -1.0)), has_beta=True),
        rc.Frame("r1", parent=1, b=-0.2, d=0.5, coupling=own("r1"), has_beta=True),
        rc.Frame("r2", parent=6, alpha=90 * DEG, d=0.05, coupling=own("r2")),
        rc.Frame("r3", parent=7, d=0.3, coupling=own("r3"), has_beta=True),
        rc.Frame("r4", parent=8, alpha=-90 * DEG, r=0.25, coupling=own("r4")),
    ]
    built = m.replace(frames=tuple(frames),
                      markers=(rc.Marker("lhand", 5, (0.08, 0.02, 0.05)), rc.Marker("rhand", 9, (0.05, 0.03, 0.1))))
    assert m.frames == built.frames and m.markers == built.markers
    q = rc.random_configurations(m, 5, rng=1)
    np.testing.assert_allclose(rc.forward_kinematics(m, q).positions, rc.forward_kinematics(built, q).positions,
                               atol=1e-15)
    # r1 hangs off t2, not off its predecessor l4: gamma and b are its candidates, not l1's
    assert m.frames[6].parent == 1 != 6 - 1
    cand = rc.candidate_parameters(m)
    assert {"r1.gamma", "r1.b"} <= set(cand) and "l1.gamma" not in cand
    # the passive frame turns by -l2 - l3: the left hand keeps its orientation as l2 and l3 move
    q2 = q.copy()
    q2[:, J["l2"]] += 0.4
    q2[:, J["l3"]] -= 0.9
    R1, R2 = rc.forward_kinematics(m, q).rotations, rc.forward_kinematics(m, q2).rotations
    np.testing.assert_allclose(R1[:, 0], R2[:, 0], atol=1e-12)
    assert np.abs(R1[:, 1] - R2[:, 1]).max() < 1e-15  # the right arm does not move at all


def test_torso_model_file_round_trip(tmp_path):
    m = torso()
    true, _ = rc.simulate(m, 1, seed=2)  # every value off its round nominal
    rc.write_model(true, tmp_path / "t.yaml")
    back = rc.read_model(tmp_path / "t.yaml")
    assert [f.parent for f in back.frames] == [f.parent for f in true.frames] == [-1, 0, 1, 2, 3, 4, 1, 6, 7, 8]
    assert [f.coupling for f in back.frames] == [f.coupling for f in true.frames]
    assert back.frames[5].coupling == ((3, -1.0), (4, -1.0))
    assert [f.has_beta for f in back.frames] == [f.has_beta for f in true.frames]
    np.testing.assert_allclose(rc.parameter_vector(back, true), rc.parameter_vector(true), atol=1e-12)
    text = yaml.safe_load((tmp_path / "t.yaml").read_text())
    r1 = next(f for f in text["frames"] if f["name"] == "r1")
    l4 = next(f for f in text["frames"] if f["name"] == "l4")
    assert r1["parent"] == "t2" and "gamma" in r1 and r1["b"] != 0
    assert l4["coupling"] == {"l2": -1.0, "l3": -1.0}


def test_torso_recovers_identifiable_parameters():
    m = torso()
    true, data = rc.simulate(m, 60, noise=NOISE, seed=0)
    assert data.mask.all()  # both markers in every row
    result = rc.calibrate(m, data)
    names = result.parameter_names
    assert result.success and len(names) == 44
    assert {"r1.gamma", "l4.d", "l4.alpha", "base.rz"} <= set(names)
    z = z_scores(result, true, m)
    assert np.abs(z).max() < 3.0, dict(zip(names, z.round(2)))
    assert result.stats.fit_after.rms < 2.5 * NOISE * np.sqrt(3)
    # the calibrated robot predicts the true one at new poses
    q = rc.random_configurations(m, 50, rng=7)
    err = np.linalg.norm(rc.forward_kinematics(result.calibrated_model, q).positions
                         - rc.forward_kinematics(true, q).positions, axis=-1)
    assert err.max() < 1e-4 < result.stats.fit_before.mean


def test_torso_z_scores_are_calibrated_over_seeds():
    """The reported standard deviations are right: z pooled over several campaigns has std ~1."""
    m = torso()
    zs, worst = [], []
    for seed in range(6):
        true, data = rc.simulate(m, 60, noise=NOISE, seed=100 + seed)
        z = z_scores(rc.calibrate(m, data), true, m)
        zs.append(z)
        worst.append(np.abs(z).max())
    pooled = np.concatenate(zs)
    assert 0.85 < pooled.std() < 1.15, (pooled.std(), worst)
    assert abs(pooled.mean()) < 4 / np.sqrt(len(pooled))


# ------------------------------------------------------------------------------------------------
# 2. 6D poses in every orientation convention, and a wrong declaration

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
    assert result.success  # the solver alone does not notice
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


# ------------------------------------------------------------------------------------------------
# 3. no base guess: the tracker 3 m away, turned 120 degrees about z and 10 about x

def test_far_base_converges_from_registration():
    m = torso()
    R_WB = Rotation.from_euler("zx", [120, 10], degrees=True).as_matrix()  # extrinsic: Rx(10) Rz(120)
    placed = m.replace(base_position=(2.0, -2.0, 1.0), base_rotation=tuple(map(tuple, R_WB)))
    true, data = rc.simulate(placed, 60, noise=NOISE, seed=5)
    nominal = m.replace(base_position=(0.0, 0.0, 0.0), base_rotation=((1.0, 0, 0), (0, 1.0, 0), (0, 0, 1.0)))
    result = rc.calibrate(nominal, data, initial_base="register")
    assert result.success
    assert result.stats.fit_before.mean > 2.0  # really no guess: metres off before
    assert result.stats.fit_after.rms < 2.5 * NOISE * np.sqrt(3)
    # base rotation corrections are relative to the registered start (calibrate's reference)
    z = z_scores(result, true, rc.register_base(nominal, data))
    assert len(z) == 44 and np.abs(z).max() < 3.0, dict(zip(result.parameter_names, z.round(2)))
    angle = Rotation.from_matrix(np.asarray(result.calibrated_model.base_rotation).T
                                 @ np.asarray(true.base_rotation)).magnitude()
    assert angle < 1e-4


# ------------------------------------------------------------------------------------------------
# 4. a decimal-comma, semicolon file with a marker missing in some rows

def test_semicolon_decimal_comma_missing_marker(tmp_path):
    m = torso()
    true, full = rc.simulate(m, 60, noise=NOISE, seed=8)
    rng = np.random.default_rng(8)
    hidden = rng.random(full.n_poses) < 0.2
    pos = full.positions.copy()
    pos[hidden, 1] = np.nan  # the right hand not seen
    data = rc.Measurements(q=full.q, positions=pos, marker_names=full.marker_names, joint_names=full.joint_names)
    rc.write_measurements(data, tmp_path / "plain.csv", model=m)
    text = (tmp_path / "plain.csv").read_text()
    (tmp_path / "locale.csv").write_text(text.replace(",", ";").replace(".", ","))
    row = (tmp_path / "locale.csv").read_text().splitlines()[1 + int(np.argmax(hidden))]
    assert ";;;" in row and "," in row and "." not in row
    back = rc.read_measurements(tmp_path / "locale.csv", m, sep=";", decimal=",")
    assert back.n_poses == full.n_poses
    np.testing.assert_array_equal(back.mask, np.column_stack([np.ones(60, bool), ~hidden]))
    assert 0.1 < hidden.mean() < 0.3
    np.testing.assert_allclose(back.positions[back.mask], full.positions[back.mask], atol=1e-12)
    result = rc.calibrate(m, back)
    assert result.errors_after.shape == (60, 2) and np.isnan(result.errors_after[hidden, 1]).all()
    assert result.stats.fit_after.n == 120 - hidden.sum()
    z = z_scores(result, true, m)
    assert np.abs(z).max() < 3.0, dict(zip(result.parameter_names, z.round(2)))


# ------------------------------------------------------------------------------------------------
# 5. bad input not covered by test_files, test_cli and test_imports: tree keys, conventions, URDF files

def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def _one_line_error(code, err, words, out_dir):
    assert code == 2 and "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("robocal calibrate: error: "), err
    for w in words:
        assert w in lines[0], (w, lines[0])
    assert not out_dir.exists()


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
# a marker on an unknown frame, a joint named twice and a zero quaternion in a plain CSV are in
# test_cli.py (MODEL_CASES, test_zero_quaternion) and test_files.py; malformed URDF text in test_imports.py


@pytest.mark.parametrize("case", sorted(TREE_CASES))
def test_bad_tree_model_file_through_cli(torso_campaign, capsys, case):
    d, text = torso_campaign
    edit, words = TREE_CASES[case]
    edit(text)
    (d / "bad.yaml").write_text(yaml.safe_dump(text, sort_keys=False))
    with pytest.raises(rc.InputError) as err:
        rc.read_model(d / "bad.yaml")
    assert err.value.source == str(d / "bad.yaml")
    code, out, err = run(capsys, "calibrate", d / "bad.yaml", d / "data.csv", "--out", d / "run")
    _one_line_error(code, err, [f"{d / 'bad.yaml'}: "] + words, d / "run")


def test_orientation_declaration_errors_through_cli(six_d, tmp_path, capsys):
    src, m, true, data = six_d
    rc.write_model(m, tmp_path / "m.yaml")
    rewrite_orientation(src / "quat_xyzw.csv", tmp_path / "e.csv", "euler:ZYX", declare=False)
    code, out, err = run(capsys, "calibrate", tmp_path / "m.yaml", tmp_path / "e.csv", "--out", tmp_path / "o")
    _one_line_error(code, err, [str(tmp_path / "e.csv"), "line 1", "lhand_e1", "--orientation euler:ZYX"],
                    tmp_path / "o")
    code, out, err = run(capsys, "calibrate", tmp_path / "m.yaml", src / "quat_xyzw.csv", "--out", tmp_path / "o",
                         "--orientation", "rpy")
    _one_line_error(code, err, [f"{src / 'quat_xyzw.csv'}: orientation: the file declares orientation quat_xyzw "
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
    code, out, err = run(capsys, "calibrate", tmp_path / "m.yaml", tmp_path / "z.csv", "--out", tmp_path / "o",
                         "--sep", ";", "--decimal", ",")
    _one_line_error(code, err, [f"{tmp_path / 'z.csv'}: line 5, column 'rhand_qx': quaternion of zero norm"],
                    tmp_path / "o")


def test_malformed_urdf_file_names_file_and_line(tmp_path):
    path = tmp_path / "arm.urdf"
    path.write_text('<robot name="arm">\n  <link name="a">\n  <link name="b"/>\n</robot>\n')
    with pytest.raises(rc.InputError) as err:
        rc.read_urdf(path)
    assert err.value.source == str(path)
    assert str(err.value).startswith(f"{path}: malformed XML") and "line 4" in str(err.value)
