"""Importers and exporters: forward kinematics equals a direct evaluation of the source to 1e-12 m.

The references here are written out with plain 4x4 products (DH) and scipy rotations (URDF), so
they share no code with robocal's engine or with the importers.
"""

from __future__ import annotations

import csv
from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import robocal as rc
from robocal.io import from_standard_dh, mdh_table, read_urdf, write_mdh_csv, write_urdf

TOL_M = 1e-12      # positions, metres
TOL_R = 1e-12      # rotation matrix entries

# ---------------------------------------------------------------------------------------------
# classic DH reference

UR5 = dict(d=[0.089159, 0.0, 0.0, 0.10915, 0.09465, 0.0823],
           a=[0.0, -0.425, -0.39225, 0.0, 0.0, 0.0],
           alpha=[np.pi / 2, 0.0, 0.0, np.pi / 2, -np.pi / 2, 0.0])


def _dh_matrix(theta, d, a, alpha):
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    return np.array([[ct, -st * ca, st * sa, a * ct],
                     [st, ct * ca, -ct * sa, a * st],
                     [0.0, sa, ca, d],
                     [0.0, 0.0, 0.0, 1.0]])


def _dh_reference(offsets, d, a, alpha, joints, q, X_W0, X_nT):
    """X_WT = X_W0 prod_i Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i) X_nT, joint value into theta or d."""
    out = []
    for qi in q:
        X = X_W0.copy()
        for i in range(len(d)):
            th = offsets[i] + (qi[i] if joints[i] == "revolute" else 0.0)
            di = d[i] + (qi[i] if joints[i] == "prismatic" else 0.0)
            X = X @ _dh_matrix(th, di, a[i], alpha[i])
        out.append(X @ X_nT)
    return np.array(out)


def _pose(R, p):
    X = np.eye(4)
    X[:3, :3] = R
    X[:3, 3] = p
    return X


def _check_fk(model, q, X_ref, marker=0):
    ev = rc.forward_kinematics(model, q)
    np.testing.assert_allclose(ev.positions[:, marker], X_ref[:, :3, 3], rtol=0, atol=TOL_M)
    np.testing.assert_allclose(ev.rotations[:, marker], X_ref[:, :3, :3], rtol=0, atol=TOL_R)


@pytest.fixture
def rng():
    return np.random.default_rng(20240611)


def _random_q(rng, n, n_poses=50):
    return rng.uniform(-np.pi, np.pi, size=(n_poses, n))


def test_ur5_standard_dh_matches_direct_products(rng):
    offsets = rng.uniform(-0.3, 0.3, 6)       # encoder zero offsets make the test sharper
    rows = [dict(theta=offsets[i], d=UR5["d"][i], a=UR5["a"][i], alpha=UR5["alpha"][i]) for i in range(6)]
    X_W0 = _pose(Rotation.from_rotvec([0.1, -0.2, 0.3]).as_matrix(), [1.2, -0.4, 0.3])
    R_tool = Rotation.from_rotvec([0.4, 0.1, -0.7]).as_matrix()
    p_tool = np.array([0.01, -0.02, 0.15])
    model = from_standard_dh(rows, name="ur5", markers=[("tool", p_tool, R_tool), ("flange", (0, 0, 0))],
                             base=X_W0)
    q = _random_q(rng, 6)
    joints = ["revolute"] * 6
    _check_fk(model, q, _dh_reference(offsets, UR5["d"], UR5["a"], UR5["alpha"], joints, q, X_W0,
                                      _pose(R_tool, p_tool)))
    _check_fk(model, q, _dh_reference(offsets, UR5["d"], UR5["a"], UR5["alpha"], joints, q, X_W0,
                                      np.eye(4)), marker=1)
    # frames 2 and 3 (parallel shoulder/elbow axes) carry beta; the tilted ones do not
    assert [f.has_beta for f in model.frames] == [True, False, True, True, False, False]
    assert model.joint_names == ("j1", "j2", "j3", "j4", "j5", "j6")


