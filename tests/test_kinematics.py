"""Forward kinematics against hand-computed values and an independent 4x4 implementation;
every Jacobian column against central finite differences."""

import numpy as np
import pytest
from robots import DEG, arm6r, cylindrical
from scipy.spatial.transform import Rotation

import robocal as rc
from robocal.kinematics import (
    Frame,
    Marker,
    Payload,
    RobotModel,
    evaluate,
    model_from_vector,
    parameter_layout,
    parameter_vector,
)


def _T(axis, kind, v):
    """Independent elementary 4x4 transform."""
    T = np.eye(4)
    if kind == "T":
        T[axis, 3] = v
    else:
        T[:3, :3] = Rotation.from_rotvec(np.eye(3)[axis] * v).as_matrix()
    return T


def _mdh(f: Frame, q: float) -> np.ndarray:
    """The docs/method.md transform, written out factor by factor."""
    th = f.theta + (q if f.joint == "revolute" else 0.0)
    r = f.r + (q if f.joint == "prismatic" else 0.0)
    return (_T(2, "R", f.gamma) @ _T(2, "T", f.b) @ _T(1, "R", f.beta) @ _T(0, "R", f.alpha)
            @ _T(0, "T", f.d) @ _T(2, "R", th) @ _T(2, "T", r))


def _reference_fk(model: RobotModel, q: np.ndarray) -> np.ndarray:
    """Marker positions by a per-pose loop of 4x4 products (slow, obviously correct)."""
    out = np.zeros((len(q), len(model.markers), 3))
    C = model.coupling_matrix
    for n, qn in enumerate(q):
        qf = C @ qn
        X = [None] * model.n_frames
        for i, f in enumerate(model.frames):
            parent = model.X_WB if f.parent < 0 else X[f.parent]
            X[i] = parent @ _mdh(f, qf[i])
        for m, mk in enumerate(model.markers):
            out[n, m] = (X[mk.frame] @ np.append(mk.position, 1.0))[:3]
    return out


def test_modified_dh_matrix_matches_method_md():
    # METHOD.md's closed form of T(j-1, j) with beta = 0
    al, d, th, r = 0.3, 0.2, -0.7, 0.15
    expected = np.array([
        [np.cos(th), -np.sin(th), 0, d],
        [np.cos(al) * np.sin(th), np.cos(al) * np.cos(th), -np.sin(al), -r * np.sin(al)],
        [np.sin(al) * np.sin(th), np.sin(al) * np.cos(th), np.cos(al), r * np.cos(al)],
        [0, 0, 0, 1]])
    m = rc.serial_model("one", [dict(joint="revolute", alpha=al, d=d, r=r)], markers=[("tool", (0, 0, 0))])
    X = rc.forward_kinematics(m, [[th]], frames=True).frames[0, 0]
    np.testing.assert_allclose(X, expected, atol=1e-15)
    # the public reference of one frame's placement says the same
    np.testing.assert_allclose(rc.mdh_transform(m.frames[0], th), expected, atol=1e-15)


@pytest.mark.parametrize("joint", ["revolute", "prismatic", "fixed"])
def test_reference_transform_matches_an_independent_product(joint):
    rng = np.random.default_rng(7)
    g, b, be, al, d, th, r, q = rng.uniform(-1, 1, 8)
    f = Frame("f", joint=joint, gamma=g, b=b, beta=be, alpha=al, d=d, theta=th, r=r)
    q = 0.0 if joint == "fixed" else q
    np.testing.assert_allclose(rc.mdh_transform(f, q), _mdh(f, q), atol=1e-15)


def test_planar_two_link_by_hand():
    # two parallel revolute axes, links 0.5 and 0.3: the textbook planar arm
    m = rc.serial_model("planar", [dict(joint="revolute"), dict(joint="revolute", d=0.5)],
                        markers=[("tool", (0.3, 0.0, 0.0))])
    q1, q2 = 0.4, -1.1
    expected = [0.5 * np.cos(q1) + 0.3 * np.cos(q1 + q2), 0.5 * np.sin(q1) + 0.3 * np.sin(q1 + q2), 0.0]
    np.testing.assert_allclose(rc.forward_kinematics(m, [[q1, q2]]).positions[0, 0], expected, atol=1e-15)


