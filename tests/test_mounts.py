"""Robots written down as they are: fixed frames and tool centre points given as transforms, rotation
matrices as vendors print them, several payloads."""

import re

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

import robocal as rc
from robocal.kinematics import mdh_transform

DEG = np.pi / 180


def printed(R, decimals=3):
    return [[round(float(v), decimals) for v in row] for row in R]


# the TCPs of the table: 30 deg about z then 20 deg about y, and 120 deg about (1, 2, 2)
R_LTCP = Rotation.from_euler("zy", [30, 20], degrees=True).as_matrix()
R_RTCP = Rotation.from_rotvec(np.deg2rad(120) * np.array([1, 2, 2]) / 3).as_matrix()

# two arms on a torso; mounts and TCPs from a table of 4x4 transforms (mm, 3 printed decimals)
TABLE = {
    "robocal_model": 1, "name": "two-arm torso", "units": {"length": "mm", "angle": "deg"},
    "base": {"position": [1500, 200, 0]},
    "joints": ["t1", "l1", "l2", "l3", "r1", "r2", "r3"],
    "frames": [
        {"name": "t1", "joint": "revolute", "r": 800, "mass": 30, "com": [0, 0, -300]},
        {"name": "lmount", "joint": "fixed", "parent": "t1", "position": [0, 250, 300],
         "rotation": {"matrix": [[1, 0, 0], [0, 0, -1], [0, 1, 0]]}},
        {"name": "l1", "joint": "revolute", "mass": 4, "com": [0, 0, 50]},
        {"name": "l2", "joint": "revolute", "alpha": -90, "d": 50, "mass": 3, "com": [150, 0, 0]},
        {"name": "l3", "joint": "revolute", "d": 300, "mass": 2, "com": [120, 0, 0]},
        {"name": "ltcp", "joint": "fixed", "position": [250, 0, 30], "rotation": {"matrix": printed(R_LTCP)}},
        {"name": "rmount", "joint": "fixed", "parent": "t1", "position": [0, -250, 300],
         "rotation": {"matrix": [[1, 0, 0], [0, 0, 1], [0, -1, 0]]}},
        {"name": "r1", "joint": "revolute", "mass": 4, "com": [0, 0, 50]},
        {"name": "r2", "joint": "revolute", "alpha": 90, "d": 50, "mass": 3, "com": [150, 0, 0]},
        {"name": "r3", "joint": "revolute", "d": 300, "mass": 2, "com": [120, 0, 0]},
        {"name": "rtcp", "joint": "fixed", "position": [200, 10, 40], "rotation": {"matrix": printed(R_RTCP)}},
    ],
    "markers": [{"name": "lhand", "frame": "ltcp", "position": [0, 0, 0]},
                {"name": "rhand", "frame": "rtcp", "position": [10, 0, 5]}],
    "payload": [{"mass": 2.0, "com": [0, 0, 20], "frame": "ltcp"}, {"mass": 1.5, "com": [0, 0, 30], "frame": "rtcp"}],
}


def hand_derived() -> rc.RobotModel:
    """The same robot in Khalil-Kleinfinger parameters worked out by hand: a mount Trans(0, +-250, 300)
    Rot(x, +-90) is b = 300, alpha = +-90, r = -250; a TCP is folded into the markers on the last
    moving frame (its rotation the printed matrix made orthonormal)."""
    d = yaml.safe_load(yaml.safe_dump(TABLE))
    frames = d["frames"]
    frames[1] = {"name": "lmount", "joint": "fixed", "parent": "t1", "b": 300, "alpha": 90, "r": -250}
    frames[6] = {"name": "rmount", "joint": "fixed", "parent": "t1", "b": 300, "alpha": -90, "r": -250}
    markers = []
    for m, (tcp, arm) in zip(d["markers"], ((frames[5], "l3"), (frames[10], "r3"))):
        U, _, Vt = np.linalg.svd(np.array(tcp["rotation"]["matrix"], dtype=float))
        R = U @ Vt
        markers.append({"name": m["name"], "frame": arm,
                        "position": (np.array(tcp["position"]) + R @ np.array(m["position"])).tolist(),
                        "rotation": {"matrix": R.tolist()}})
    d["frames"] = [f for f in frames if f["name"] not in ("ltcp", "rtcp")]
    d["markers"] = markers
    d["payload"] = [{"mass": 2.0, "com": (R_of(TABLE, 5) @ [0, 0, 20] + [250, 0, 30]).tolist(), "frame": "l3"},
                    {"mass": 1.5, "com": (R_of(TABLE, 10) @ [0, 0, 30] + [200, 10, 40]).tolist(), "frame": "r3"}]
    return rc.model_from_dict(d)


def R_of(table, i):
    U, _, Vt = np.linalg.svd(np.array(table["frames"][i]["rotation"]["matrix"], dtype=float))
    return U @ Vt