def test_standard_dh_with_prismatic_row(rng):
    d = [0.3, 0.1, 0.0, 0.05]
    a = [0.2, 0.0, 0.1, 0.0]
    alpha = [0.0, -np.pi / 2, np.pi / 2, 0.3]
    joints = ["revolute", "prismatic", "revolute", "revolute"]
    offsets = [0.1, 0.2, -0.3, 0.0]
    rows = [(offsets[i], d[i], a[i], alpha[i], joints[i]) for i in range(4)]
    model = from_standard_dh(rows, name="rprr")
    q = _random_q(rng, 4)
    _check_fk(model, q, _dh_reference(offsets, d, a, alpha, joints, q, np.eye(4), np.eye(4)))
    assert model.frames[1].joint == "prismatic"


def test_standard_dh_rejects_bad_rows():
    with pytest.raises(rc.InputError, match=r"rows\[1\]"):
        from_standard_dh([(0, 0, 0, 0), (0, 0, 0)], name="x")
    with pytest.raises(rc.InputError, match="joint type"):
        from_standard_dh([(0, 0, 0, 0, "spherical")], name="x")
    with pytest.raises(rc.InputError, match="joint_limits"):
        from_standard_dh([(0, 0, 0, 0)], name="x", joint_limits=[(0, 1), (0, 1)])


# ---------------------------------------------------------------------------------------------
# URDF reference

def _urdf_reference(joints, q):
    """Compose ``origin * motion`` per joint; joints: (type, xyz, rpy, axis); q per moving joint."""
    out = []
    for qi in q:
        X = np.eye(4)
        k = 0
        for jtype, xyz, rpy, axis in joints:
            X = X @ _pose(Rotation.from_euler("xyz", rpy).as_matrix(), xyz)   # extrinsic = Rz Ry Rx
            if jtype == "fixed":
                continue
            u = np.asarray(axis, float) / np.linalg.norm(axis)
            if jtype == "prismatic":
                X = X @ _pose(np.eye(3), qi[k] * u)
            else:
                X = X @ _pose(Rotation.from_rotvec(qi[k] * u).as_matrix(), np.zeros(3))
            k += 1
        out.append(X)
    return np.array(out)


def _urdf_text(name, joints, limits=None):
    """URDF for a chain link0 -> link1 ... from (type, xyz, rpy, axis) rows."""
    parts = [f'<robot name="{name}">']
    parts += [f'  <link name="link{i}"/>' for i in range(len(joints) + 1)]
    for i, (jtype, xyz, rpy, axis) in enumerate(joints):
        lim = ""
        if jtype in ("revolute", "prismatic"):
            lo, hi = (limits or {}).get(i, (-2.9, 2.9))
            lim = f'<limit lower="{lo!r}" upper="{hi!r}" effort="100" velocity="1"/>'
        parts.append(
            f'  <joint name="joint{i + 1}" type="{jtype}"><parent link="link{i}"/><child link="link{i + 1}"/>'
            f'<origin xyz="{" ".join(map(repr, xyz))}" rpy="{" ".join(map(repr, rpy))}"/>'
            f'<axis xyz="{" ".join(map(repr, axis))}"/>{lim}</joint>')
    parts.append("</robot>")
    return "\n".join(parts)


# a 7-axis arm after the iiwa 14's public link lengths, with axes given as y, x and skew directions
# and some rotated origins, so every branch of the line geometry is used
ARM7 = [
    ("revolute", (0.0, 0.0, 0.1575), (0.0, 0.0, 0.0), (0, 0, 1)),
    ("revolute", (0.0, 0.0, 0.2025), (0.0, 0.0, 0.3), (0, 1, 0)),
    ("revolute", (0.0, 0.0, 0.2045), (0.1, 0.0, 0.0), (0, 0, 1)),
    ("revolute", (0.0, 0.0, 0.2155), (0.0, 0.0, 0.0), (1, 0, 0)),
    ("continuous", (0.0, 0.02, 0.1845), (0.0, -0.2, 0.0), (0, 0, 1)),
    ("revolute", (0.0, 0.0, 0.2155), (np.pi / 2, 0.0, np.pi), (0, -1, 0)),
    ("revolute", (0.01, 0.0, 0.081), (0.0, 0.0, 0.0), (0.1, 0.2, 2.0)),
    ("fixed", (0.0, 0.0, 0.045), (0.3, -0.2, 0.5), (1, 0, 0)),
]