def test_cylindrical_by_hand():
    # revolute base, vertical prismatic, radial prismatic: tool at (r cos q1, r sin q1, h)
    m = rc.serial_model("cyl", [dict(joint="revolute"), dict(joint="prismatic"),
                                dict(joint="prismatic", alpha=-90 * DEG)], markers=[("tool", (0, 0, 0))])
    q = np.array([[0.3, 0.7, 0.4]])
    P = rc.forward_kinematics(m, q).positions[0, 0]
    # alpha = -90 deg about x turns z3 onto +y of frame 2, which joint 1 turns by q1 about the vertical
    np.testing.assert_allclose(P, [-0.4 * np.sin(0.3), 0.4 * np.cos(0.3), 0.7], atol=1e-15)


@pytest.mark.parametrize("make", [arm6r, cylindrical])
def test_fk_matches_independent_implementation(make):
    m = make()
    q = rc.random_configurations(m, 20, rng=3)
    np.testing.assert_allclose(rc.forward_kinematics(m, q).positions, _reference_fk(m, q), atol=1e-14)


def _random_tree_model(seed, *, compliance=True, prismatic=True):
    """A random tree with coupled joints, beta and gamma/b everywhere, masses, payload, two markers."""
    rng = np.random.default_rng(seed)
    parents = [-1, 0, 1, 2, 1, 4]
    frames = []
    for i in range(6):
        joint = "prismatic" if (prismatic and rng.random() < 0.4) else "revolute"
        frames.append(Frame(
            name=f"f{i}", joint=joint, parent=parents[i], gamma=rng.normal(0, .3), b=rng.normal(0, .1),
            beta=rng.normal(0, .1), alpha=rng.normal(0, 1), d=rng.normal(0, .3), theta=rng.normal(0, 1),
            r=rng.normal(0, .3), coupling=((i, 1.0),) if i != 3 else ((1, -1.0), (2, 0.5)),
            mass=rng.uniform(1, 5), com=tuple(rng.normal(0, .2, 3)),
            k_theta=rng.normal(0, 1e-3) * compliance, k_alpha=rng.normal(0, 1e-3) * compliance,
            k_beta=rng.normal(0, 1e-3) * compliance))
    rot = lambda s: tuple(map(tuple, Rotation.random(random_state=s).as_matrix()))  # noqa: E731
    return RobotModel(
        name="tree", frames=tuple(frames), joint_names=tuple(f"q{i}" for i in range(6)),
        joint_limits=((-1.0, 1.0),) * 6,
        markers=(Marker("a", 3, (0.1, 0.2, 0.3), rot(seed + 1)), Marker("b", 5, (0.0, 0.1, -0.2))),
        base_position=(0.5, 0.1, -0.2), base_rotation=rot(seed + 2), gravity=(0.3, -1.0, -9.7),
        payload=Payload(2.0, (0.1, 0.0, 0.05), -1))


def _fd_jacobian(model, q, p, h=1e-6, payload_mass=None):
    cols = []
    for k in range(len(p)):
        dp = np.zeros_like(p)
        dp[k] = h
        e1 = evaluate(model, q, p + dp, orientations=True, compliance=True, payload_mass=payload_mass)
        e0 = evaluate(model, q, p - dp, orientations=True, compliance=True, payload_mass=payload_mass)
        dpos = (e1.positions - e0.positions) / (2 * h)
        dR = e1.rotations @ np.swapaxes(e0.rotations, -1, -2)
        drot = Rotation.from_matrix(dR.reshape(-1, 3, 3)).as_rotvec().reshape(dpos.shape) / (2 * h)
        cols.append(np.concatenate([dpos, drot], axis=-1))
    return np.stack(cols, axis=-1)


def _assert_columns_match(model, q, payload_mass=None):
    p = parameter_vector(model)
    J = evaluate(model, q, jacobian=True, compliance=True, payload_mass=payload_mass).jacobian
    F = _fd_jacobian(model, q, p, payload_mass=payload_mass)
    names = parameter_layout(model).names
    scale = np.maximum(np.abs(F).max(axis=(0, 1, 2)), 1e-3)  # relative per column, absolute near zero
    err = np.abs(J - F).max(axis=(0, 1, 2)) / scale
    bad = [(names[k], err[k]) for k in np.nonzero(err > 1e-6)[0]]
    assert not bad, bad


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_every_column_matches_finite_differences_on_random_trees(seed):
    m = _random_tree_model(seed)
    q = np.random.default_rng(seed).uniform(-1, 1, (6, 6))
    _assert_columns_match(m, q)


def test_columns_match_with_per_pose_payload():
    m = _random_tree_model(7)
    q = np.random.default_rng(7).uniform(-1, 1, (5, 6))
    _assert_columns_match(m, q, payload_mass=np.array([0.0, 1.0, 2.5, 4.0, 0.3]))


