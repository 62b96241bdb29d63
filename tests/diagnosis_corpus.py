"""Simulated mistakes with a known cause, and clean or imperfect campaigns with none, for the
diagnosis (docs/diagnosis.md): each case is built from a seed on a 6R arm or a TH8-like
cylindrical arm with robocal's simulation, names the hypotheses one of which should come first,
and holds the true robot its calibrated model is held against.

Used by tests/test_diagnosis.py (a few seeds) and benchmarks/diagnosis_corpus.py (the whole corpus).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from robots import DEG, arm6r, cylindrical
from scipy.spatial.transform import Rotation

import robocal as rc

NOISE = 2e-5
N_POSES = 48
TWO_MARKERS = (("tool", (0.05, 0.02, 0.12)), ("tool2", (-0.06, 0.03, 0.1)))


@dataclass(frozen=True, eq=False)
class Case:
    """A campaign to calibrate (and diagnose, as ``calibrate`` does): the model given to the
    calibration, the data, the calibration's keyword arguments, the hypotheses one of which should
    come first (() for no cause), and the true robot when known."""

    name: str
    model: rc.RobotModel
    data: rc.Measurements
    expected: tuple[str, ...]
    options: dict = field(default_factory=dict)
    truth: rc.RobotModel | None = None

    def run(self):
        """(calibration result, its diagnosis)."""
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = rc.calibrate(self.model, self.data, **self.options)
            return result, result.diagnosis

    @property
    def q_eval(self):
        """Readings of use the calibrated model is held against the truth at."""
        return rc.sim.random_configurations(self.model, 200, np.random.default_rng(99))

    def model_error(self, result) -> float | None:
        """RMS distance (m) between where the calibrated model and the truth put the first marker."""
        if self.truth is None:
            return None
        q = self.q_eval
        a = rc.evaluate(result.calibrated_model, q).positions[:, 0]
        b = rc.evaluate(self.truth, q).positions[:, 0]
        return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1))))


ROBOTS = {"6r": arm6r, "cylindrical": cylindrical}


def _sim(robot, seed, n=N_POSES, **kw):
    m = ROBOTS[robot](masses=kw.pop("masses", False))
    if "markers" in kw:
        last = m.markers[0].frame
        m = m.replace(markers=tuple(rc.Marker(name, last, pos) for name, pos in kw.pop("markers")))
    true, data = rc.simulate(m, n, seed=seed, noise=NOISE, **kw)
    return m, true, data


def _measure(true, q, rng, **kw):
    return rc.sim.measure(true, q, noise=NOISE, rng=rng, **kw)


def _angle_joint(m, prefer=1):
    angles = [j for j, k in enumerate(m.reading_quantities) if k == "angle"]
    return angles[prefer] if prefer < len(angles) else angles[0]


# -- each mistake: (robot, seed) -> Case ------------------------------------------------------------

def missed_shot(robot, seed):
    m, true, d = _sim(robot, seed)
    pos = d.positions.copy()
    pos[20:-1] = d.positions[21:]            # the shot at row 20 was missed: every later row holds the next
    return Case("missed shot at row 20", m, replace(d, positions=pos), ("rows shifted",), truth=true)


def labels_offset(robot, seed):
    m, true, d = _sim(robot, seed)
    joined = replace(d.subset(np.arange(1, d.n_poses)), positions=d.positions[:-1], mask=d.mask[:-1])
    return Case("pose labels off by one in a join", m, joined, ("pose labels offset",), truth=true)


def left_handed(robot, seed):
    m, true, d = _sim(robot, seed)
    pos = d.positions.copy()
    pos[..., 1] *= -1
    return Case("left-handed tracker frame", m, replace(d, positions=pos), ("mirrored frame",), truth=true)


def axes_in_marker(robot, seed):
    m, true, d = _sim(robot, seed, markers=TWO_MARKERS)
    pos = d.positions.copy()
    pos[:, 1, [0, 1]] = pos[:, 1, [1, 0]]
    return Case("x and y swapped in one marker", m, replace(d, positions=pos), ("axes swapped",), truth=true)


def marker_copied(robot, seed):
    m, true, d = _sim(robot, seed, markers=TWO_MARKERS)
    pos = d.positions.copy()
    pos[:, 1] = pos[:, 0]
    return Case("one marker filled with another's values", m, replace(d, positions=pos), ("marker copied",),
                truth=true)


def _gear(robot, seed, ratio):
    m, true, d = _sim(robot, seed)
    j = _angle_joint(m)
    q_true = d.q.copy()
    q_true[:, j] *= ratio
    meas = _measure(true, q_true, np.random.default_rng(seed + 100))
    return Case(f"joint turns {ratio}x its reading", m, replace(meas, q=d.q), ("joint scale",), truth=true)


def gear_small(robot, seed):
    return _gear(robot, seed, 1.002)


def gear_large(robot, seed):
    return _gear(robot, seed, 1.02)


def joint_sign(robot, seed):
    m, true, d = _sim(robot, seed)
    q = d.q.copy()
    q[:, 4] *= -1                             # the wrist pitch
    return Case("one joint's sign flipped", m, replace(d, q=q), ("joint sign", "model values"), truth=true)


def joint_still(robot, seed):
    m = ROBOTS[robot]()
    rng = np.random.default_rng(seed)
    q = rc.sim.random_configurations(m, N_POSES, rng)
    q[:, 4] = 0.3
    true, d = rc.simulate(m, q=q, seed=seed, noise=NOISE)
    return Case("one joint never moves", m, d, ("joint still",), truth=true)


def sister_robot(robot, seed):
    m, true, d = _sim(robot, seed)
    _other, d2 = rc.simulate(m, q=d.q[24:], seed=seed + 1000, noise=NOISE)
    pos = np.concatenate([d.positions[:24], d2.positions])
    return Case("half the campaign from a sister robot", m, replace(d, positions=pos), ("step change",))


def joint_rehomed(robot, seed):
    m, true, d = _sim(robot, seed)
    j = _angle_joint(m)
    q = d.q.copy()
    q[N_POSES // 2:, j] += 0.1 * DEG          # rehomed halfway: from then on it reads 0.1 deg more
    return Case("a joint rehomed halfway (its zero moved 0.1 deg)", m, replace(d, q=q), ("joint rehomed",),
                truth=true)


def joint_drifting(robot, seed):
    m, true, d = _sim(robot, seed)
    j = _angle_joint(m)
    q = d.q.copy()
    q[:, j] += 0.1 * DEG * np.linspace(0.0, 1.0, d.n_poses)    # warming up: 0.1 deg more by the last row
    return Case("a joint's readings drifting 0.1 deg along the campaign", m, replace(d, q=q), ("drift",), truth=true)


def _lost(robot, seed, joint, *, masses=False, friction=()):
    """The arm with 0.05 deg of lost motion on ``joint`` the model leaves out: the campaign
    simulator's robot (``RobotImperfections``), not the model's backlash. ``friction`` () rests it
    behind its last move, zeros where its gravity load pushes it."""
    m, true, d = _sim(robot, seed, masses=masses)
    lost = np.zeros(m.n_joints)
    lost[joint] = 0.05 * DEG
    imp = rc.sim.RobotImperfections(encoder_resolution=(0.0,) * m.n_joints, repeatability_sigma=NOISE,
                                    instrument_noise_per_m=0.0, backlash=tuple(lost), backlash_friction=friction)
    return m, true, rc.sim.measure_campaign(true, d.q, imp, rng=seed)


def lost_motion(robot, seed):
    """The first angle joint with 0.05 deg of lost motion, each pose approached as the rows come."""
    m, true, data = _lost(robot, seed, _angle_joint(ROBOTS[robot](), 0))
    return Case("a joint with 0.05 deg of lost motion", m, data, ("lost motion",), truth=true)


def lost_motion_gravity(robot, seed):
    """The 6R arm's shoulder with 0.05 deg of lost motion, resting where its gravity load pushes it
    (the load turns over within the workspace); the cylindrical arm's loaded joints are slides whose
    load never turns over (a joint offset takes it up): no case."""
    if robot != "6r":
        return None
    m, true, data = _lost(robot, seed, 1, masses=True, friction=(0.0,) * 6)
    return Case("the shoulder with 0.05 deg of lost motion under gravity", m, data, ("lost motion",), truth=true)


def _compliances(robot):
    """The true compliances of the joints that bend under a payload, rad/(N m)."""
    return {"j2.k_theta": 5e-6, "j3.k_theta": 6e-6} if robot == "6r" else {"j2.k_alpha": 2e-6, "j3.k_alpha": 3e-6}


def payload_mid(robot, seed):
    m = ROBOTS[robot](masses=True)
    k = _compliances(robot)
    true, d = rc.simulate(m, N_POSES, seed=seed, noise=NOISE, parameters=("geometric",), true_compliance=k)
    load = np.where(np.arange(N_POSES) >= 24, 10.0, 0.0)
    meas = _measure(true, d.q, np.random.default_rng(seed + 100), payload_mass=load)
    return Case("10 kg payload put on mid-campaign", m, replace(meas, payload_mass=None), ("step change",),
                {"parameters": ("geometric", "compliance")}, truth=true)


def payload_grams(robot, seed):
    m = ROBOTS[robot](masses=True)
    k = _compliances(robot)
    rng = np.random.default_rng(seed)
    load = rng.choice([0.0, 5.0, 10.0], N_POSES)
    true, d = rc.simulate(m, N_POSES, seed=seed, noise=NOISE, parameters=("geometric",), true_compliance=k,
                          payload_mass=load)
    data = replace(d, payload_mass=load * 1000.0)
    return Case("payload column in grams", m, data, ("unit factor",), {"parameters": ("geometric", "compliance")},
                truth=true)


def _marker_moved(robot, seed, rows, offset):
    m, true, d = _sim(robot, seed)
    mk = true.markers[0]
    moved = true.replace(markers=(replace(mk, position=tuple(np.add(mk.position, offset))),))
    later = _measure(moved, d.q[rows], np.random.default_rng(seed + 100))
    pos = d.positions.copy()
    pos[rows] = later.positions
    return m, true, replace(d, positions=pos)


def reflector_moved(robot, seed):
    m, true, d = _marker_moved(robot, seed, np.arange(30, N_POSES), (1e-3, 0, 0))
    return Case("reflector moved 1 mm at row 30", m, d, ("marker moved",), truth=true)


def tool_changed(robot, seed):
    m, true, d = _marker_moved(robot, seed, np.arange(24, N_POSES), (0.03, -0.01, 0.02))
    return Case("the tool changed at row 24", m, d, ("marker moved",), truth=true)


def second_nest(robot, seed):
    rows = np.sort(np.random.default_rng(seed + 3).choice(N_POSES, N_POSES // 4, replace=False))
    m, true, d = _marker_moved(robot, seed, rows, (0.0, 0.008, 0.0))
    return Case("a reflector in a second nest on a quarter of the rows", m, d, ("marker moved",), truth=true)


def labels_swapped(robot, seed):
    m, true, d = _sim(robot, seed, markers=TWO_MARKERS)
    rows = np.sort(np.random.default_rng(seed + 4).choice(N_POSES, N_POSES // 3, replace=False))
    pos = d.positions.copy()
    pos[rows] = pos[rows][:, ::-1]
    return Case("marker labels swapped on a third of the rows", m, replace(d, positions=pos), ("labels swapped",),
                truth=true)


def tracker_bumped(robot, seed):
    m, true, d = _sim(robot, seed)
    R = Rotation.from_rotvec([0, 0, 0.01 * DEG]).as_matrix()
    pos = d.positions.copy()
    pos[24:] = pos[24:] @ R.T
    return Case("tracker bumped by 0.01 deg at row 24", m, replace(d, positions=pos), ("step change",), truth=true)


def thermal_drift(robot, seed):
    m, true, d = _sim(robot, seed)
    t = np.linspace(0.0, 1.0, d.n_poses)[:, None, None]
    pos = d.positions + t * np.array([0.3e-3, 0.0, 0.0]) / np.sqrt(1.0)
    return Case("slow thermal drift of 0.3 mm", m, replace(d, positions=pos), ("drift",), truth=true)


def rotations_inverted(robot, seed):
    m, true, d = _sim(robot, seed, orientation=True, noise_rot=1e-4)
    return Case("rotations given as their inverses", m, replace(d, rotations=np.swapaxes(d.rotations, -1, -2)),
                ("rotation convention",), truth=true)


def euler_convention(robot, seed):
    m, true, d = _sim(robot, seed, orientation=True, noise_rot=1e-4)
    flat = Rotation.from_matrix(d.rotations.reshape(-1, 3, 3))
    R = Rotation.from_euler("xyz", flat.as_euler("XYZ")).as_matrix().reshape(d.rotations.shape)
    return Case("Euler XYZ read as xyz", m, replace(d, rotations=R), ("rotation convention",), truth=true)


def quaternion_order(robot, seed):
    m, true, d = _sim(robot, seed, orientation=True, noise_rot=1e-4)
    quat = Rotation.from_matrix(d.rotations.reshape(-1, 3, 3)).as_quat()       # x, y, z, w
    R = Rotation.from_quat(np.roll(quat, 1, axis=1)).as_matrix().reshape(d.rotations.shape)   # w, x, y, z read
    return Case("quaternions (w, x, y, z) read as (x, y, z, w)", m, replace(d, rotations=R), ("rotation convention",),
                truth=true)


def _positions_scaled(robot, seed, f, name):
    m, true, d = _sim(robot, seed)
    return Case(name, m, replace(d, positions=d.positions * f), ("unit factor",), truth=true)


def metres_as_mm(robot, seed):
    return _positions_scaled(robot, seed, 1e-3, "metres declared as millimetres")


def mm_as_metres(robot, seed):
    return _positions_scaled(robot, seed, 1e3, "millimetres declared as metres")


def _joints_scaled(robot, seed, f, joints, name):
    m, true, d = _sim(robot, seed)
    q = d.q.copy()
    cols = [j for j, k in enumerate(m.reading_quantities) if k == joints] if isinstance(joints, str) else joints
    q[:, cols] *= f
    return Case(name, m, replace(d, q=q), ("unit factor",), truth=true)


def degrees_as_radians(robot, seed):
    return _joints_scaled(robot, seed, 180 / np.pi, "angle", "degrees declared as radians")


def radians_as_degrees(robot, seed):
    return _joints_scaled(robot, seed, np.pi / 180, "angle", "radians declared as degrees")


def one_joint_unit(robot, seed):
    return _joints_scaled(robot, seed, np.pi / 180, [3], "one joint's radians declared as degrees")


def prismatic_mm_as_m(robot, seed):
    if robot != "cylindrical":
        return None
    return _joints_scaled(robot, seed, 1e3, "length", "prismatic millimetres declared as metres")


def whole_turn(robot, seed):
    m, true, d = _sim(robot, seed)
    q = d.q.copy()
    q[:, 5] += 2 * np.pi                       # the last joint's turn count
    return Case("one joint a full turn off", m, replace(d, q=q), ("whole turns",), truth=true)


def targets(robot, seed):
    m, true, d = _sim(robot, seed)
    return Case("the nominal model's targets in place of the measurements", m,
                replace(d, positions=rc.evaluate(m, d.q).positions), ("nominal predictions",), truth=true)


def model_sign(robot, seed):
    m, true, d = _sim(robot, seed)
    if robot == "6r":
        wrong = m.replace(frames=tuple(replace(f, d=-f.d) if f.name == "j3" else f for f in m.frames))
    else:
        wrong = m.replace(frames=tuple(replace(f, alpha=-f.alpha) if f.name == "j5" else f for f in m.frames))
    return Case("a sign error in the model", wrong, d, ("model sign", "model values"), truth=true)


def link_off(robot, seed):
    m, true, d = _sim(robot, seed)
    frame = "j3" if robot == "6r" else "j4"
    field_ = "d" if robot == "6r" else "r"
    wrong = m.replace(frames=tuple(replace(f, **{field_: getattr(f, field_) + 0.1}) if f.name == frame else f
                                   for f in m.frames))
    return Case("a link 100 mm off in the model file", wrong, d, ("model values",), truth=true)


def model_in_metres(robot, seed):
    m, true, d = _sim(robot, seed)
    small = m.replace(frames=tuple(replace(f, d=f.d * 1e-3, r=f.r * 1e-3) for f in m.frames),
                      markers=tuple(replace(k, position=tuple(np.multiply(k.position, 1e-3))) for k in m.markers),
                      base_position=tuple(np.multiply(m.base_position, 1e-3)))
    return Case("the model's lengths in metres where millimetres were declared", small, d,
                ("model unit", "model values"), truth=true)


def markers_swapped(robot, seed):
    m, true, d = _sim(robot, seed, markers=TWO_MARKERS)
    return Case("two markers swapped", m, replace(d, positions=d.positions[:, ::-1].copy()), ("markers swapped",),
                {"known": ("markers",)}, truth=true)


def reading_typo(robot, seed):
    m, true, d = _sim(robot, seed)
    q = d.q.copy()
    q[5, 5] += 40 * DEG
    return Case("one reading mistyped", m, replace(d, q=q), ("blunders",), truth=true)


def joints_swapped(robot, seed):
    m, true, d = _sim(robot, seed)
    a, b = (1, 2) if robot == "6r" else (3, 4)
    q = d.q.copy()
    q[:, [a, b]] = q[:, [b, a]]
    return Case("two joint columns swapped", m, replace(d, q=q), ("joints swapped",), truth=true)


def marker_frame(robot, seed):
    m, true, d = _sim(robot, seed)
    wrong = m.replace(markers=(replace(m.markers[0], frame=m.markers[0].frame - 1),))
    return Case("the marker on the wrong frame in the model", wrong, d, ("marker frame",), truth=true)


def another_robot(robot, seed):
    m = ROBOTS[robot]()
    bigger = m.replace(frames=tuple(replace(f, d=f.d * 1.3, r=f.r * 1.3) for f in m.frames))
    true, d = rc.simulate(bigger, N_POSES, seed=seed, noise=NOISE)
    return Case("the file of a bigger robot", m, d, ("robot size", "model values"), truth=true)


def labels_cyclic(robot, seed):
    m, true, d = _sim(robot, seed)
    return Case("pose column shifted by one row", m, replace(d, q=np.roll(d.q, -1, axis=0)), ("pose labels offset",),
                truth=true)


def blunder(robot, seed):
    m, true, d = _sim(robot, seed)
    pos = d.positions.copy()
    pos[7, 0, 0] += 5e-3
    return Case("one value off by 5 mm", m, replace(d, positions=pos), ("blunders",), truth=true)


def path(m, n, seed):
    """Readings along a smooth path through the joint space (consecutive poses neighbours)."""
    rng = np.random.default_rng(seed)
    lo, hi = m.lower_limits, m.upper_limits
    t = np.linspace(0.0, 1.0, n)[:, None]
    phase = rng.uniform(0, 2 * np.pi, (1, m.n_joints))
    return lo + (hi - lo) * (0.5 + 0.4 * np.sin(2 * np.pi * (1.5 + rng.uniform(0, 1, (1, m.n_joints))) * t + phase))


def readings_lag(robot, seed):
    m = ROBOTS[robot]()
    q = path(m, 120, seed)
    true, d = rc.simulate(m, q=q, seed=seed, noise=NOISE)
    return Case("the joint log lags half a row along a path", m, replace(d, q=q - np.gradient(q, axis=0) / 2.0),
                ("readings lag",), truth=true)


MISTAKES = (missed_shot, labels_offset, left_handed, axes_in_marker, marker_copied, gear_small, gear_large, joint_sign,
            joint_still, joint_rehomed, joint_drifting, lost_motion, lost_motion_gravity, sister_robot, payload_mid,
            payload_grams, reflector_moved, tool_changed, second_nest, labels_swapped, tracker_bumped, thermal_drift,
            rotations_inverted, euler_convention, quaternion_order, metres_as_mm, mm_as_metres, degrees_as_radians,
            radians_as_degrees, one_joint_unit, prismatic_mm_as_m, whole_turn, targets, model_sign, link_off,
            model_in_metres, markers_swapped, reading_typo, joints_swapped, marker_frame, another_robot, labels_cyclic,
            blunder, readings_lag)


def mistakes(robot: str, seed: int):
    """Every mistake that applies to ``robot``, built from ``seed``."""
    return [c for c in (make(robot, seed) for make in MISTAKES) if c is not None]


# -- no cause: clean campaigns and robots with effects beyond the model ------------------------------

def clean(robot, seed):
    m, true, d = _sim(robot, seed, n=int(np.random.default_rng(seed).integers(30, 120)))
    return Case("clean", m, d, (), truth=true)


def gear_errors(robot, seed):
    """Each joint off its reading by a small periodic error of its gears (a few arc seconds)."""
    m, true, d = _sim(robot, seed)
    rng = np.random.default_rng(seed + 7)
    amp = rng.uniform(1, 3, m.n_joints) * 4.8e-6 * np.array([q == "angle" for q in m.reading_quantities])
    q_true = d.q + amp * np.sin(rng.integers(20, 80, m.n_joints) * d.q + rng.uniform(0, 2 * np.pi, m.n_joints))
    meas = _measure(true, q_true, rng)
    return Case("gear errors", m, replace(meas, q=d.q), ())


def pose_scatter(robot, seed):
    """The arm scatters about each pose by its repeatability (0.02 mm per axis), all markers alike."""
    m, true, d = _sim(robot, seed)
    rng = np.random.default_rng(seed + 8)
    return Case("per-pose scatter", m, replace(d, positions=d.positions + rng.normal(0, 2e-5, (d.n_poses, 1, 3))),
                ())


def elasticity(robot, seed):
    """Joints that bend under gravity, calibrated as rigid."""
    m = ROBOTS[robot](masses=True)
    k = {"j2.k_theta": 1e-6, "j3.k_theta": 1.5e-6} if robot == "6r" else {"j1.k_theta": 1e-6, "j4.k_theta": 1.5e-6}
    _, d = rc.simulate(m, N_POSES, seed=seed, noise=NOISE, true_compliance=k)
    return Case("link elasticity", m, d, ())


def slow_drift(robot, seed):
    """The instrument creeps by 0.02 mm over the campaign."""
    m, true, d = _sim(robot, seed)
    t = np.linspace(0.0, 1.0, d.n_poses)[:, None, None]
    return Case("slow drift", m, replace(d, positions=d.positions + t * np.array([0.0, 2e-5, 0.0])), ())


NO_CAUSE = (clean, gear_errors, pose_scatter, elasticity, slow_drift)