# a SCARA-like arm: parallel axes, a prismatic joint along -z, a fixed joint, an axis 0.2 deg off
# parallel (beta), and a revolute axis at a skew angle
SCARA = [
    ("fixed", (0.1, 0.2, 0.05), (0.0, 0.0, 0.4), (1, 0, 0)),
    ("revolute", (0.0, 0.0, 0.3), (0.0, 0.0, 0.0), (0, 0, 1)),
    ("revolute", (0.4, 0.0, 0.02), (0.0, 0.0, 0.0), (0, 0, 1)),
    ("prismatic", (0.3, 0.05, 0.0), (0.0, 0.0, 0.0), (0, 0, -1)),
    ("fixed", (0.0, 0.0, -0.1), (0.0, 0.0, 0.7), (0, 0, 1)),
    ("revolute", (0.0, 0.0, -0.02), (0.0, 0.0, 0.0),
     (float(np.sin(np.deg2rad(0.2))), 0, float(np.cos(np.deg2rad(0.2))))),
    ("revolute", (0.0, 0.05, -0.03), (0.2, 0.0, 0.0), (1, 1, 1)),
    ("fixed", (0.0, 0.0, -0.06), (np.pi, 0.0, 0.0), (1, 0, 0)),
]


def _moving(joints):
    return [j for j in joints if j[0] != "fixed"]


@pytest.mark.parametrize("joints", [ARM7, SCARA], ids=["arm7", "scara"])
def test_urdf_matches_composed_origins(joints, rng):
    model = read_urdf(_urdf_text("arm", joints))
    n = len(_moving(joints))
    assert model.n_joints == n
    assert model.joint_names == tuple(f"joint{i + 1}" for i, j in enumerate(joints) if j[0] != "fixed")
    q = _random_q(rng, n)
    if joints is SCARA:
        q[:, 2] = rng.uniform(-0.2, 0.2, len(q))   # metres on the prismatic joint
    _check_fk(model, q, _urdf_reference(joints, q))


def test_urdf_prismatic_fixed_and_parallel_axes_are_modelled_as_expected():
    model = read_urdf(_urdf_text("scara", SCARA))
    kinds = [f.joint for f in model.frames]
    assert kinds == ["revolute", "revolute", "prismatic", "revolute", "revolute"]
    # frame 2 is parallel to frame 1: x along the 0.4 m link, r = 0 on the earlier frame
    assert model.frames[1].d == pytest.approx(0.4, abs=1e-15)
    assert model.frames[0].r == pytest.approx(0.0, abs=1e-15)
    assert [f.has_beta for f in model.frames] == [True, True, True, True, False]
    # the 0.2 deg tilt sits in beta, not in a huge common-normal offset
    assert abs(model.frames[3].beta) == pytest.approx(np.deg2rad(0.2), abs=1e-12)
    assert abs(model.frames[3].r) < 1.0
    # the first axis is the root's z through the origin's vertical: base = the fixed root offset
    np.testing.assert_allclose(model.base_position, [0.1, 0.2, 0.0], atol=1e-15)


def test_urdf_limits_and_continuous():
    model = read_urdf(_urdf_text("arm", ARM7, limits={0: (-1.0, 2.0)}))
    assert model.joint_limits[0] == (-1.0, 2.0)
    assert model.joint_limits[4] == (-np.pi, np.pi)        # continuous


