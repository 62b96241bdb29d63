"""import-urdf on stock arm URDFs: UR5, Panda and Kinova (Jaco) from the example-robot-data package
(a test dependency), and a Gen3-shaped arm written for these tests (examples/urdf/gen3_like.urdf;
the package ships no Gen3). The reference is an independent evaluation of the URDF's own numbers:
origin times joint motion per joint, with plain 4x4 products and scipy rotations."""

from __future__ import annotations

import math
import sysconfig
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import robocal as rc

DATA = Path(__file__).resolve().parent.parent / "examples" / "urdf"
ERD = Path(sysconfig.get_paths()["purelib"]) / "cmeel.prefix" / "share" / "example-robot-data" / "robots"

STOCK = {   # file, the tip the import should choose, the arm's joints
    "ur5": (ERD / "ur_description/urdf/ur5_robot.urdf", "wrist_3_link", 6),
    "panda": (ERD / "panda_description/urdf/panda.urdf", "panda_hand_tcp", 7),
    "kinova-jaco": (ERD / "kinova_description/robots/kinova.urdf", "j2s6s200_link_6", 6),
    "gen3-like": (DATA / "gen3_like.urdf", "gripper_base_link", 7),
}


def _numbers(text, n, default):
    return np.array([float(v) for v in text.split()]) if text else np.array(default, float)


def _reference(path: Path, tip: str, q: np.ndarray) -> np.ndarray:
    """X (n_poses, 4, 4) of ``tip`` in the root link: the URDF's joints from the root to the tip."""
    root = ET.parse(path).getroot()
    joints = {j.find("child").get("link"): j for j in root.findall("joint")}
    chain, link = [], tip
    while link in joints:
        chain.append(joints[link])
        link = joints[link].find("parent").get("link")
    chain.reverse()
    names = [j.get("name") for j in chain if j.get("type") != "fixed"]
    out = np.tile(np.eye(4), (len(q), 1, 1))
    for j in chain:
        o = j.find("origin")
        X = np.eye(4)
        if o is not None:
            X[:3, :3] = Rotation.from_euler("xyz", _numbers(o.get("rpy"), 3, [0, 0, 0])).as_matrix()
            X[:3, 3] = _numbers(o.get("xyz"), 3, [0, 0, 0])
        out = out @ X
        if j.get("type") == "fixed":
            continue
        ax = j.find("axis")
        u = _numbers(None if ax is None else ax.get("xyz"), 3, [1, 0, 0])
        u = u / np.linalg.norm(u)
        v = q[:, names.index(j.get("name"))]
        M = np.tile(np.eye(4), (len(q), 1, 1))
        if j.get("type") == "prismatic":
            M[:, :3, 3] = v[:, None] * u
        else:
            M[:, :3, :3] = Rotation.from_rotvec(v[:, None] * u).as_matrix()
        out = out @ M
    return out


@pytest.mark.parametrize("robot", list(STOCK))
def test_stock_urdf_forward_kinematics(robot, tmp_path, cli):
    path, tip, n_joints = STOCK[robot]
    if not path.exists():
        pytest.skip("example-robot-data is not installed (pip install example-robot-data)")
    out = tmp_path / "arm.yaml"
    code, printed, err = cli("import-urdf", path, "--out", out)
    assert code == 0, err
    model = rc.read_model(out)              # the written file, in mm and degrees, read back
    assert model.n_joints == n_joints and model.description.endswith(f"-> {tip}")
    rng = np.random.default_rng(1)
    lo, hi = np.maximum(model.lower_limits, -math.pi), np.minimum(model.upper_limits, math.pi)
    q = rng.uniform(lo, hi, size=(40, model.n_joints))
    X = _reference(path, tip, q)
    ev = rc.forward_kinematics(model, q)
    assert np.abs(ev.positions[:, 0] - X[:, :3, 3]).max() < 1e-9
    assert np.abs(ev.rotations[:, 0] - X[:, :3, :3]).max() < 1e-9
    # what the file says is clean: no 1.87e-37 from round-off, nor 179.999999999719 where the URDF
    # wrote pi to 11 digits (the Gen3 shape writes 3.1416, which is a different angle)
    text = out.read_text()
    assert "e-3" not in text and "e-2" not in text, text
    if robot != "gen3-like":
        assert "99999999" not in text and "00000000" not in text and "e-1" not in text, text


def test_fixed_leaf_is_no_branch_and_the_flag_is_named_as_typed(tmp_path, cli):
    urdf = tmp_path / "two.urdf"
    urdf.write_text('<robot name="y"><link name="root"/><link name="a"/><link name="b"/>'
                    '<joint name="ja" type="revolute"><parent link="root"/><child link="a"/><axis xyz="0 0 1"/>'
                    '<limit lower="-1" upper="1"/></joint>'
                    '<joint name="jb" type="revolute"><parent link="root"/><child link="b"/><axis xyz="0 0 1"/>'
                    '<limit lower="-1" upper="1"/></joint></robot>')
    code, _, err = cli("import-urdf", urdf, "--out", tmp_path / "y.yaml")
    assert code == 2 and "--tip-link" in err and "tip_link" not in err
    code, printed, err = cli("import-urdf", urdf, "--out", tmp_path / "y.yaml", "--tip-link", "b")
    assert code == 0 and "1 joints (jb)" in printed