@pytest.mark.parametrize("make", [arm6r, cylindrical])
def test_columns_match_on_serial_arms_with_and_without_compliance(make):
    m = make(masses=True)
    q = rc.random_configurations(m, 6, rng=1)
    _assert_columns_match(m, q)
    lay = parameter_layout(m)
    compliant = np.array([prm.index for prm in lay.parameters if prm.family == "compliance"])
    p = parameter_vector(m)
    p[compliant] = 1e-5
    _assert_columns_match(model_from_vector(m, p), q)


def test_columns_match_with_some_compliances_zero_and_columns_in_any_order():
    # the corrections are planned from the non-zero compliances and the columns asked for
    m = _random_tree_model(3)
    lay = parameter_layout(m)
    compliant = np.array([prm.index for prm in lay.parameters if prm.family == "compliance"])
    p = parameter_vector(m)
    p[compliant[::3]] = 0.0
    m = model_from_vector(m, p)
    q = np.random.default_rng(3).uniform(-1, 1, (5, 6))
    cols = np.random.default_rng(4).permutation(lay.n_params)[:40]
    J = evaluate(m, q, jacobian=True, compliance=True, columns=cols).jacobian
    F = _fd_jacobian(m, q, p)[..., cols]
    scale = np.maximum(np.abs(F).max(axis=(0, 1, 2)), 1e-3)
    err = np.abs(J - F).max(axis=(0, 1, 2)) / scale
    assert err.max() < 1e-6, [(lay.names[c], e) for c, e in zip(cols, err) if e >= 1e-6]


def test_geometric_columns_are_the_textbook_ones():
    # theta_j: [z_j x (P - O_j); z_j]; r_j: [z_j; 0], in the measurement frame
    m = arm6r()
    q = rc.random_configurations(m, 3, rng=5)
    ev = rc.forward_kinematics(m, q, frames=True)
    J = rc.jacobian(m, q, columns=["j4.theta", "j4.r"])
    z, origin = ev.frames[:, 3, :3, 2], ev.frames[:, 3, :3, 3]
    P = ev.positions[:, 0]
    np.testing.assert_allclose(J[:, 0, :3, 0], np.cross(z, P - origin), atol=1e-14)
    np.testing.assert_allclose(J[:, 0, 3:, 0], z, atol=1e-14)
    np.testing.assert_allclose(J[:, 0, :3, 1], z, atol=1e-14)
    np.testing.assert_allclose(J[:, 0, 3:, 1], 0.0, atol=1e-14)


def test_model_from_vector_round_trip_with_rotation_corrections():
    m = _random_tree_model(3)
    p = parameter_vector(m)
    p[3:6] = [0.01, -0.02, 0.03]
    marker = m.markers[0].name
    p[parameter_layout(m).indices([f"{marker}.rx", f"{marker}.ry", f"{marker}.rz"])] = [0.02, 0.01, -0.01]
    m2 = model_from_vector(m, p)
    np.testing.assert_allclose(parameter_vector(m2, m), p, atol=1e-14)
    q = np.random.default_rng(0).uniform(-1, 1, (4, 6))
    np.testing.assert_allclose(evaluate(m2, q).positions, evaluate(m, q, p).positions, atol=1e-14)


def test_coupled_joint_follows_readings():
    # q4 = -q2 - q3 (parallelogram): the frame variable is the combination
    m = arm6r()
    frames = list(m.frames)
    from dataclasses import replace
    frames[3] = replace(frames[3], coupling=((1, -1.0), (2, -1.0)))
    mc = m.replace(frames=tuple(frames))
    q = rc.random_configurations(m, 4, rng=2)
    qeq = q.copy()
    qeq[:, 3] = -q[:, 1] - q[:, 2]
    np.testing.assert_allclose(rc.forward_kinematics(mc, q).positions, rc.forward_kinematics(m, qeq).positions,
                               atol=1e-14)


def test_columns_in_blocks_of_poses_equal_those_in_one_block(monkeypatch):
    # the step columns are computed a block of poses at a time: blocks of 7 poses, the last one short
    import robocal._model.kinematics as kin

    m = arm6r(markers=(("a", (0.05, 0.02, 0.12)), ("b", (-0.1, 0.0, 0.05))))
    q = rc.random_configurations(m, 30, rng=2)
    whole = evaluate(m, q, jacobian=True, orientations=True).jacobian
    monkeypatch.setattr(kin, "COLUMN_BLOCK", 7)
    np.testing.assert_array_equal(evaluate(m, q, jacobian=True, orientations=True).jacobian, whole)


