"""Identification recovers known parameters within the uncertainty it reports; identifiability
finds what theory predicts; degenerate data are refused with an explanation."""

import warnings

import numpy as np
import pytest

import robocal as rc
from robocal import select_poses

from robots import arm6r, cylindrical

NOISE = 2e-5


def _truth(true, nominal, result):
    p = rc.parameter_vector(true, nominal)
    names = rc.parameter_names(nominal)
    return np.array([p[names.index(e.name)] for e in result.parameters])


def _campaign(m, design, seed, n_val=300):
    q = np.vstack([design, rc.random_configurations(m, n_val, rng=1000 + seed)])
    true, data = rc.simulate(m, q=q, noise=NOISE, seed=seed)
    return true, data.subset(slice(0, len(design))), data.subset(slice(len(design), None))


def _noise_floor(true, val):
    """RMS error the true robot itself shows on the held-out measurements: the noise alone."""
    e = np.linalg.norm(rc.forward_kinematics(true, val.q).positions - val.positions, axis=2)
    return np.sqrt(np.mean(e ** 2))


@pytest.mark.parametrize("make", [arm6r, cylindrical])
def test_recovers_parameters_within_three_reported_std(make):
    m = make()
    design = select_poses(m, 48, rng=0).q
    true, fit, val = _campaign(m, design, 0)
    res = rc.calibrate(m, fit, validation=val)
    assert res.success
    z = (np.array([e.estimate for e in res.parameters]) - _truth(true, m, res)) / [e.std for e in res.parameters]
    assert np.all(np.abs(z) < 3), dict(zip(res.parameter_names, z.round(2)))
    assert res.stats.validation_before.rms > 20 * _noise_floor(true, val)


@pytest.mark.parametrize("make", [arm6r, cylindrical])
def test_held_out_error_ends_near_the_noise_floor(make):
    # 48 poses for ~25 parameters: the estimate's own error inflates the held-out RMS by about
    # sqrt(1 + tr(W M^-1)/3) (a few per cent with chosen poses); one campaign scatters around that,
    # so the bound is checked on the mean of ten campaigns sharing one pose plan
    m = make()
    design = select_poses(m, 48, rng=0).q
    ratios = []
    for seed in range(10):
        true, fit, val = _campaign(m, design, seed)
        res = rc.calibrate(m, fit, validation=val)
        ratios.append(res.stats.validation_after.rms / _noise_floor(true, val))
    assert np.mean(ratios) < 1.10, np.round(ratios, 3)
    assert min(ratios) > 1.0  # a calibrated model cannot beat the truth on fresh noise


@pytest.mark.parametrize("make", [arm6r, cylindrical])
def test_reported_std_is_honest_over_many_campaigns(make):
    # z-scores pooled over 20 independent campaigns have unit spread if the covariance is right
    m = make()
    z = []
    for seed in range(20):
        true, data = rc.simulate(m, 48, noise=NOISE, seed=seed)
        res = rc.calibrate(m, data)
        z.append((np.array([e.estimate for e in res.parameters]) - _truth(true, m, res)) / [e.std for e in res.parameters])
    z = np.concatenate(z)
    assert 0.85 < z.std() < 1.15
    assert abs(z.mean()) < 0.1
    assert np.mean(np.abs(z) > 3) < 0.01


@pytest.mark.parametrize("make", [arm6r, cylindrical])
def test_noise_free_data_recover_parameters_exactly(make):
    m = make()
    true, data = rc.simulate(m, 48, noise=0.0, seed=4)
    res = rc.calibrate(m, data)
    err = np.array([e.estimate for e in res.parameters]) - _truth(true, m, res)
    assert np.abs(err).max() < 1e-9


def test_errors_on_eliminated_parameters_are_absorbed_exactly():
    # the true robot has errors on every geometric parameter, even those that cannot be identified:
    # the identified set still reproduces it exactly (the dependencies are global, not first order)
    m = arm6r()
    names = rc.candidate_parameters(m, ("geometric",))
    true = rc.perturb_model(m, names, rng=5)
    data = rc.measure(true, rc.random_configurations(m, 60, rng=6), noise=0.0)
    res = rc.calibrate(m, data)
    assert res.stats.fit_after.max < 1e-10


def test_eliminated_parameters_are_those_theory_predicts():
    ident = rc.identifiability(arm6r())
    elim = {a.name: dict(a.absorbers) for a in ident.eliminated}
    # frame 1 is absorbed by the base (its transform precedes joint 1 or commutes with it)
    for k in ("beta", "alpha", "d", "theta", "r"):
        assert f"j1.{k}" in elim
    assert elim["j1.theta"] == pytest.approx({"base.rz": 1.0})
    assert elim["j1.r"] == pytest.approx({"base.z": 1.0})
    # joints 2 and 3 are parallel: r3 lies along r2; beta3 takes its place
    assert elim["j3.r"] == pytest.approx({"j2.r": 1.0})
    assert "j3.beta" in ident.identified
    # the point marker absorbs the last joint's offset along and about its axis
    assert "j6.r" in elim and "j6.theta" in elim
    assert len(ident.identified) == 27
    table = {row["frame"]: row for row in rc.status_table(ident, arm6r().frame_names)}
    assert table["j3"]["beta"] == "I" and table["j3"]["r"] == "E" and table["j2"]["beta"] == "-"


