"""A measurement campaign on a simulated real robot, with the imperfections a real one has.

Where ``_simulate.measure`` adds isotropic noise to exact kinematics, this module simulates how a
campaign actually happens: the controller servoes each joint to an encoder count (the recorded
reading is that count, the true joint lies anywhere within its quantum), the arm scatters
around where it should be (its repeatability), and the instrument's noise grows with distance
(theodolites and trackers are specified in mm per metre), and, if asked, each joint's lost motion
(backlash) leaves the arm half of it away from its motor: on the side gravity pushes it to where
gravity's load on the joint beats the friction of its transmission, else behind the direction it
came from. It also simulates the robot in use:
a controller that stores its model rounded to its own quantum, commands targets through it,
and reaches them within encoder resolution and repeatability.
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
    is_a,
    marker_of,
    optional,
    readings_of,
)
from .._base.errors import InputError
from .._base.threads import one_blas_thread
from .._model.kinematics import evaluate, gravity_loads
from .._model.measurements import Measurements, approach_sides
from .._model.parameters import model_from_vector, parameter_vector
from .._model.robot import RobotModel


@dataclass(frozen=True)
class RobotImperfections:
    """How a real robot, its controller and the instrument depart from the ideal (SI).

    ``encoder_resolution`` (n_joints,) rad or m per count; ``repeatability_sigma`` standard
    deviation per axis of the attained position about its mean, m; ``instrument_noise_per_m``
    standard deviation per axis per metre of distance from ``instrument_position`` (in W);
    ``length_quantum``/``angle_quantum`` the round-off of the parameters stored in the controller;
    ``backlash`` (n_joints,) lost motion per joint, rad or m (empty: none). Encoders sit on the
    motors, so readings do not see it: the arm stops ``backlash / 2`` short of the reading, behind
    the direction of the last move of that joint. Poses are visited in the order given; the first
    is approached from the last (as in a cycle). ``backlash_friction`` (n_joints,) N m or N (empty:
    infinite): where the gravity load on a joint (``gravity_loads``) exceeds it, the arm rests on
    the side gravity pushes it to, whatever the approach (backlash under gravity, which a
    compliance term partly describes). An ISO 9283 test approaches each pose the same way every
    cycle, so backlash cannot show in its RP: it is an error the limit does not count.
    """

    encoder_resolution: tuple[float, ...]
    repeatability_sigma: float
    instrument_noise_per_m: float
    instrument_position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    length_quantum: float = 0.0
    angle_quantum: float = 0.0
    backlash: tuple[float, ...] = ()
    backlash_friction: tuple[float, ...] = ()

    def __post_init__(self):
        n = len(self.encoder_resolution)
        b = np.asarray(self.backlash, dtype=float)
        if len(b) and (len(b) != n or not np.all(np.isfinite(b)) or np.any(b < 0)):
            raise InputError("must be empty or one finite, non-negative value per joint", where="backlash")
        f = np.asarray(self.backlash_friction, dtype=float)
        if len(f) and (len(f) != n or np.any(np.isnan(f)) or np.any(f < 0)):
            raise InputError("must be empty or one non-negative value per joint", where="backlash_friction")
        if len(f) and not len(b):
            raise InputError("needs backlash", where="backlash_friction")

    def repeatability_rp(self) -> float:
        """ISO 9283 RP = l_mean + 3 S_l expected for isotropic Gaussian scatter of this sigma.

        The distance to the barycentre then follows a Maxwell law: mean 2 sqrt(2/pi) sigma,
        standard deviation sqrt(3 - 8/pi) sigma.
        """
        s = self.repeatability_sigma
        return float(2 * np.sqrt(2 / np.pi) * s + 3 * np.sqrt(3 - 8 / np.pi) * s)


def _quantise(q, res):
    res = np.asarray(res, dtype=float)
    safe = np.where(res > 0, res, 1.0)
    return np.where(res > 0, np.round(q / safe) * safe, q)


@accepts(true_model=is_a(RobotModel), recorded=readings_of("true_model"), imp=is_a(RobotImperfections),
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
    side = -approach_sides(recorded)
    if len(imp.backlash_friction):
        load = gravity_loads(true_model, recorded, payload_mass=payload_mass)
        held = np.abs(load) > np.asarray(imp.backlash_friction, dtype=float)
        side = np.where(held, np.sign(load), side)
    return side


def _attain(true_model: RobotModel, recorded, imp: RobotImperfections, rng, payload_mass=None):
    """Positions the arm reaches at recorded encoder counts, and what the instrument reads."""
    res = np.asarray(imp.encoder_resolution, dtype=float)
    actual = recorded + rng.uniform(-0.5, 0.5, recorded.shape) * res
    if len(imp.backlash):
        actual = actual + backlash_sides(true_model, recorded, imp, payload_mass) * (
            0.5 * np.asarray(imp.backlash, dtype=float))
    P = evaluate(true_model, actual, payload_mass=payload_mass).positions
    P = P + rng.normal(0.0, imp.repeatability_sigma, P.shape)
    dist = np.linalg.norm(P - np.asarray(imp.instrument_position), axis=-1, keepdims=True)
    return P + rng.normal(0.0, 1.0, P.shape) * imp.instrument_noise_per_m * dist


@accepts(true_model=is_a(RobotModel), q_commanded=readings_of("true_model"), imp=is_a(RobotImperfections), rng=SEED,
         payload_mass=optional(MASSES), labels=SEQUENCE)
@one_blas_thread
def measure_campaign(true_model: RobotModel, q_commanded, imp: RobotImperfections, *, rng=None,
                     payload_mass=None, labels=()) -> Measurements:
    """Measurements of a campaign at the commanded configurations: readings are encoder counts.

    Parameters
    ----------
    {true_model, q_commanded, imp, rng, payload_mass, labels}

    Returns
    -------
    Measurements
        What the instrument records, SI.
    """
    rng = np.random.default_rng(rng)
    recorded = _quantise(np.atleast_2d(np.asarray(q_commanded, dtype=float)), imp.encoder_resolution)
    P = _attain(true_model, recorded, imp, rng, payload_mass)
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
         targets_q=readings_of("nominal"), imp=is_a(RobotImperfections), rng=SEED, marker=marker_of("nominal"))
@one_blas_thread
def accuracy_in_use(true_model: RobotModel, controller_model: RobotModel | None, nominal: RobotModel, targets_q,
                    imp: RobotImperfections, *, rng=None, marker: int = 0) -> np.ndarray:
    """Distance (m) between each target and what the instrument sees the robot reach (ISO 9283 sense).

    Targets are the poses ``nominal`` reaches at ``targets_q`` (what an off-line program asks for).
    Without ``controller_model`` the controller commands the targets' readings as they are (an
    uncalibrated robot); with it, it stores that model rounded to its quanta and commands the
    compensated readings. Returns (n_targets,).

    Parameters
    ----------
    {true_model, controller_model}
    nominal : RobotModel
        The nominal model (gives the joint readings of the targets).
    {targets_q, imp, rng}
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
    recorded = _quantise(q, imp.encoder_resolution)
    P = _attain(true_model, recorded, imp, rng)[:, marker]
    return np.linalg.norm(P - target, axis=1)