def test_urdf_masses_follow_links(rng):
    text = _urdf_text("arm", ARM7).replace(
        '<link name="link4"/>',
        '<link name="link4"><inertial><origin xyz="0.1 -0.02 0.03"/><mass value="2.5"/></inertial></link>')
    model = read_urdf(text)
    f = model.frames[3]
    assert f.mass == 2.5
    q = _random_q(rng, 7, 5)
    ev = rc.forward_kinematics(model, q, frames=True)
    c_W = ev.frames[:, 3, :3, :3] @ np.array(f.com) + ev.frames[:, 3, :3, 3]
    X_ref = _urdf_reference(ARM7[:4], q[:, :4])
    np.testing.assert_allclose(c_W, X_ref[:, :3, :3] @ [0.1, -0.02, 0.03] + X_ref[:, :3, 3], atol=TOL_M)


def test_urdf_tip_link_markers_and_file(tmp_path, rng):
    path = tmp_path / "arm.urdf"
    path.write_text(_urdf_text("arm", ARM7))
    p = np.array([0.0, 0.01, 0.12])
    model = read_urdf(path, base_link="link0", tip_link="link5", markers=[("ball", p)])
    assert model.n_joints == 5 and model.name == "arm"
    q = _random_q(rng, 5)
    X_ref = _urdf_reference(ARM7[:5], q)
    ev = rc.forward_kinematics(model, q)
    np.testing.assert_allclose(ev.positions[:, 0], X_ref[:, :3, :3] @ p + X_ref[:, :3, 3], atol=TOL_M)
    # a base inside the chain: W is that link
    model = read_urdf(path, base_link="link2", tip_link="link8")
    q = _random_q(rng, 5)
    _check_fk(model, q, _urdf_reference(ARM7[2:], q))


def test_urdf_mimic_becomes_coupling(rng):
    text = _urdf_text("arm", ARM7).replace(
        '<joint name="joint3" type="revolute">',
        '<joint name="joint3" type="revolute"><mimic joint="joint2" multiplier="-0.5" offset="0.2"/>')
    model = read_urdf(text)
    assert model.n_joints == 6 and "joint3" not in model.joint_names
    assert model.frames[2].coupling == ((1, -0.5),)
    q6 = _random_q(rng, 6)
    q7 = np.insert(q6, 2, -0.5 * q6[:, 1] + 0.2, axis=1)
    _check_fk(model, q6, _urdf_reference(ARM7, q7))


# ---------------------------------------------------------------------------------------------
# round trips

def _ur5_model():
    rows = [dict(theta=0.1 * i, d=UR5["d"][i], a=UR5["a"][i], alpha=UR5["alpha"][i]) for i in range(6)]
    return from_standard_dh(rows, name="ur5", markers=[("tool", (0.01, 0.0, 0.1),
                                                        Rotation.from_rotvec([0.3, 0, 0.1]).as_matrix())],
                            base=_pose(Rotation.from_rotvec([0, 0.2, 1.0]).as_matrix(), [0.5, 0.1, -0.2]))


def _gimbal_model():
    """Origins at pitch +-pi/2 (and just off it), where roll and yaw are ill-conditioned."""
    return rc.serial_model("g", [dict(), dict(beta=np.pi / 2, alpha=0.3, theta=0.2, d=0.3, r=0.1),
                                      dict(beta=np.pi / 2 - 1e-7, alpha=-0.4, d=0.2),
                                      dict(beta=-np.pi / 2 + 3.7e-6, alpha=1.1, theta=-2.0, d=0.1)],
                                markers=[("t", (0.1, 0.2, 0.3))])


