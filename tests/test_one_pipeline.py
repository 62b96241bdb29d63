"""One calibration for every kind of observation: the fixes made once in the one sequence of steps
hold for measured points and contacts alike, and the blocks' own properties (how each kind is held
out, what an observation's own unknowns are) are what differs between kinds."""

from __future__ import annotations

import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import robocal as rc
from robocal._identification.checks import outlier_check
from robocal._identification.contact_blocks import ContactRows
from robocal._identification.holdout import holdout_of
from robocal._identification.problem import Problem
from robocal.sim import socket_campaign

ARM7 = Path(__file__).resolve().parent.parent / "examples" / "arm7" / "model.yaml"
ENCODER = 2e-5


@pytest.fixture(scope="module")
def arm7():
    return rc.read_model(ARM7)


@pytest.fixture(scope="module")
def true_arm(arm7):
    return rc.perturb_model(arm7, rc.identifiability(arm7, parameters=("frames",)).identified, rng=11)


def test_a_kind_of_a_single_row_is_no_outlier_by_construction():
    """Its robust spread is zero; the scale is never below the stated deviation (docs/checks.md)."""
    check, out = outlier_check(np.array([[0.34e-5]]), np.array([1e-5]), rc.Noise.of("tracker"), ["P1: a-b"])
    assert check.status == "pass" and not out.any()
    # a row five stated deviations off is still named among many like it
    e = np.r_[np.full(20, 0.3e-5), 9e-5][:, None]
    _, out = outlier_check(e, np.full(21, 1e-5), rc.Noise.of("tracker"), [str(i) for i in range(21)])
    assert out[-1] and out.sum() == 1


