"""Simulation of a calibration campaign: a "true" robot, configurations and noisy measurements.

Every random function takes an explicit seed or ``numpy.random.Generator``.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.spatial.transform import Rotation

from .._base.arguments import (
    FLAG,
    MAPPING,
    MASSES,
    NAMES,
    NON_NEGATIVE,
    PAIR,
    SEED,
    SEQUENCE,
    accepts,
    is_a,
    names_in,
    optional,
    readings_of,
    whole,
)
from .._base.errors import InputError
from .._base.options import MAX_POSES
from .._base.threads import one_blas_thread
from .._identification.identifiability import identifiability
from .._model.configurations import random_configurations
from .._model.kinematics import evaluate
from .._model.measurements import Measurements, approach_sides
from .._model.parameters import model_from_vector, parameter_layout, parameter_names, parameter_vector
from .._model.robot import RobotModel


def _signed_uniform(rng, lo, hi, n):
    """Magnitudes uniform in [lo, hi] with random signs."""
    return rng.uniform(lo, hi, n) * rng.choice([-1.0, 1.0], n)


@accepts(model=is_a(RobotModel), names=names_in(lambda a: parameter_names(a["model"])), length_error=PAIR,
         angle_error=PAIR, compliance_error=optional(PAIR), rng=SEED)
def perturb_model(model: RobotModel, names, *, length_error=(1e-4, 1e-3), angle_error=(np.deg2rad(0.01),
                  np.deg2rad(0.1)), compliance_error=None, rng=None) -> RobotModel:
    """A copy of ``model`` with random errors on the parameters ``names``.

    Each error's magnitude is uniform in the (lo, hi) range of its kind (m, rad, rad/(N m)) with a
    random sign. Compliance parameters need ``compliance_error`` (else they are left alone); a
    compliance stays non-negative (a robot is not stiffer than rigid): a negative draw is mirrored,
    and so does a backlash (a lost motion is not negative), drawn in the length and angle ranges; a
    transmission's gear scale (a ratio) is drawn in the angle range, as radians per radian.

    Parameters
    ----------
    {model}
    names : sequence of str
        The parameters that get an error.
    {length_error, angle_error, compliance_error, rng}

    Returns
    -------
    RobotModel
        A copy of ``model`` with the errors.
    """
    rng = np.random.default_rng(rng)
    lay = parameter_layout(model)
    p = parameter_vector(model)
    # a gear scale error as a ratio: the angle range's magnitudes over a radian (0.01 deg: 1.7e-4)
    ranges = {"length": length_error, "angle": angle_error, "compliance": compliance_error, "ratio": angle_error}
    for n in names:
        bounds = ranges[lay[n].quantity]
        if bounds is None:
            continue
        lo, hi = bounds
        p[lay[n].index] += _signed_uniform(rng, lo, hi, 1)[0]
        if lay[n].quantity == "compliance" or lay[n].family == "backlash":
            p[lay[n].index] = abs(p[lay[n].index])
    # another robot than the model: never the model's own words (a nominal model's, say)
    return replace(model_from_vector(model, p), description=f"a simulated robot: the model {model.name} with "
                   f"random errors on {len(names)} of its parameters (perturb_model)")


@accepts(true_model=is_a(RobotModel), q=readings_of("true_model"), noise=NON_NEGATIVE,
         noise_rot=optional(NON_NEGATIVE), orientation=FLAG, payload_mass=optional(MASSES), rng=SEED, labels=SEQUENCE)
def measure(true_model: RobotModel, q, *, noise: float = 2e-5, noise_rot: float | None = None,
            orientation: bool = False, payload_mass=None, rng=None, labels=()) -> Measurements:
    """Measurements of ``true_model`` at readings ``q`` with isotropic Gaussian noise (std, metres).

    ``noise_rot`` (rad) perturbs measured orientations when ``orientation`` is set. The poses are
    visited in row order: a robot with backlash rests on the sides that order gives, and the
    measurements keep its approach directions (``extra["approach"]``).

    Parameters
    ----------
    {true_model}
    q : array_like, shape (n_poses, n_joints)
        Joint readings of the poses measured, rad or m.
    {noise, noise_rot}
    orientation : bool
        Whether to measure orientations too.
    {payload_mass, rng, labels}

    Returns
    -------
    Measurements
        The simulated measurements, SI.
    """
    rng = np.random.default_rng(rng)
    q = np.atleast_2d(np.asarray(q, dtype=float))
    ev = evaluate(true_model, q, orientations=orientation, payload_mass=payload_mass)
    pos = ev.positions + rng.normal(0.0, noise, ev.positions.shape)
    rot = None
    if orientation:
        n, m = ev.rotations.shape[:2]
        sr = noise_rot if noise_rot is not None else 0.0
        dR = Rotation.from_rotvec(rng.normal(0.0, sr, (n * m, 3))).as_matrix().reshape(n, m, 3, 3)
        rot = dR @ ev.rotations
    return Measurements(q=q, positions=pos, rotations=rot, marker_names=true_model.marker_names,
                        joint_names=true_model.joint_names, payload_mass=payload_mass, labels=tuple(labels),
                        source="simulated", extra={"approach": approach_sides(q)})


@accepts(model=is_a(RobotModel), n_poses=optional(whole(1, MAX_POSES)), q=optional(readings_of()), parameters=NAMES,
         known=NAMES, length_error=PAIR, angle_error=PAIR, compliance_error=optional(PAIR),
         true_compliance=optional(MAPPING), noise=NON_NEGATIVE, orientation=FLAG, noise_rot=optional(NON_NEGATIVE),
         payload_mass=optional(MASSES), seed=SEED)
@one_blas_thread
def simulate(model: RobotModel, n_poses: int | None = None, *, q=None, parameters=("geometric",), known=(),
             length_error=(1e-4, 1e-3), angle_error=(np.deg2rad(0.01), np.deg2rad(0.1)),
             compliance_error=None, true_compliance: dict | None = None, noise: float = 2e-5,
             orientation: bool = False, noise_rot: float | None = None, payload_mass=None,
             seed=0) -> tuple[RobotModel, Measurements]:
    """Draw a true robot near ``model`` and measure it at ``n_poses`` random configurations (or ``q``).

    Errors go on the parameters that are identifiable for this robot (theory, random poses) in
    the requested families, so the truth is unambiguous; ``true_compliance`` maps parameter names
    to exact true values (rad/(N m)) set after the random errors.
    Returns ``(true_model, measurements)``.

    Parameters
    ----------
    model : RobotModel
        The nominal robot.
    {n_poses, q, parameters, known, length_error, angle_error, compliance_error, true_compliance}
    noise : float
        Position noise of the instrument, m (one standard deviation per axis).
    orientation : bool
        Whether to measure orientations too.
    {noise_rot, payload_mass, seed}

    Returns
    -------
    (RobotModel, Measurements)
        The true robot and its measurements.
    """
    if q is None and n_poses is None:
        raise InputError("give n_poses or q", where="n_poses")
    rng = np.random.default_rng(seed)
    ident = identifiability(model, None, parameters=parameters, known=known, orientation=orientation, rng=rng)
    true = perturb_model(model, ident.identified, length_error=length_error, angle_error=angle_error,
                         compliance_error=compliance_error, rng=rng)
    if true_compliance:
        lay = parameter_layout(true)
        p = parameter_vector(true)
        for n, v in true_compliance.items():
            p[lay[n].index] = v
        true = model_from_vector(true, p)
    if q is None:
        q = random_configurations(model, n_poses, rng)
    data = measure(true, q, noise=noise, noise_rot=noise_rot, orientation=orientation,
                   payload_mass=payload_mass, rng=rng)
    return true, data
