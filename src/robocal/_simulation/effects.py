"""What real robots do beyond the model: campaigns and use of a simulated robot with effects no
calibrated parameter takes up, against which the verdict and the accuracy in use are tested.

``_simulation.measure`` adds isotropic noise to exact kinematics, and ``_campaign`` adds a
controller's quanta, scatter and lost motion; a verdict tuned on those alone meets on real robots
effects its model does not have. This module adds them (``UnmodelledEffects``):

- elasticity beyond the compliance model: each joint deflects under its gravity load, progressively
  (the stiffness falls with the load, as a gear's does at small loads, and a cable's), and each link
  bends under the weight beyond it, moving the tool along gravity;
- gear errors: each joint turns by a periodic function of its own angle (eccentricity, the
  second harmonic of a gear pair), with phases of its own;
- slow thermal drift: the arm grows as it warms up, towards its working temperature with a time
  constant of a third of the campaign (lengths scale about the base);
- per-pose scatter: the robot's repeatability, a fresh Gaussian draw at every pose.

In use (``placement_errors``) the same robot goes to random configurations within its limits, at
thermal states spread over the campaign's, and the errors are those of a model's predictions
against where it goes (no instrument in between).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._base.arguments import (
    NON_NEGATIVE,
    SEED,
    SEQUENCE,
    accepts,
    both,
    is_a,
    marker_of,
    masses_for,
    readings_of,
    same_robot_as,
    shaped,
    whole,
)
from .._base.errors import InputError
from .._base.options import MAX_POSES
from .._model.configurations import random_configurations
from .._model.kinematics import evaluate, gravity_loads
from .._model.measurements import Measurements, approach_sides
from .._model.robot import RobotModel


@dataclass(frozen=True)
class UnmodelledEffects:
    """Effects of a real robot beyond the model, SI.

    ``elasticity`` rad per N m: a joint deflects by ``elasticity * load * (1 + |load| / load_scale)``
    under its gravity load (``load_scale`` N m); ``bending`` m per N m: the tool sinks along gravity
    by ``bending`` times the sum over the revolute joints of the absolute gravity load they carry;
    ``gear_error`` rad: each joint turns by ``gear_error * (sin(q + a) + 0.5 sin(2 q + b))``;
    ``drift``: the arm's relative growth once warm (``warm_up`` of it reached at a time t of the
    campaign, t in [0, 1]); ``scatter`` m: per-axis standard
    deviation of the attained position about its mean (repeatability).
    """

    elasticity: float = 0.0
    load_scale: float = 20.0
    bending: float = 0.0
    gear_error: float = 0.0
    drift: float = 0.0
    scatter: float = 0.0

    def __post_init__(self):
        for name in ("elasticity", "load_scale", "bending", "gear_error", "drift", "scatter"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and np.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be a finite, non-negative number, got {v!r}")


# a robot of the kind calibration meets: a gear-driven arm, a cable-driven one, one that warms
PRESETS = {
    "elastic": UnmodelledEffects(elasticity=4e-6, bending=2e-6, scatter=1e-5),
    "gears": UnmodelledEffects(gear_error=np.deg2rad(0.02), scatter=1e-5),
    "thermal": UnmodelledEffects(drift=5e-4, scatter=1e-5),
    "cable": UnmodelledEffects(elasticity=2e-5, gear_error=np.deg2rad(0.02), scatter=5.5e-4),
    "scatter": UnmodelledEffects(scatter=1e-4),
}


# the warm-up's time constant, as a share of the campaign's duration
WARM_UP_TIME = 1.0 / 3.0


def warm_up(t) -> np.ndarray:
    """The share of its growth the arm has at time ``t`` (in campaign durations) of a working day."""
    return 1.0 - np.exp(-np.asarray(t, dtype=float) / WARM_UP_TIME)


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


def _warmth(value, name, args):
    """(n_poses,) numbers in [0, 1]."""
    a = shaped(len(np.atleast_2d(np.asarray(args["q"], dtype=float))))(value, name, args)
    if np.any((a < 0) | (a > 1)):
        raise InputError("must be numbers in [0, 1] (0 cold, 1 warm)", where=name)


_REAL_ROBOT = dict(true_model=is_a(RobotModel), q=readings_of("true_model"), rng=SEED, robot_seed=whole(0),
                   payload_mass=masses_for())


@accepts(**_REAL_ROBOT, effects=is_a(UnmodelledEffects), warmth=_warmth)
def attained(true_model: RobotModel, q, effects: UnmodelledEffects, *, warmth, rng, robot_seed: int = 0,
             payload_mass=None) -> np.ndarray:
    """Where the real robot's markers go at readings ``q`` (n, n_markers, 3), W, m.

    ``warmth`` (n,) in [0, 1]: the thermal state at each pose (0 cold, 1 warm); ``rng`` draws the
    scatter; ``robot_seed`` fixes the robot's own gear phases.

    Parameters
    ----------
    {true_model, q}
    effects : UnmodelledEffects
        What the real robot does beyond the model.
    warmth : array_like, shape (n_poses,)
        Thermal state at each pose, in [0, 1] (0 cold, 1 warm).
    {rng}
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
    actual = q.copy()
    angle = _angles(true_model)
    if effects.gear_error:
        a, b = _phases(true_model, robot_seed)
        actual[:, angle] += effects.gear_error * (np.sin(q + a) + 0.5 * np.sin(2 * q + b))[:, angle]
    load = None
    if effects.elasticity or effects.bending:
        load = gravity_loads(true_model, q, payload_mass=payload_mass)
    if effects.elasticity:
        assert load is not None             # computed above whenever elasticity is on
        actual[:, angle] += (effects.elasticity * load * (1.0 + np.abs(load) / effects.load_scale))[:, angle]
    P = evaluate(true_model, actual, payload_mass=payload_mass).positions
    if effects.bending:
        g = np.asarray(true_model.gravity, dtype=float)
        down = g / max(float(np.linalg.norm(g)), 1e-12)
        assert load is not None             # computed above whenever bending is on
        sag = effects.bending * np.sum(np.abs(load[:, angle]), axis=1)
        P = P + sag[:, None, None] * down
    if effects.drift:
        origin = np.asarray(true_model.base_position, dtype=float)
        P = origin + (1.0 + effects.drift * np.asarray(warmth, dtype=float))[:, None, None] * (P - origin)
    if effects.scatter:
        P = P + rng.normal(0.0, effects.scatter, P.shape)
    return P


