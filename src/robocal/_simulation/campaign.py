"""A measurement campaign on a simulated real robot, and the robot in use.

Where ``simulate.measure`` adds isotropic noise to exact kinematics, this module simulates how a
campaign actually happens, with what a real robot, its controller and the instrument do that a model
may leave out (``RobotImperfections``, each effect off unless given):

- the controller servoes each joint to an encoder count: the recorded reading is that count, the
  true joint lies anywhere within its quantum; it stores its model rounded to its own quanta;
- lost motion (backlash): the encoders sit on the motors, so the arm rests half of it away from the
  reading: on the side gravity pushes it to where gravity's load on the joint beats the friction of
  its transmission, else behind the direction it came from;
- gear errors: each joint turns by a periodic function of its own angle (eccentricity, the second
  harmonic of a gear pair), with phases of its own;
- elasticity beyond the compliance model: each joint deflects under its gravity load, progressively
  (the stiffness falls with the load, as a gear's does at small loads, and a cable's), and each link
  bends under the weight beyond it, moving the tool along gravity;
- slow thermal drift: the arm grows as it warms up, towards its working temperature with a time
  constant of a third of the campaign (lengths scale about the base);
- the arm's repeatability: a fresh Gaussian scatter at every pose;
- the instrument's noise, a constant part and one that grows with distance (theodolites and trackers
  are specified in mm per metre).

In use, ``accuracy_in_use`` has the controller command targets through the model it stores and the
instrument see what the robot reaches (ISO 9283 sense); ``placement_errors`` compares a model's
predictions with where the robot goes at random configurations, at thermal states spread over the
campaign's (no instrument in between).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._accuracy.compensation import compensate
from .._accuracy.limit import rounded_parameters
from .._base.arguments import (
    MASSES,
    SEED,
    SEQUENCE,
    accepts,
    both,
    is_a,
    marker_of,
    masses_for,
    number,
    optional,
    readings_of,
    same_robot_as,
    shaped,
    whole,
)
from .._base.errors import InputError
from .._base.options import MAX_POSES
from .._base.threads import one_blas_thread
from .._model.configurations import random_configurations
from .._model.kinematics import evaluate, gravity_loads
from .._model.measurements import Measurements, approach_sides
from .._model.parameters import model_from_vector, parameter_vector
from .._model.robot import RobotModel


@dataclass(frozen=True, kw_only=True)
class RobotImperfections:
    """How a real robot, its controller and the instrument depart from the ideal model, SI; each
    effect is off unless given.

    The controller: ``encoder_resolution`` (n_joints,) rad or m per count (empty: the readings are
    where the joints are); ``length_quantum``/``angle_quantum`` the round-off of the parameters it
    stores.

    The arm: ``repeatability_sigma`` m, the per-axis standard deviation of the attained position
    about its mean, drawn afresh at every pose. ``backlash`` (n_joints,) lost motion per joint, rad
    or m (empty: none). Encoders sit on the motors, so readings do not see it: the arm stops
    ``backlash / 2`` short of the reading, behind the direction of the last move of that joint.
    Poses are visited in the order given; the first is approached from the last (as in a cycle).
    ``backlash_friction`` (n_joints,) N m or N (empty: infinite): where the gravity load on a joint
    (``gravity_loads``) exceeds it, the arm rests on the side gravity pushes it to, whatever the
    approach (backlash under gravity, which a compliance term partly describes). An ISO 9283 test
    approaches each pose the same way every cycle, so backlash cannot show in its RP: it is an error
    the limit does not count. ``gear_error`` rad: each revolute joint turns by
    ``gear_error * (sin(q + a) + 0.5 sin(2 q + b))``, with phases a, b of its own (drawn from the
    robot's seed). ``elasticity`` rad per N m: a revolute joint deflects by
    ``elasticity * load * (1 + |load| / load_scale)`` under its gravity load (``load_scale`` N m);
    ``bending`` m per N m: the tool sinks along gravity by ``bending`` times the sum over the
    revolute joints of the absolute gravity load they carry. ``drift``: the arm's relative growth
    once warm; lengths scale about the base by ``1 + drift * warmth``, and along a campaign
    ``warmth = 1 - exp(-3 t)``, t going from 0 at the first pose to 1 at the last.

    The instrument: the per-axis standard deviation of its noise is ``instrument_noise`` m plus
    ``instrument_noise_per_m`` per metre of distance from ``instrument_position`` (in W).
    """

    encoder_resolution: tuple[float, ...] = ()
    length_quantum: float = 0.0
    angle_quantum: float = 0.0
    repeatability_sigma: float = 0.0
    backlash: tuple[float, ...] = ()
    backlash_friction: tuple[float, ...] = ()
    gear_error: float = 0.0
    elasticity: float = 0.0
    load_scale: float = 20.0
    bending: float = 0.0
    drift: float = 0.0
    instrument_noise: float = 0.0
    instrument_noise_per_m: float = 0.0
    instrument_position: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self):
        for name in ("length_quantum", "angle_quantum", "repeatability_sigma", "gear_error", "elasticity", "bending",
                     "drift", "instrument_noise", "instrument_noise_per_m"):
            number(getattr(self, name), name, low=0.0)
        number(self.load_scale, "load_scale", low=0.0, low_open=True)
        shaped(3)(self.instrument_position, "instrument_position", {})
        e = np.asarray(self.encoder_resolution, dtype=float)
        if e.ndim != 1 or not np.all(np.isfinite(e)) or np.any(e < 0):
            raise InputError("must be empty or one finite, non-negative value per joint", where="encoder_resolution")
        b = np.asarray(self.backlash, dtype=float)
        n = len(e) or len(b)
        if len(b) and (len(b) != n or not np.all(np.isfinite(b)) or np.any(b < 0)):
            raise InputError("must be empty or one finite, non-negative value per joint", where="backlash")
        f = np.asarray(self.backlash_friction, dtype=float)
        if len(f) and (len(f) != n or np.any(np.isnan(f)) or np.any(f < 0)):
            raise InputError("must be empty or one non-negative value per joint", where="backlash_friction")
        if len(f) and not len(b):
            raise InputError("needs backlash", where="backlash_friction")


# a robot of the kind calibration meets, measured by a tracker of 20 um per axis: a gear-driven arm,
# a cable-driven one, one that warms
_TRACKER = 2e-5
PRESETS = {
    "elastic": RobotImperfections(elasticity=4e-6, bending=2e-6, repeatability_sigma=1e-5, instrument_noise=_TRACKER),
    "gears": RobotImperfections(gear_error=np.deg2rad(0.02), repeatability_sigma=1e-5, instrument_noise=_TRACKER),
    "thermal": RobotImperfections(drift=5e-4, repeatability_sigma=1e-5, instrument_noise=_TRACKER),
    "cable": RobotImperfections(elasticity=2e-5, gear_error=np.deg2rad(0.02), repeatability_sigma=5.5e-4,
                                instrument_noise=_TRACKER),
    "scatter": RobotImperfections(repeatability_sigma=1e-4, instrument_noise=_TRACKER),
}


# the warm-up's time constant, as a share of the campaign's duration
WARM_UP_TIME = 1.0 / 3.0


def warm_up(t) -> np.ndarray:
    """The share of its growth the arm has at time ``t`` (in campaign durations) of a working day."""
    return 1.0 - np.exp(-np.asarray(t, dtype=float) / WARM_UP_TIME)


def _quantise(q, res):
    if not len(res):
        return q
    res = np.asarray(res, dtype=float)
    safe = np.where(res > 0, res, 1.0)
    return np.where(res > 0, np.round(q / safe) * safe, q)


def _phases(model: RobotModel, seed: int) -> np.ndarray:
    """(2, n_joints) the fixed phases of each joint's gear error (a property of the robot)."""
    return np.random.default_rng(seed).uniform(0, 2 * np.pi, (2, model.n_joints))


def _angles(model: RobotModel) -> np.ndarray:
    """(n_joints,) whether each reading turns a revolute frame."""
    angle = np.zeros(model.n_joints, dtype=bool)
    for f in model.frames:
        for j, _ in f.coupling:
            angle[j] |= f.joint == "revolute"
    return angle


def _fits(model: str):
    """Imperfections whose per-joint values (if any) are one per joint of the model argument ``model``."""
    def rule(value, name, args):
        is_a(RobotImperfections)(value, name, args)
        n = args[model].n_joints
        for field in ("encoder_resolution", "backlash"):
            k = len(getattr(value, field))
            if k not in (0, n):
                raise InputError(f"{field} must have one value per joint of {model} ({n}), got {k}", where=name)
    return rule


def _warmth(value, name, args):
    """(n_poses,) numbers in [0, 1]."""
    a = shaped(len(np.atleast_2d(np.asarray(args["q"], dtype=float))))(value, name, args)
    if np.any((a < 0) | (a > 1)):
        raise InputError("must be numbers in [0, 1] (0 cold, 1 warm)", where=name)


def _sides(recorded, imp: RobotImperfections, load) -> np.ndarray:
    """``backlash_sides`` given the gravity loads (None without friction)."""
    side = -approach_sides(recorded)
    if len(imp.backlash_friction):
        held = np.abs(load) > np.asarray(imp.backlash_friction, dtype=float)
        side = np.where(held, np.sign(load), side)
    return side


@accepts(true_model=is_a(RobotModel), recorded=readings_of("true_model"), imp=_fits("true_model"),
         payload_mass=optional(MASSES))
def backlash_sides(true_model: RobotModel, recorded, imp: RobotImperfections, payload_mass=None) -> np.ndarray:
    """+1 or -1 per pose and joint: the side of its gap, relative to the reading, where the arm rests.

    Behind the last move (``-approach_sides``) unless gravity's load on the joint exceeds
    ``imp.backlash_friction``; then on the side the load pushes it to. Returns (n_poses, n_joints).

    Parameters
    ----------
    {true_model, recorded, imp}
    payload_mass : float or array_like of shape (n_poses,), optional
        Payload mass, kg.

    Returns
    -------
    numpy.ndarray, shape (n_poses, n_joints)
        The side (+1 or -1) each joint rests on.
    """
    load = gravity_loads(true_model, recorded, payload_mass=payload_mass) if len(imp.backlash_friction) else None
    return _sides(recorded, imp, load)


def _joints(true_model: RobotModel, q, imp: RobotImperfections, rng, robot_seed: int, payload_mass):
    """Where the joints are at readings ``q`` (within their encoder counts, lost motion, gear errors,
    deflection under gravity), and the gravity loads when an effect needs them (else None)."""
    if len(imp.encoder_resolution):
        actual = q + rng.uniform(-0.5, 0.5, q.shape) * np.asarray(imp.encoder_resolution, dtype=float)
    else:
        actual = q.copy()
    load = None
    if imp.elasticity or imp.bending or len(imp.backlash_friction):
        load = gravity_loads(true_model, q, payload_mass=payload_mass)
    if len(imp.backlash):
        actual = actual + _sides(q, imp, load) * (0.5 * np.asarray(imp.backlash, dtype=float))
    angle = _angles(true_model)
    if imp.gear_error:
        a, b = _phases(true_model, robot_seed)
        actual[:, angle] += imp.gear_error * (np.sin(q + a) + 0.5 * np.sin(2 * q + b))[:, angle]
    if imp.elasticity:
        assert load is not None             # computed above whenever elasticity is on
        actual[:, angle] += (imp.elasticity * load * (1.0 + np.abs(load) / imp.load_scale))[:, angle]
    return actual, load


_REAL_ROBOT = dict(true_model=is_a(RobotModel), q=readings_of("true_model"), imp=_fits("true_model"), rng=SEED,
                   robot_seed=whole(0), payload_mass=masses_for())


@accepts(**_REAL_ROBOT, warmth=optional(_warmth))
def attained(true_model: RobotModel, q, imp: RobotImperfections, *, rng=None, warmth=None, robot_seed: int = 0,
             payload_mass=None) -> np.ndarray:
    """Where the real robot's markers go at readings ``q``, visited in row order (no instrument in
    between): (n, n_markers, 3), W, m.

    Random draws, in this order: where each joint lies within its encoder count (when
    ``imp.encoder_resolution`` is given), the arm's scatter (when ``imp.repeatability_sigma`` is).

    Parameters
    ----------
    {true_model, q, imp, rng}
    warmth : array_like, shape (n_poses,), optional
        Thermal state at each pose, in [0, 1] (0 cold, 1 warm); None: warming up along the rows, as
        in a campaign.
    robot_seed : int
        Fixes the robot's own gear phases (>= 0).
    {payload_mass}

    Returns
    -------
    numpy.ndarray, shape (n_poses, n_markers, 3)
        The markers' positions in W, m.
    """
    rng = np.random.default_rng(rng)
    q = np.atleast_2d(np.asarray(q, dtype=float))
    actual, load = _joints(true_model, q, imp, rng, robot_seed, payload_mass)
    P = evaluate(true_model, actual, payload_mass=payload_mass).positions
    if imp.bending:
        assert load is not None             # computed with the joints whenever bending is on
        angle = _angles(true_model)
        g = np.asarray(true_model.gravity, dtype=float)
        down = g / max(float(np.linalg.norm(g)), 1e-12)
        P = P + (imp.bending * np.sum(np.abs(load[:, angle]), axis=1))[:, None, None] * down
    if imp.drift:
        w = warm_up(np.linspace(0.0, 1.0, len(q))) if warmth is None else np.asarray(warmth, dtype=float)
        origin = np.asarray(true_model.base_position, dtype=float)
        P = origin + (1.0 + imp.drift * w)[:, None, None] * (P - origin)
    if imp.repeatability_sigma:
        P = P + rng.normal(0.0, imp.repeatability_sigma, P.shape)
    return P


def _measured(true_model: RobotModel, q_commanded, imp: RobotImperfections, rng, robot_seed: int = 0,
              payload_mass=None):
    """The readings (encoder counts) at the commanded configurations and what the instrument reads."""
    recorded = _quantise(np.atleast_2d(np.asarray(q_commanded, dtype=float)), imp.encoder_resolution)
    P = attained(true_model, recorded, imp, rng=rng, robot_seed=robot_seed, payload_mass=payload_mass)
    z = rng.normal(0.0, 1.0, P.shape)
    dist = np.linalg.norm(P - np.asarray(imp.instrument_position), axis=-1, keepdims=True)
    # two products rather than one factor: each part alone gives the same numbers as drawn before
    return recorded, P + (z * imp.instrument_noise_per_m * dist + z * imp.instrument_noise)


@accepts(true_model=is_a(RobotModel), q_commanded=readings_of("true_model"), imp=_fits("true_model"), rng=SEED,
         robot_seed=whole(0), payload_mass=masses_for("q_commanded"), labels=SEQUENCE)
@one_blas_thread
def measure_campaign(true_model: RobotModel, q_commanded, imp: RobotImperfections, *, rng=None, robot_seed: int = 0,
                     payload_mass=None, labels=()) -> Measurements:
    """Measurements of a campaign at the commanded configurations, visited in row order (the arm
    warming along it): readings are encoder counts, positions what the instrument sees.

    Random draws, in this order: those of ``attained``, then the instrument's noise.

    Parameters
    ----------
    {true_model, q_commanded, imp, rng}
    robot_seed : int
        Fixes the robot's own gear phases (>= 0).
    {payload_mass, labels}

    Returns
    -------
    Measurements
        What the instrument records, SI.
    """
    rng = np.random.default_rng(rng)
    recorded, P = _measured(true_model, q_commanded, imp, rng, robot_seed, payload_mass)
    return Measurements(q=recorded, positions=P, marker_names=true_model.marker_names,
                        joint_names=true_model.joint_names, payload_mass=payload_mass, labels=tuple(labels),
                        source="simulated campaign", extra={"approach": approach_sides(recorded)})


@accepts(model=is_a(RobotModel), imp=is_a(RobotImperfections))
def stored_model(model: RobotModel, imp: RobotImperfections) -> RobotModel:
    """The model as the controller stores it: dimensions and angles rounded to its quanta.

    Parameters
    ----------
    {model, imp}

    Returns
    -------
    RobotModel
        The model as the controller stores it (rounded).
    """
    if imp.length_quantum <= 0 and imp.angle_quantum <= 0:
        return model
    rp = rounded_parameters(model, imp.length_quantum, imp.angle_quantum)
    p = parameter_vector(model)
    p[rp.params] = _quantise(p[rp.params], rp.quanta)
    return model_from_vector(model, p)


@accepts(true_model=is_a(RobotModel), controller_model=optional(is_a(RobotModel)), nominal=is_a(RobotModel),
         targets_q=readings_of("nominal"), imp=_fits("true_model"), rng=SEED, robot_seed=whole(0),
         marker=marker_of("nominal"))
@one_blas_thread
def accuracy_in_use(true_model: RobotModel, controller_model: RobotModel | None, nominal: RobotModel, targets_q,
                    imp: RobotImperfections, *, rng=None, robot_seed: int = 0, marker: int = 0) -> np.ndarray:
    """Distance (m) between each target and what the instrument sees the robot reach (ISO 9283 sense).

    Targets are the poses ``nominal`` reaches at ``targets_q`` (what an off-line program asks for),
    visited in turn as the poses of a campaign. Without ``controller_model`` the controller commands
    the targets' readings as they are (an uncalibrated robot); with it, it stores that model rounded
    to its quanta and commands the compensated readings. Returns (n_targets,).

    Parameters
    ----------
    {true_model, controller_model}
    nominal : RobotModel
        The nominal model (gives the joint readings of the targets).
    {targets_q, imp, rng}
    robot_seed : int
        Fixes the robot's own gear phases (>= 0).
    marker : int
        Index of the marker in the nominal model.

    Returns
    -------
    numpy.ndarray, shape (n_poses,)
        Position error at each target, m.
    """
    rng = np.random.default_rng(rng)
    q = np.atleast_2d(np.asarray(targets_q, dtype=float))
    ev = evaluate(nominal, q, orientations=True)
    target = ev.positions[:, marker]
    if controller_model is not None:
        # the targets as the instrument's frame holds them: the nominal base is part of them here
        q = compensate(stored_model(controller_model, imp), q, nominal=nominal, positions=target,
                       rotations=ev.rotations[:, marker] if nominal.n_joints >= 6 else None, marker=marker).q
    P = _measured(true_model, q, imp, rng, robot_seed)[1][:, marker]
    return np.linalg.norm(P - target, axis=1)


@accepts(true_model=is_a(RobotModel), model=both(is_a(RobotModel), same_robot_as("true_model")),
         imp=_fits("true_model"), n=whole(1, MAX_POSES), rng=SEED, robot_seed=whole(0), marker=marker_of())
def placement_errors(true_model: RobotModel, model: RobotModel, imp: RobotImperfections, *, n: int = 300,
                     rng=None, robot_seed: int = 0, marker: int = 0) -> np.ndarray:
    """How far ``model``'s predictions are from where the real robot goes, at ``n`` random
    configurations within the limits (read by its encoders), at random times of a working day as
    long as the campaign (the arm warming up as it did then): (n,) norms, m.

    Parameters
    ----------
    {true_model}
    model : RobotModel
        The model whose predictions are judged (the true robot's joints and markers).
    {imp}
    n : int
        Configurations drawn.
    {rng}
    robot_seed : int
        Fixes the robot's own gear phases (>= 0).
    {marker}

    Returns
    -------
    numpy.ndarray, shape (n,)
        The distances, m.
    """
    rng = np.random.default_rng(rng)
    q = _quantise(random_configurations(true_model, n, rng), imp.encoder_resolution)
    real = attained(true_model, q, imp, warmth=warm_up(rng.uniform(0.0, 1.0, n)), rng=rng, robot_seed=robot_seed)
    predicted = evaluate(model, q).positions
    return np.linalg.norm(predicted[:, marker] - real[:, marker], axis=1)