@pytest.mark.parametrize("make", [
    _ur5_model,
    lambda: read_urdf(_urdf_text("arm", ARM7)),
    lambda: read_urdf(_urdf_text("scara", SCARA)),
    _gimbal_model,
], ids=["ur5", "arm7", "scara", "gimbal"])
def test_write_then_read_urdf_keeps_fk(make, tmp_path, rng):
    model = make()
    path = tmp_path / "out.urdf"
    write_urdf(model, path)
    back = read_urdf(path)
    assert back.joint_names == model.joint_names
    assert back.joint_limits == model.joint_limits
    q = _random_q(rng, model.n_joints)
    if any(f.joint == "prismatic" for f in model.frames):
        q[:, 2] = rng.uniform(-0.2, 0.2, len(q))
    a, b = rc.forward_kinematics(model, q), rc.forward_kinematics(back, q)
    np.testing.assert_allclose(b.positions, a.positions, rtol=0, atol=TOL_M)
    np.testing.assert_allclose(b.rotations, a.rotations, rtol=0, atol=TOL_R)
    assert not list(tmp_path.glob(".*.tmp"))       # atomic write leaves no temporary behind


def test_write_urdf_tree_and_mimic(tmp_path, rng):
    base = rc.serial_model("t", [dict(), dict(alpha=np.pi / 2, d=0.3), dict(d=0.4, theta=0.2)],
                                markers=[("tip", (0.1, 0, 0))])
    frames = list(base.frames)
    # frame 3 hangs off frame 1 (a tree, using gamma and b) and follows -0.5 x reading j2
    frames[2] = replace(frames[2], parent=0, gamma=0.3, b=0.05, coupling=((1, -0.5),))
    model = base.replace(frames=tuple(frames), joint_names=("j1", "j2"), joint_limits=((-1, 1), (-2, 2)),
                         markers=(rc.Marker("a", 1, (0, 0.1, 0)), rc.Marker("b", 2, (0.2, 0, 0.1))))
    path = tmp_path / "tree.urdf"
    write_urdf(model, path)
    q = _random_q(rng, 2)
    ref = rc.forward_kinematics(model, q)
    for m, tip in ((0, "a"), (1, "b")):
        back = read_urdf(path, tip_link=tip)
        np.testing.assert_allclose(rc.forward_kinematics(back, q).positions[:, 0], ref.positions[:, m],
                                   rtol=0, atol=TOL_M)
    assert '<mimic joint="j2" multiplier="-0.5"' in path.read_text()


def test_write_urdf_rejects_multi_reading_coupling(tmp_path):
    m = rc.serial_model("x", [dict(), dict(d=0.2)])
    m = m.replace(frames=(m.frames[0], replace(m.frames[1], coupling=((0, 1.0), (1, 1.0)))))
    with pytest.raises(rc.InputError, match="several readings"):
        write_urdf(m, tmp_path / "x.urdf")
    assert not (tmp_path / "x.urdf").exists()


# ---------------------------------------------------------------------------------------------
# MDH table

def test_mdh_table_and_csv(tmp_path):
    model = _ur5_model()
    rows = mdh_table(model)
    assert list(rows[0]) == ["frame", "parent", "joint", "reading", "has_beta", "beta_rad", "alpha_rad",
                             "d_m", "theta_rad", "r_m", "gamma_rad", "b_m"]
    assert rows[2]["d_m"] == -0.425 and rows[1]["alpha_rad"] == np.pi / 2 and rows[0]["parent"] == "base"
    path = tmp_path / "mdh.csv"
    write_mdh_csv(model, path)
    with open(path, newline="") as fh:
        got = list(csv.DictReader(fh))[1:]       # the first row places the base
    assert float(got[2]["d_mm"]) == pytest.approx(-425.0, abs=1e-12)
    assert float(got[4]["alpha_deg"]) == pytest.approx(90.0, abs=1e-12)
    assert float(got[0]["r_mm"]) == pytest.approx(89.159, abs=1e-12)
    assert got[3]["reading"] == "j4"
    with pytest.raises(rc.InputError, match="units"):
        mdh_table(model, units="furlong")


# ---------------------------------------------------------------------------------------------
# bad input

GOOD = _urdf_text("arm", ARM7[:3])