def test_mounts_and_tcps_from_a_table_match_the_hand_derived_model(tmp_path):
    (tmp_path / "table.yaml").write_text(yaml.safe_dump(TABLE, sort_keys=False))
    model = rc.read_model(tmp_path / "table.yaml")
    hand = hand_derived()
    q = rc.random_configurations(model, 50, np.random.default_rng(0))
    a, b = rc.forward_kinematics(model, q), rc.forward_kinematics(hand, q)
    assert np.abs(a.positions - b.positions).max() < 1e-9
    assert np.abs(a.rotations - b.rotations).max() < 1e-9
    # gravity too: each payload on its own frame acts as on the folded frame
    np.testing.assert_allclose(rc.gravity_loads(model, q), rc.gravity_loads(hand, q), atol=1e-9)
    # the 3-decimal matrices were re-orthonormalised, and said so with the change
    notes = " ".join(model.notes)
    assert "frames[5].rotation.matrix: re-orthonormalised" in notes and "frames[10]" in notes
    assert "frames[1]" not in notes   # an exact matrix is taken as it is
    # the file written back keeps the placement as DH values and reads back the same robot
    rc.write_model(model, tmp_path / "back.yaml")
    back = rc.read_model(tmp_path / "back.yaml")
    assert np.abs(rc.forward_kinematics(back, q).positions - a.positions).max() < 1e-9
    assert len(back.other_payloads) == 1 and back.other_payloads[0].mass == 1.5


def test_fixed_placement_against_the_product_of_transforms():
    model = rc.model_from_dict(TABLE)
    i = model.frame_names.index("rtcp")
    X = np.eye(4)
    X[:3, :3] = R_of(TABLE, 10)
    X[:3, 3] = np.array([200, 10, 40]) / 1e3
    np.testing.assert_allclose(mdh_transform(model.frames[i]), X, atol=1e-14)


def test_table_calibrates_from_the_command_line(tmp_path, cli):
    (tmp_path / "table.yaml").write_text(yaml.safe_dump(TABLE, sort_keys=False))
    model = rc.read_model(tmp_path / "table.yaml")
    true, data = rc.simulate(model, 40, seed=4)
    rc.write_measurements(data, tmp_path / "d.csv", model=model)
    code, out, err = cli("calibrate", tmp_path / "table.yaml", tmp_path / "d.csv", "--out", tmp_path / "o")
    assert code == 0, err + out
    assert "re-orthonormalised" in out
    assert rc.read_model(tmp_path / "o" / "calibrated.yaml").n_frames == model.n_frames


@pytest.mark.parametrize("edit, where, words", [
    (lambda f: f[2].update(position=[0, 0, 1]), "frames[2].position", "only a fixed frame"),
    (lambda f: f[1].update(d=5), "frames[1].d", "either as position/rotation or as"),
    (lambda f: f[5].update(rotation={"matrix": printed(1.02 * R_LTCP)}), "frames[5].rotation.matrix",
     "accepted within 0.005"),
])
def test_placement_errors(edit, where, words):
    d = yaml.safe_load(yaml.safe_dump(TABLE))
    edit(d["frames"])
    with pytest.raises(rc.InputError) as err:
        rc.model_from_dict(d, source="t.yaml")
    assert err.value.where == where and words in str(err.value)


def test_report_and_summary_show_every_nonzero_nominal_the_calibrated_file_keeps():
    from robocal._presentation.html import render_report
    from robocal._presentation.text import calibration_summary

    model = rc.model_from_dict(TABLE)
    _, data = rc.simulate(model, 30, seed=4)
    result = rc.calibrate(model, data)
    lay = dict(zip(rc.parameter_names(model), rc.parameter_vector(result.calibrated_model)))
    held = dict(result.held_nominals)
    considered = set(result.identifiability.candidates)
    # exactly the non-zero values outside the candidates (rotation corrections are zero in a model)
    assert held == {n: v for n, v in lay.items() if v != 0.0 and n not in considered}
    assert {"ltcp.beta", "rtcp.gamma"} <= set(held)
    summary = calibration_summary(result)
    assert f"kept at nominal, not candidates ({len(held)} non-zero)" in summary and "rtcp.gamma" in summary
    html = render_report(result)
    # a fixed frame's held values show as its placement, as the file writes it (position in mm, matrix)
    for name in ("ltcp", "rtcp"):
        placed = next(f for f in TABLE["frames"] if f["name"] == name)
        shown = re.search(rf'data-key="{name}:nominal.position"[^>]*>([^<]*)<', html).group(1)
        assert [float(v) for v in shown.split(",")] == pytest.approx(placed["position"], abs=5e-5)
    moving = {n.split(".")[0] for n in held} - {"ltcp", "rtcp", "lmount", "rmount"}
    for n in held:
        if n.split(".")[0] in moving:
            assert f"{np.rad2deg(held[n]):.5f}"[:7] in html   # shown in the frame table's nominal row
