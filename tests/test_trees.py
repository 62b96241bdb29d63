"""Kinematic trees and coupled joints, and a base guessed metres away.

The robot is examples/torso/model.yaml: a two-frame trunk, a left arm that follows the trunk's
last frame (with a passive parallelogram frame driven by -l2 - l3) and a right arm that hangs off
the same trunk frame (Khalil-Kleinfinger gamma/b). Recovery is judged by z = (estimate - truth) /
reported std over the identified parameters.
"""


import numpy as np
import yaml
from conftest import z_scores
from robots import DEG, torso
from scipy.spatial.transform import Rotation

import robocal as rc

NOISE = 2e-5


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
    # r1 hangs off t2, not off its predecessor l4; both arms' first frames get gamma and b alike,
    # and t2's theta and r, which move both branches as their gamma and b do, come after them
    assert m.frames[6].parent == 1 != 6 - 1
    cand = rc.candidate_parameters(m)
    assert {"r1.gamma", "r1.b", "l1.gamma", "l1.b"} <= set(cand)
    assert cand.index("t2.theta") > cand.index("r1.b") and cand.index("t2.r") > cand.index("r1.b")
    absorbed = {e.name: dict(e.absorbers) for e in rc.identifiability(m, None).eliminated}
    assert set(absorbed["t2.theta"]) == {"l1.gamma", "r1.gamma"}
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
    assert result.solver.success and len(names) == 44
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



























# ------------------------------------------------------------------------------------------------
# 3. no base guess: the tracker 3 m away, turned 120 degrees about z and 10 about x

def test_far_base_converges_from_registration():
    m = torso()
    R_WB = Rotation.from_euler("zx", [120, 10], degrees=True).as_matrix()  # extrinsic: Rx(10) Rz(120)
    placed = m.replace(base_position=(2.0, -2.0, 1.0), base_rotation=tuple(map(tuple, R_WB)))
    true, data = rc.simulate(placed, 60, noise=NOISE, seed=5)
    nominal = m.replace(base_position=(0.0, 0.0, 0.0), base_rotation=((1.0, 0, 0), (0, 1.0, 0), (0, 0, 1.0)))
    result = rc.calibrate(nominal, data, initial_base="register")
    assert result.solver.success
    # "before" is the nominal geometry with its base registered too: the robot's own error, not the guess's
    assert result.stats.fit_before.mean < 0.01 and any("base and markers fitted" in n for n in result.notes)
    assert result.stats.fit_after.rms < 2.5 * NOISE * np.sqrt(3)
    # base rotation corrections are relative to the registered start (calibrate's reference)
    z = z_scores(result, true, rc.register_base(nominal, data))
    assert len(z) == 44 and np.abs(z).max() < 3.0, dict(zip(result.parameter_names, z.round(2)))
    angle = Rotation.from_matrix(np.asarray(result.calibrated_model.base_rotation).T
                                 @ np.asarray(true.base_rotation)).magnitude()
    assert angle < 1e-4


# ------------------------------------------------------------------------------------------------
# 4. a decimal-comma, semicolon file with a marker missing in some rows



# ------------------------------------------------------------------------------------------------
# 5. bad input not covered by test_files, test_cli and test_imports: tree keys, conventions, URDF files
