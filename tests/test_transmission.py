"""Transmission errors (docs/conventions.md): the chain at q_eff = q + B(q) t, every Jacobian column
against central finite differences (with compliance and backlash), the terms recovered from
simulated campaigns, and the family everywhere a family goes."""

from dataclasses import replace

import numpy as np
import pytest
from robots import arm6r, cylindrical
from test_backlash import _column_errors, _with_backlash
from test_kinematics import _assert_columns_match, _random_tree_model

import robocal as rc
from robocal.kinematics import evaluate, parameter_layout

DEG = np.pi / 180


def _with_transmission(model, rng, *, reduction=0.0, scale=1e-2):
    """``model`` with a gear-scale error and joint (and, with ``reduction``, motor) harmonics of
    0.01 to 0.05 deg on every revolute joint; a gear-scale error on every prismatic one."""
    frames = []
    for f in model.frames:
        if f.joint == "revolute":
            h = rng.uniform(0.01, 0.05, 8) * DEG * rng.choice([-1, 1], 8)
            f = replace(f, reduction=reduction, gear_scale=rng.uniform(-scale, scale), gear_cos1=h[0], gear_sin1=h[1],
                        gear_cos2=h[2], gear_sin2=h[3], **(dict(motor_cos1=h[4], motor_sin1=h[5], motor_cos2=h[6],
                                                                  motor_sin2=h[7]) if reduction else {}))
        elif f.joint == "prismatic":
            f = replace(f, gear_scale=rng.uniform(-scale, scale))
        frames.append(f)
    return model.replace(frames=tuple(frames))


def test_the_arm_reaches_the_transmitted_angle():
    """A one-joint arm: the marker turns by q (1 + s) + a cos q + b sin q + c cos(n q), by hand."""
    m = rc.serial_model("r", [dict(joint="revolute", gear_scale=0.02, gear_cos1=1e-3, gear_sin1=-2e-3, reduction=50.0,
                                   motor_cos1=3e-4)], markers=[("tool", (1.0, 0.0, 0.0))])
    q = np.array([[0.3], [-1.2], [2.0]])
    reached = q[:, 0] * 1.02 + 1e-3 * np.cos(q[:, 0]) - 2e-3 * np.sin(q[:, 0]) + 3e-4 * np.cos(50 * q[:, 0])
    P = rc.forward_kinematics(m, q).positions[:, 0]
    np.testing.assert_allclose(P[:, :2], np.column_stack([np.cos(reached), np.sin(reached)]), atol=1e-14)


@pytest.mark.parametrize("seed", [0, 1])
def test_every_column_matches_finite_differences_on_random_trees(seed):
    # coupled joints, prismatic ones (a gear scale only), compliance everywhere, motor harmonics
    rng = np.random.default_rng(seed)
    m = _with_transmission(_random_tree_model(seed), rng, reduction=7.5)
    q = rng.uniform(-1, 1, (6, 6))
    _assert_columns_match(m, q)


@pytest.mark.parametrize("make", [arm6r, cylindrical])
def test_columns_match_on_serial_arms_with_backlash(make):
    rng = np.random.default_rng(3)
    m = _with_transmission(_with_backlash(make(masses=True), rng, width=30.0), rng, reduction=31.0)
    assert not _column_errors(m, rc.random_configurations(m, 6, rng=1))


def test_columns_at_zero_terms_are_the_joint_columns_times_the_basis():
    """At a model without transmission terms a term's column is its joint's column times cos(k q)."""
    m = arm6r()
    q = rc.random_configurations(m, 5, rng=2)
    lay = parameter_layout(m)
    J = evaluate(m, q, jacobian=True, columns=lay.indices(["j2.theta", "j2.gear_cos2", "j2.gear_scale"])).jacobian
    np.testing.assert_allclose(J[..., 1], J[..., 0] * np.cos(2 * q[:, 1])[:, None, None], atol=1e-15)
    np.testing.assert_allclose(J[..., 2], J[..., 0] * q[:, 1][:, None, None], atol=1e-15)