def test_cylindrical_eliminations():
    ident = rc.identifiability(cylindrical())
    elim = {a.name for a in ident.eliminated}
    # the vertical prismatic joint is parallel to the base joint: its r and theta offsets are the base's
    assert {"j2.r", "j2.theta"} <= elim
    # the wrist roll axis is parallel to the radial axis and on the same line
    assert {"j4.r", "j4.theta"} <= elim
    assert "j4.beta" in ident.identified and "j2.beta" in ident.identified


def test_held_fixed_base_makes_frame1_visible():
    ident = rc.identifiability(arm6r(), known=("base",))
    assert "j1.theta" in ident.identified and "j1.alpha" in ident.identified
    assert not any(n.startswith("base.") for n in ident.candidates)


def test_tolerance_is_stated_and_settable():
    m = arm6r()
    assert rc.identifiability(m).tol == 1e-6
    loose = rc.identifiability(m, tol=0.5)
    assert len(loose.identified) < 27 and loose.tol == 0.5
    assert loose.condition_number >= 1 and set(loose.observability) == {"O1", "O2", "O3", "O4", "O5"}


def test_too_few_poses_is_refused_with_the_count():
    m = arm6r()
    _, data = rc.simulate(m, 6, seed=1)
    with pytest.raises(rc.DegenerateDataError, match=r"6 poses .* 18 equations for 27"):
        rc.calibrate(m, data)


def test_repeated_poses_are_detected():
    m = arm6r()
    true, data = rc.simulate(m, 30, seed=1)
    q = np.vstack([data.q, data.q[:10]])
    rep = rc.measure(true, q, noise=NOISE, rng=2)
    res = rc.calibrate(m, rep)
    assert any("10 of 40 poses repeat" in n for n in res.notes)
    # the same nine poses over and over cannot stand in for distinct ones
    few = rc.measure(true, np.repeat(data.q[:9], 5, axis=0), noise=NOISE, rng=3)
    with pytest.raises(rc.DegenerateDataError, match="9 distinct"):
        rc.calibrate(m, few)


def test_rank_deficient_design_is_explained():
    # joint 5 never moves: the wrist parameters it would reveal cannot be separated
    m = arm6r()
    q = rc.random_configurations(m, 60, rng=3)
    q[:, 4] = 0.3
    true = rc.perturb_model(m, rc.identifiability(m).identified, rng=1)
    data = rc.measure(true, q, noise=NOISE, rng=4)
    with pytest.warns(rc.IdentifiabilityWarning, match="cannot separate"):
        res = rc.calibrate(m, data)
    check = next(c for c in res.checks if c.name == "identifiability at these poses")
    assert check.status == "warn" and "j5.alpha" in check.items and res.verdict != "pass"
    assert len(res.parameters) < 27


def test_robust_loss_resists_outliers():
    m = arm6r()
    true, data = rc.simulate(m, 80, noise=NOISE, seed=8)
    pos = data.positions.copy()
    pos[::10, 0] += 0.005  # 8 gross outliers of 5 mm
    bad = rc.Measurements(q=data.q, positions=pos, marker_names=data.marker_names)
    plain = rc.calibrate(m, bad, on_outliers="flag")
    robust = rc.calibrate(m, bad, loss="soft_l1")
    t = _truth(true, m, robust)
    err_plain = np.abs(np.array([e.estimate for e in plain.parameters]) - t).max()
    err_robust = np.abs(np.array([e.estimate for e in robust.parameters]) - t).max()
    assert err_robust < err_plain / 5
    # least squares names the outliers and fails; by default it refits with the robust loss itself
    outliers = next(c for c in plain.checks if c.name == "outliers")
    assert plain.verdict == "fail" and outliers.status == "fail"
    assert {item.split(",")[0] for item in outliers.items} == {data.labels[i] for i in range(0, 80, 10)}
    refit = rc.calibrate(m, bad)
    assert refit.loss == "soft_l1" and refit.verdict == "warn"
    np.testing.assert_allclose([e.estimate for e in refit.parameters], [e.estimate for e in robust.parameters])


def test_closed_form_registration_needs_no_base_guess():
    m = arm6r()
    true, data = rc.simulate(m, 48, noise=NOISE, seed=9)
    blind = m.replace(base_position=(0.0, 0.0, 0.0), base_rotation=((1.0, 0, 0), (0, 1.0, 0), (0, 0, 1.0)))
    res = rc.calibrate(blind, data, initial_base="register")
    assert res.success and res.stats.fit_after.rms < 2 * np.sqrt(3) * NOISE
    np.testing.assert_allclose(res.calibrated_model.base_position, true.base_position, atol=1e-4)


def test_non_convergence_is_reported():
    m = arm6r()
    _, data = rc.simulate(m, 48, seed=1)
    with pytest.warns(rc.ConvergenceWarning):
        res = rc.calibrate(m, data, max_nfev=1)
    assert not res.success and res.status == 0


def test_validation_without_data_keeps_fields_present():
    m = cylindrical()
    _, data = rc.simulate(m, 40, seed=2)
    res = rc.calibrate(m, data)
    assert res.validation_after is None and res.stats.validation_after.n == 0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        corr = res.correlation
    np.testing.assert_allclose(np.diag(corr), 1.0)


def test_pose_selection_improves_observability():
    sel = select_poses(arm6r(), 30, rng=1)
    assert sel.log_det_selected > sel.log_det_random
    assert sel.q.shape == (30, 6) and len(set(sel.indices)) == 30