@accepts(**_REAL_ROBOT, effects=is_a(UnmodelledEffects), noise=NON_NEGATIVE, labels=SEQUENCE)
def measure_real(true_model: RobotModel, q, effects: UnmodelledEffects, *, noise: float = 2e-5, rng=None,
                 robot_seed: int = 0, payload_mass=None, labels=()) -> Measurements:
    """A campaign of the real robot at readings ``q``, visited in row order (the arm warming along
    it), measured by an instrument of per-axis ``noise`` (m).

    Parameters
    ----------
    {true_model, q}
    effects : UnmodelledEffects
        What the real robot does beyond the model.
    {noise, rng}
    robot_seed : int
        Fixes the robot's own gear phases (>= 0).
    {payload_mass, labels}

    Returns
    -------
    Measurements
        The simulated campaign, SI.
    """
    rng = np.random.default_rng(rng)
    q = np.atleast_2d(np.asarray(q, dtype=float))
    warmth = warm_up(np.linspace(0.0, 1.0, len(q)))
    P = attained(true_model, q, effects, warmth=warmth, rng=rng, robot_seed=robot_seed, payload_mass=payload_mass)
    P = P + rng.normal(0.0, noise, P.shape)
    return Measurements(q=q, positions=P, marker_names=true_model.marker_names, joint_names=true_model.joint_names,
                        payload_mass=payload_mass, labels=tuple(labels), source="simulated real robot",
                        extra={"approach": approach_sides(q)})


@accepts(true_model=is_a(RobotModel), model=both(is_a(RobotModel), same_robot_as("true_model")),
         effects=is_a(UnmodelledEffects), n=whole(1, MAX_POSES), rng=SEED, robot_seed=whole(0), marker=marker_of())
def placement_errors(true_model: RobotModel, model: RobotModel, effects: UnmodelledEffects, *, n: int = 300,
                     rng=None, robot_seed: int = 0, marker: int = 0) -> np.ndarray:
    """How far ``model``'s predictions are from where the real robot goes, at ``n`` random
    configurations within the limits, at random times of a working day as long as the campaign
    (the arm warming up as it did then): (n,) norms, m.

    Parameters
    ----------
    {true_model}
    model : RobotModel
        The model whose predictions are judged (the true robot's joints and markers).
    effects : UnmodelledEffects
        What the real robot does beyond the model.
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
    q = random_configurations(true_model, n, rng)
    real = attained(true_model, q, effects, warmth=warm_up(rng.uniform(0.0, 1.0, n)), rng=rng, robot_seed=robot_seed)
    predicted = evaluate(model, q).positions
    return np.linalg.norm(predicted[:, marker] - real[:, marker], axis=1)