@pytest.mark.parametrize("text, match, where", [
    ('<robot name="x"><link name="a"></robot>', "malformed XML", None),
    (GOOD.replace('name="joint2"', 'name="joint1"'), "named twice", "joint 'joint1'"),
    (GOOD.replace('<parent link="link1"/>', '<parent link="nowhere"/>'), "not defined", "joint 'joint2'"),
    (GOOD.replace('<axis xyz="0 1 0"/>', '<axis xyz="0 0 0"/>'), "zero length", "joint 'joint2'"),
    (GOOD.replace('type="revolute"', 'type="floating"', 1), "not supported", "joint 'joint1'"),
    (GOOD.replace('<axis xyz="0 1 0"/>', '<axis xyz="0 one 0"/>'), "3 numbers", "joint 'joint2' axis"),
    (GOOD.replace('<robot name="arm">',
                  '<robot name="arm"><link name="side"/><joint name="s" type="revolute"><parent link="link0"/>'
                  '<child link="side"/><limit lower="-1" upper="1"/></joint>'), "branches at link 'link0'",
     "tip_link"),
    (GOOD.replace("<limit", "<nolimit"), "needs <limit", "joint 'joint1'"),
], ids=["malformed", "joint-twice", "unknown-parent", "zero-axis", "floating", "bad-number", "branch",
        "no-limit"])
def test_bad_urdf(text, match, where):
    with pytest.raises(rc.InputError, match=match) as err:
        read_urdf(text)
    assert err.value.source == "<string>"
    assert err.value.where == where


def test_entity_bomb_is_refused_before_parsing(tmp_path):
    bomb = ('<?xml version="1.0"?>\n<!DOCTYPE robot [\n <!ENTITY a "aaaaaaaaaa">\n'
            + "".join(f' <!ENTITY a{i + 1} "&a{i};&a{i};&a{i};&a{i};&a{i};&a{i};&a{i};&a{i};">\n'.replace("&a0;", "&a;")
                      for i in range(12))
            + ']>\n<robot name="&a12;"><link name="l"/></robot>')
    path = tmp_path / "bomb.urdf"
    path.write_text(bomb)
    with pytest.raises(rc.InputError, match="DOCTYPE") as err:
        read_urdf(path)
    assert err.value.source == str(path)
    external = '<!DOCTYPE r [<!ENTITY x SYSTEM "file:///etc/passwd">]><robot name="&x;"/>'
    with pytest.raises(rc.InputError, match="DOCTYPE"):
        read_urdf(external)


def test_missing_file_and_wrong_root(tmp_path):
    with pytest.raises(rc.InputError, match="cannot read") as err:
        read_urdf(tmp_path / "none.urdf")
    assert err.value.source.endswith("none.urdf")
    with pytest.raises(rc.InputError, match="<robot>"):
        read_urdf("<sdf/>")


def test_malformed_urdf_file_names_file_and_line(tmp_path):
    path = tmp_path / "arm.urdf"
    path.write_text('<robot name="arm">\n  <link name="a">\n  <link name="b"/>\n</robot>\n')
    with pytest.raises(rc.InputError) as err:
        rc.read_urdf(path)
    assert err.value.source == str(path)
    assert str(err.value).startswith(f"{path}: malformed XML") and "line 4" in str(err.value)


@pytest.mark.parametrize("markers", [[("tcp", (0.01, 0.02, 0.12))],
                                     [("smr1", (0.05, 0.0, 0.1)), ("smr2", (-0.05, 0.02, 0.1))]],
                         ids=["one", "two"])
def test_urdf_round_trip_keeps_the_marker_names(markers, tmp_path, rng):
    # measurement files name their markers: a model exported and read back must still match them
    model = _ur5_model().replace(markers=tuple(rc.Marker(n, 5, p) for n, p in markers))
    path = tmp_path / "out.urdf"
    write_urdf(model, path)
    back = read_urdf(path)
    assert back.marker_names == model.marker_names
    q = _random_q(rng, model.n_joints)
    np.testing.assert_allclose(rc.forward_kinematics(back, q).positions, rc.forward_kinematics(model, q).positions,
                               rtol=0, atol=TOL_M)