def test_one_known_distance_beside_measured_points_is_no_outlier(arm7, true_arm):
    """The spacing of one placement is a kind of one row: fitted beside tracker points that fix the
    scale, it is a fraction of its stated deviation off, which is no outlier."""
    c = socket_campaign(true_arm, placements=1, poses_per_socket=12, joint_noise=ENCODER, rng=5)
    d = c.distances[0]
    off = type(d)(d.a, d.b, d.length + 0.3 * d.sigma, d.sigma)        # stated a third of its deviation off
    c = replace(c, distances=(off,))                                 # one known distance: one row
    data = rc.measure(true_arm, rc.random_configurations(arm7, 30, 2), rng=2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = rc.calibrate(arm7, data, contacts=c)
    checks = {ch.name: ch for ch in res.checks}
    assert checks["outliers among the distance contacts"].status == "pass"
    assert checks["fit of the distance contacts"].status != "fail"
    assert res.verdict != "fail", [(ch.name, ch.summary) for ch in res.checks if ch.status == "fail"]


def test_a_failing_calibration_from_contacts_warns_as_one_from_measured_points(arm7):
    """A calibration whose changes no real robot has fails, and says so as a warning, whatever it
    observed (the contact path emitted none)."""
    wrong = arm7.replace(frames=tuple(f if i != 2 else replace(f, d=f.d + 0.1) for i, f in enumerate(arm7.frames)))
    c = socket_campaign(wrong, placements=3, poses_per_socket=10, joint_noise=ENCODER, rng=4)
    with pytest.warns(rc.CheckWarning, match="FAILED"):
        res = rc.calibrate(arm7, contacts=c)
    assert res.verdict == "fail"
    q = rc.random_configurations(arm7, 40, 4)
    data = rc.measure(arm7, q, rng=4)
    q[7, 2] += 4 * np.pi                                  # a reading two turns beyond its limit
    with pytest.warns(rc.CheckWarning, match="FAILED"):
        assert rc.calibrate(arm7, replace(data, q=q)).verdict == "fail"


def test_rows_that_alone_fix_a_quantity_are_kept_linear_for_measured_points_too(arm7, true_arm):
    """A marker measured at one pose only: its three rows alone fix it. A robust loss keeps them
    linear and says that nothing else checks them, as it does for a contact kind's only rows."""
    last = len(arm7.frames) - 1
    two = arm7.replace(markers=arm7.markers + (rc.Marker("probe", last, (0.02, 0.03, 0.1)),))
    true2 = true_arm.replace(markers=true_arm.markers + (rc.Marker("probe", last, (0.021, 0.031, 0.1)),))
    q = rc.random_configurations(two, 40, 3)
    data = rc.measure(true2, q, rng=3)
    aside = np.zeros(data.mask.shape, dtype=bool)
    aside[1:, 1] = True                                    # the probe seen at the first pose only
    data = data.without(aside)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = rc.calibrate(two, data, loss="soft_l1")
    alone = next(ch for ch in res.checks if ch.name == "rows carried alone")
    assert alone.status == "warn" and any("marker probe" in i for i in alone.items)


# -- the blocks' own properties ---------------------------------------------------------------------

def test_a_contact_observations_own_errors_take_its_unknowns_from_its_own_rows(arm7, true_arm):
    c = socket_campaign(true_arm, placements=2, poses_per_socket=6, joint_noise=0.0, rng=1)
    rows = ContactRows.of(arm7, c, (), compliance=False)
    e = rows.own_errors(rc.parameter_vector(arm7))
    P = rc.forward_kinematics(arm7, c.q).positions[:, 0]
    for kind, label, idx in rows.obs_groups:
        if kind == "socket":
            g = next(g for g in c.groups("socket") if g.label == label)
            assert np.allclose(e[idx], P[g.rows] - P[g.rows].mean(axis=0), atol=1e-12)
    dist = [(label, idx) for kind, label, idx in rows.obs_groups if kind == "distance"]
    assert len(dist) == 2 * len(c.distances)                         # one per placement and pair
    label, idx = dist[0]
    placement, pair = label.split(": ")
    a, b = pair.split("-")
    ga, gb = (next(g for g in c.groups("socket") if g.placement == placement and g.target == t) for t in (a, b))
    length = next(d.length for d in c.distances if (d.a, d.b) == (a, b))
    expect = np.linalg.norm(P[ga.rows].mean(axis=0) - P[gb.rows].mean(axis=0)) - length
    assert e[idx[0], 0] == pytest.approx(expect, abs=1e-12)


def test_held_out_groups_are_folds_of_poses_and_placements(arm7, true_arm):
    c = socket_campaign(true_arm, placements=3, poses_per_socket=5, joint_noise=ENCODER, rng=2)
    data = rc.measure(true_arm, rc.random_configurations(arm7, 25, 5), rng=5)
    names = ("j2.theta", "j3.d")
    h = holdout_of(Problem(arm7, names, data=data, contacts=c, compliance=False), 5)
    obs = Problem(arm7, names, data=data, contacts=c, compliance=False).observations()
    assert h.point_folds == 5 and h.k == 5 + 3 and h.placements == c.placements()
    points, contacts = h.groups[:obs.n_points], h.groups[obs.n_points:]
    assert set(points) == set(range(5))
    for name, g in zip(c.placements(), range(5, 8)):
        assert set(np.array(obs.placement[obs.n_points:])[contacts == g]) == {name}
    one = socket_campaign(true_arm, placements=1, poses_per_socket=5, joint_noise=ENCODER, rng=2)
    assert holdout_of(Problem(arm7, names, contacts=one, compliance=False), 5).k == 0     # nothing to hold out


def test_observations_set_aside_keep_their_numbers(arm7, true_arm):
    c = socket_campaign(true_arm, placements=2, poses_per_socket=5, joint_noise=ENCODER, rng=3)
    data = rc.measure(true_arm, rc.random_configurations(arm7, 10, 6), rng=6)
    prob = Problem(arm7, ("j2.theta",), data=data, contacts=c, compliance=False)
    aside = np.zeros(len(prob.observations()), dtype=bool)
    aside[[2, 12]] = True                           # a measured point and a seating
    kept = prob.without(aside)
    assert kept.n_rows == prob.n_rows - 6
    numbers = np.unique(kept.row_observations())
    assert 2 not in numbers and 12 not in numbers and len(numbers) == len(aside) - 2
    assert kept.observations().label == prob.observations().label


def test_estimate_of_an_unknown_name_says_so(arm7, true_arm):
    data = rc.measure(true_arm, rc.random_configurations(arm7, 40, 7), rng=7)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = rc.calibrate(arm7, data)
    with pytest.raises(rc.InputError, match="nope"):
        res.estimate("nope")
