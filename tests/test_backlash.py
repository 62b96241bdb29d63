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


def test_model_file_keeps_backlash_and_its_side(tmp_path):
    m = _with_backlash(cylindrical(masses=True), np.random.default_rng(0), side="approach", width=0.5, friction=2.0)
    rc.write_model(m, tmp_path / "m.yaml")
    back = rc.read_model(tmp_path / "m.yaml")
    assert back.backlash_side == "approach"
    np.testing.assert_allclose(parameter_vector(back), parameter_vector(m), atol=1e-12)
    assert [f.backlash_width for f in back.frames] == [0.5] * 6
    assert [f.backlash_friction for f in back.frames] == [2.0] * 6
    text = (tmp_path / "m.yaml").read_text().replace("side: approach", "side: sideways")
    (tmp_path / "bad.yaml").write_text(text)
    with pytest.raises(rc.InputError, match="backlash.side"):
        rc.read_model(tmp_path / "bad.yaml")


def test_approach_columns_are_read_written_and_kept_by_a_split(tmp_path):
    m = cylindrical(masses=True)
    q = rc.random_configurations(m, 8, rng=0)
    data = rc.measure(m, q, rng=1)
    # written only where the row order does not give them
    rc.write_measurements(data, tmp_path / "order.csv", model=m)
    assert "approach_" not in (tmp_path / "order.csv").read_text()
    flipped = -data.extra["approach"]
    data2 = rc.Measurements(q=data.q, positions=data.positions, marker_names=data.marker_names,
                            joint_names=data.joint_names, extra={"approach": flipped})
    rc.write_measurements(data2, tmp_path / "a.csv", model=m)
    back = rc.read_measurements(tmp_path / "a.csv", m)
    np.testing.assert_array_equal(back.extra["approach"], flipped)
    fit, val = back.split(3, rng=0)
    both = np.vstack([fit.extra["approach"], val.extra["approach"]])
    assert sorted(map(tuple, both)) == sorted(map(tuple, flipped))
    text = (tmp_path / "a.csv").read_text().splitlines()
    text[1] = text[1][:-2] + "+2"
    (tmp_path / "bad.csv").write_text("\n".join(text) + "\n")
    with pytest.raises(rc.InputError, match="approach"):
        rc.read_measurements(tmp_path / "bad.csv", m)