def test_forward_kinematics_in_chunks_allocates_its_outputs_and_little_more(monkeypatch):
    """Poses beyond LARGE_POSES are evaluated a chunk at a time: the chunks' results go straight
    into the outputs, so a call's memory is its outputs and one chunk's work (its pass in the
    model's workspace). Gathered and joined, the chunks' results took twice the outputs' memory,
    which the C heap took from the system and gave back at each call (fresh pages faulted in, or
    not, depending on what the process had done before: benchmarks/bench_fk_processes.py)."""
    import tracemalloc

    import robocal._model.kinematics as kin

    monkeypatch.setattr(kin, "LARGE_POSES", 1000)
    monkeypatch.setattr(kin, "CHUNK_POSES", 500)
    m = arm6r(markers=(("a", (0.05, 0.02, 0.12)), ("b", (-0.1, 0.0, 0.05))))
    q = rc.random_configurations(m, 16_001, rng=4)
    rc.forward_kinematics(m, q)                # the workspace's buffers made
    tracemalloc.start()
    ev = rc.forward_kinematics(m, q)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    outputs = ev.positions.nbytes + ev.rotations.nbytes
    assert peak < 1.3 * outputs, (peak, outputs)
    whole = evaluate(m, q[:900], orientations=True)
    np.testing.assert_array_equal(ev.positions[:900], whole.positions)
    np.testing.assert_array_equal(ev.rotations[:900], whole.rotations)


def test_readings_changed_in_place_are_not_taken_for_the_old_ones():
    # the cosines of the readings are remembered between passes, by value, not by the array
    m = arm6r()
    q = rc.random_configurations(m, 5, rng=3)
    first = evaluate(m, q).positions
    q[2, 1] += 0.3
    np.testing.assert_allclose(evaluate(m, q).positions, _reference_fk(m, q), atol=1e-12)
    assert np.abs(evaluate(m, q).positions - first).max() > 1e-3


@pytest.mark.parametrize("orientations", [False, True])
def test_an_evaluation_moved_by_the_base_and_markers_equals_a_new_one(orientations):
    """A fit of the base and markers alone evaluates the chain once and moves it: positions,
    orientations, the base's and markers' columns, and (moved when first asked for) every frame
    and column equal those of a new pass, also when moved twice and on two markers' frames."""
    from robots import torso

    import robocal._model.kinematics as K

    for m in (arm6r(), torso()):
        lay, p = K.layout(m), parameter_vector(m)
        qf = rc.random_configurations(m, 30, rng=1) @ m.coupling_matrix.T
        rng = np.random.default_rng(0)
        p2 = p.copy()
        p2[:6] += 0.05 * rng.standard_normal(6)
        for k in lay.marker0:
            p2[k:k + 6] += 0.01 * rng.standard_normal(6)
        p3 = p2.copy()
        p3[2] += 0.01
        assert K.moves_rigidly(lay, p, p2) and not K.moves_rigidly(lay, p, p2 + 1e-9)

        def new(v, m=m, lay=lay, qf=qf):
            return K.evaluate_state(m, lay, v, qf, compliance=False, orientations=orientations)

        moved = K.moved_state(K.moved_state(new(p), p2), p3)      # moved twice, the first never completed
        ref = new(p3)
        placed = np.setdiff1d(np.arange(lay.n_params), lay.chain_params)
        for mi in range(len(m.markers)):
            np.testing.assert_allclose(K.jacobian_columns(m, lay, moved, placed, mi),
                                       K.jacobian_columns(m, lay, ref, placed, mi), rtol=0, atol=1e-14)
        assert moved.ps.moved_from is not None                     # the chain's other frames not moved yet
        np.testing.assert_allclose(moved.ps.P, ref.ps.P, rtol=0, atol=1e-14)
        for a, b in zip(moved.ps.RM, ref.ps.RM):
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-14)
        everything = np.arange(lay.n_params)
        for mi in range(len(m.markers)):
            np.testing.assert_allclose(K.jacobian_columns(m, lay, moved, everything, mi),
                                       K.jacobian_columns(m, lay, ref, everything, mi), rtol=0, atol=1e-14)
        for name in ("R", "O", "U", "Q"):
            np.testing.assert_allclose(getattr(moved.ps, name), getattr(ref.ps, name), rtol=0, atol=1e-14)
