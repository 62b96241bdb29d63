"""Backlash (lost motion): the forward kinematics at q + b s, every Jacobian column against
central finite differences under both side models, the simulator's lost motion recovered."""

from dataclasses import replace

import numpy as np
import pytest

import robocal as rc
from robocal.kinematics import evaluate, model_from_vector, parameter_layout, parameter_vector

from robots import arm6r, cylindrical
from test_kinematics import _random_tree_model
from scipy.spatial.transform import Rotation

ARCMIN = np.pi / 180 / 60


def _with_backlash(model, rng, *, side="gravity", width=1.0, friction=0.0):
    """``model`` with a backlash of 0.5 to 3 arcmin (0.02 to 0.05 mm on slides) on every joint."""
    frames = tuple(replace(f, backlash_theta=rng.uniform(0.5, 3) * ARCMIN / 2 if f.joint == "revolute" else 0.0,
                           backlash_r=rng.uniform(0.02, 0.05) * 1e-3 / 2 if f.joint == "prismatic" else 0.0,
                           backlash_width=width, backlash_friction=friction) for f in model.frames)
    return model.replace(frames=frames, backlash_side=side)


def _fd(model, q, p, approach, h):
    cols = []
    for k in range(len(p)):
        dp = np.zeros_like(p)
        dp[k] = h
        e1, e0 = (evaluate(model, q, p + s * dp, orientations=True, compliance=True, backlash=True, approach=approach)
                  for s in (1, -1))
        dpos = (e1.positions - e0.positions) / (2 * h)
        dR = e1.rotations @ np.swapaxes(e0.rotations, -1, -2)
        drot = Rotation.from_matrix(dR.reshape(-1, 3, 3)).as_rotvec().reshape(dpos.shape) / (2 * h)
        cols.append(np.concatenate([dpos, drot], axis=-1))
    return np.stack(cols, axis=-1)


def _column_errors(model, q, approach=None, h=1e-6):
    p = parameter_vector(model)
    J = evaluate(model, q, jacobian=True, compliance=True, backlash=True, approach=approach).jacobian
    F = _fd(model, q, p, approach, h)
    scale = np.maximum(np.abs(F).max(axis=(0, 1, 2)), 1e-3)   # relative per column, absolute near zero
    err = np.abs(J - F).max(axis=(0, 1, 2)) / scale
    names = parameter_layout(model).names
    return {names[k]: err[k] for k in np.nonzero(err > 1e-6)[0]}


@pytest.mark.parametrize("side, width, friction", [("gravity", 1e-3, 0.0), ("gravity", 20.0, 0.0),
                                                   ("gravity", 3.0, 2.0), ("approach", 1.0, 0.0)])
def test_every_column_matches_finite_differences_on_random_trees(side, width, friction):
    # width 1e-3: every load far from the transition; 20: every pose within it (the chain-rule
    # terms through the load matter); friction: the approach shifts the transition
    rng = np.random.default_rng(5)
    m = _with_backlash(_random_tree_model(4), rng, side=side, width=width, friction=friction)
    q = rng.uniform(-1, 1, (6, 6))
    approach = rng.choice([-1.0, 1.0], (6, 6))
    assert not _column_errors(m, q, approach)


@pytest.mark.parametrize("make", [arm6r, cylindrical])
def test_columns_match_on_serial_arms_near_the_transition(make):
    rng = np.random.default_rng(2)
    m = _with_backlash(make(masses=True), rng, width=30.0)
    q = rc.random_configurations(m, 6, rng=1)
    assert not _column_errors(m, q)
    lay = parameter_layout(m)
    p = parameter_vector(m)
    p[[prm.index for prm in lay.parameters if prm.family == "compliance"]] = 1e-5
    assert not _column_errors(model_from_vector(m, p), q)
