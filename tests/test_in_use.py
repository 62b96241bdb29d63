"""The verdict answers "will this model place the robot better, and how well?" from evidence about use.

Judged on simulated robots with effects beyond the model (robocal.sim: elasticity, gear errors,
warm-up drift, a cable robot's 2 mm repeatability, per-pose scatter), against where the robot really
goes at 300 random poses; and on the cases users met (docs/checks.md).
"""

import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from robots import arm6r, cylindrical

import robocal as rc
from robocal.identification import Points, Problem, solve
from robocal.sim import PRESETS, RobotImperfections, measure_campaign, placement_errors, socket_campaign

NOISE = 2e-5
SEEDS = 50


def _real_campaign(robot, seed, *, n=150, noise=NOISE, m=None):
    """(nominal, true robot, campaign) of a 6R with ``robot``'s imperfections measured with ``noise``, from ``seed``."""
    m = arm6r(masses=True) if m is None else m
    true = rc.perturb_model(m, rc.identifiability(m).identified, rng=seed)
    q = rc.random_configurations(m, n, np.random.default_rng(seed + 1000))
    return m, true, measure_campaign(true, q, replace(robot, instrument_noise=noise), rng=seed + 2000, robot_seed=seed)


@pytest.mark.parametrize("kind", sorted(PRESETS))
def test_the_verdict_and_the_accuracy_in_use_hold_on_robots_beyond_the_model(kind):
    """Over 50 seeds: never a failure for a calibration that places the robot better than the nominal
    model at 300 random poses, and the predicted accuracy in use within 20 % of the true one in at
    least 90 % of them."""
    effects = PRESETS[kind]
    noise = 1e-4 if kind == "cable" else NOISE          # a cable robot is measured by a coarser tracker
    within, wrongly_failed = 0, []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for seed in range(SEEDS):
            m, true, data = _real_campaign(effects, seed, noise=noise)
            result = rc.calibrate(m, data, noise=rc.Noise.of(position=noise))
            after = placement_errors(true, result.calibrated_model, effects, rng=seed + 3000, robot_seed=seed)
            before = placement_errors(true, m, effects, rng=seed + 3000, robot_seed=seed)
            if result.verdict == "fail" and after.mean() < before.mean():
                wrongly_failed.append(seed)
            within += abs(result.in_use.position_after.mean / after.mean() - 1.0) <= 0.2
    assert not wrongly_failed
    assert within >= 0.9 * SEEDS, within


def test_cross_validation_by_one_step_equals_refitting_each_fold():
    m, true, data = _real_campaign(PRESETS["elastic"], 3, n=100)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = rc.calibrate(m, data, on_outliers="flag")
    names = result.parameter_names
    labels = np.arange(100) * 5 // 100
    refit = np.zeros(100)
    full = solve(Problem(m, names, data=data, compliance=False), rc.parameter_vector(m))
    for g in range(5):
        sol = solve(Problem(m, names, data=data.subset(labels != g), compliance=False), full.p)
        held = Problem(m, names, data=data.subset(labels == g), compliance=False)
        refit[labels == g] = held.points.error_norms(sol.p)[:, 0]
    # the engine of the figure tested against refits
    from robocal._identification.holdout import Holdout, cross_validate
    whole = Problem(m, names, data=data, compliance=False)
    holdout = Holdout(labels, 5, "5 folds of consecutive poses", labels, 5)
    one_step = cross_validate(whole, full.p, holdout).norms[:, 0]
    assert np.max(np.abs(one_step - refit)) < 1e-3 * refit.mean()


def _cv_rms(result) -> float:
    return result.in_use.position_after.rms


def test_a_limit_a_larger_noise_or_stated_deviations_never_cost_accuracy_in_use():
    """On the elastic robot, each remedy's cross-validated error is within its standard error of
    the calibration without it: they may hold parameters back only where that costs nothing."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for seed in range(5):
            m, true, data = _real_campaign(PRESETS["elastic"], 100 + seed)
            plain = rc.calibrate(m, data)
            se = plain.in_use.standard_error
            stated = replace(data, sigma=np.full(data.mask.shape, 1.5e-5 + 6e-6 * np.linalg.norm(
                data.positions, axis=2)))
            for remedy in (dict(limit=1e-3), dict(noise=rc.Noise.of(position=2e-4)), dict(data=stated)):
                given = rc.calibrate(m, remedy.pop("data", data), **remedy)
                assert given.in_use.position_after.mean <= plain.in_use.position_after.mean + se, (seed, remedy)


def _angle_turned(model, q, positions):
    """The angle the one-joint ``model``'s marker turned by from where ``q`` puts it (its axis through the base)."""
    exact = rc.forward_kinematics(model, q).positions[:, 0]
    axis = np.cross(exact[0], exact[1])
    axis /= np.linalg.norm(axis)
    got = positions[:, 0]
    return np.arctan2(np.cross(exact, got) @ axis, np.sum(exact * got, axis=1))


def test_the_real_robots_effects_move_the_marker_by_what_they_say():
    """One campaign simulator for every effect: a gear error of the stated amplitude with its two
    harmonics, lost motion on top of it, a joint deflecting under its load, the arm growing as it
    warms up, the instrument's noise of both kinds; each against the figures worked out by hand."""
    q = np.linspace(-3.0, 3.0, 61)[:, None]
    # a vertical axis carries no load: the marker, 1 m out, turns by the gear error alone
    flat = rc.serial_model("v", [dict()], markers=[("t", (1.0, 0.0, 0.0))])
    g = 3e-3
    gears = rc.sim.measure_campaign(flat, q, RobotImperfections(gear_error=g), rng=0, robot_seed=4).positions
    error = _angle_turned(flat, q, gears)
    # g (sin(q + a) + 0.5 sin(2 q + b)) = g (cos a sin q + sin a cos q + 0.5 cos b sin 2q + 0.5 sin b cos 2q)
    basis = g * np.column_stack([np.sin(q), np.cos(q), 0.5 * np.sin(2 * q), 0.5 * np.cos(2 * q)])
    c, *_ = np.linalg.lstsq(basis, error, rcond=None)
    assert np.max(np.abs(basis @ c - error)) < 1e-12
    assert np.hypot(c[0], c[1]) == pytest.approx(1.0, abs=1e-9) and np.hypot(c[2], c[3]) == pytest.approx(1.0, abs=1e-9)
    other = rc.sim.measure_campaign(flat, q, RobotImperfections(gear_error=g), rng=0, robot_seed=5).positions
    assert np.max(np.abs(_angle_turned(flat, q, other) - error)) > g / 10     # phases of another robot
    # lost motion adds half of it behind each move, on the same gear error, readings untouched
    both = rc.sim.measure_campaign(flat, q, RobotImperfections(gear_error=g, backlash=(2e-3,)), rng=0, robot_seed=4)
    np.testing.assert_allclose(_angle_turned(flat, q, both.positions) - error,
                               -rc.sim.approach_sides(q)[:, 0] * 1e-3, atol=1e-12)
    np.testing.assert_array_equal(both.q, q)
    # a horizontal axis, 2 kg at 0.5 m: the load is 9.81 cos(q) N m, the deflection k L (1 + |L| / s)
    c, s = np.cos(-np.pi / 2), np.sin(-np.pi / 2)
    arm = rc.serial_model("h", [dict(joint="revolute", mass=2.0, com=(0.5, 0.0, 0.0))],
                          markers=[("t", (1.0, 0.0, 0.0))], base_rotation=[[1, 0, 0], [0, c, -s], [0, s, c]])
    k, scale = 1e-4, 20.0
    bent = rc.sim.measure_campaign(arm, q, RobotImperfections(elasticity=k, load_scale=scale), rng=0).positions
    load = 9.81 * np.cos(q[:, 0])
    np.testing.assert_allclose(_angle_turned(arm, q, bent), k * load * (1 + np.abs(load) / scale), atol=1e-12)
    assert bent[30, 0, 2] < -0.9 * k * 9.81           # at q = 0 the arm is horizontal and sinks
    # warming up: the marker's distance from the base grows to 1 + drift (1 - exp(-3)) by the last pose
    warm = rc.sim.measure_campaign(flat, q, RobotImperfections(drift=1e-3), rng=0).positions
    t = np.linspace(0.0, 1.0, len(q))
    np.testing.assert_allclose(np.linalg.norm(warm[:, 0], axis=1), 1 + 1e-3 * (1 - np.exp(-3 * t)), rtol=0,
                               atol=1e-12)
    # the instrument's noise per axis: 20 um plus 30 um per metre of its distance (2 to 3 m)
    many = np.tile(q, (100, 1))
    seen = RobotImperfections(instrument_noise=2e-5, instrument_noise_per_m=3e-5, instrument_position=(-2.0, 0, 0))
    noisy = rc.sim.measure_campaign(flat, many, seen, rng=1).positions - rc.forward_kinematics(flat, many).positions
    far = np.linalg.norm(rc.forward_kinematics(flat, many).positions[:, 0] - (-2.0, 0, 0), axis=1)
    ratio = noisy[:, 0] / (2e-5 + 3e-5 * far)[:, None]
    assert np.std(ratio) == pytest.approx(1.0, abs=0.03) and abs(np.mean(ratio)) < 0.03


# -- the cases users met ------------------------------------------------------------------------------

def test_an_elastic_robot_with_millimetres_left_is_not_failed():
    """A humanoid-like elastic arm measured by motion capture leaves millimetres: better in use, and
    held-out poses show the same scatter: the robot's own, said, not failed (the fit's size alone
    never fails)."""
    robot = RobotImperfections(elasticity=6e-5, bending=2e-5, repeatability_sigma=3e-4)
    m, true, data = _real_campaign(robot, 7, n=300, noise=1e-4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = rc.calibrate(m, data, noise="camera")
    fit = next(c for c in result.checks if c.name == "fit against the instrument")
    assert result.stats.fit_after.rms > 1e-3 and fit.status == "pass" and "the robot's own scatter" in fit.summary
    assert result.verdict != "fail" and result.in_use.position_after.mean < result.in_use.position_before.mean


def test_a_validation_campaign_of_another_set_up_fails_unless_registered_on():
    m, true, data = _real_campaign(PRESETS["gears"], 4)
    moved = true.replace(base_position=tuple(np.add(true.base_position, (3.0, -1.0, 0.5))))
    other = rc.measure(moved, rc.random_configurations(m, 40, np.random.default_rng(8)), noise=NOISE, rng=9)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        naive = rc.calibrate(m, data, validation=other)
        registered = rc.calibrate(m, data, validation=other, register_validation=True)
    use = next(c for c in naive.checks if c.name == "accuracy in use")
    assert naive.verdict == "fail" and use.status == "fail" and "another set-up" in use.cause
    assert registered.verdict != "fail" and registered.in_use.position_after.mean < 1e-3
    assert "registered" in registered.in_use.method


def test_a_validation_set_with_a_joint_homed_otherwise_names_the_joint(tmp_path):
    """The published UR5 grid fitted, its 20 test poses with the elbow's readings 0.3 deg off (homed
    otherwise between the campaigns): 8fee3fe failed it as "another set-up or another robot, or a
    mistake" and registering base and tool leaves 0.75 mm of 2.75. Now the elbow and its
    offset are named (0.099 mm once taken off); the figures are kept in result.json. A base moved
    instead stays another set-up (the test above)."""
    real = pytest.importorskip("real_campaigns")
    model = real.nominal("UR5")
    grid, test = real.campaign("UR5", "grid", model), real.campaign("UR5", "random", model)
    q = test.q.copy()
    q[:, 2] += np.radians(0.3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = rc.calibrate(model, grid, validation=replace(test, q=q))
    use = next(c for c in result.checks if c.name == "accuracy in use")
    homed = result.in_use.rehomed
    assert use.status == "fail" and "joint elbow homed otherwise" in use.cause and "home joint elbow" in use.fix
    assert homed.joint == "elbow" and abs(np.degrees(homed.offset) - 0.3) < 0.02 and homed.errors.mean < 0.11e-3
    assert result.in_use.registered_after.mean > 0.7e-3
    rc.write_result(result, tmp_path / "result.json")
    again = rc.read_result(tmp_path / "result.json").in_use.rehomed
    assert again.joint == "elbow" and again.offset == homed.offset and again.errors.mean == homed.errors.mean


def test_a_prismatic_joint_homed_otherwise_is_named_in_millimetres_and_a_vertical_one_is_a_set_up():
    """The cylindrical arm's radial axis read 3 mm off on the validation set: named with its offset in
    mm; its vertical axis read 2 mm off is a base moved up (the registration explains it first)."""
    m = cylindrical()
    true, data = rc.simulate(m, 60, seed=3)
    val = rc.measure(true, rc.random_configurations(m, 30, rng=5), noise=2e-5, rng=6)
    found = {}
    for j, off in ((2, 3e-3), (1, 2e-3)):
        q = val.q.copy()
        q[:, j] += off
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = rc.calibrate(m, data, validation=replace(val, q=q))
        found[j] = next(c for c in result.checks if c.name == "accuracy in use"), result.in_use.rehomed
    (radial, homed), (vertical, _) = found[2], found[1]
    assert "joint j3 homed otherwise" in radial.cause and "j3's readings +3.0" in radial.summary
    assert homed.quantity == "length" and abs(homed.offset - 3e-3) < 0.05e-3
    assert "another set-up" in vertical.cause and "homed" not in vertical.cause


def test_worse_in_use_fails():
    """Held-out poses the calibration places worse than the nominal model: a failure, whatever the fit."""
    from robocal._identification.checks import in_use_check  # the check on its own, with figures made to order
    from robocal._identification.holdout import HeldOut, accuracy_in_use
    rng = np.random.default_rng(0)
    before = rng.normal(scale=1e-4, size=(60, 1, 3))
    after = before * 3.0
    held = [HeldOut(v, None, np.sum(v ** 2, axis=2)) for v in (before, after)]
    check = in_use_check(accuracy_in_use("validation", None, "set", *held, np.full(60, 1e-4)))
    assert check.status == "fail" and "worse than before" in check.summary


def test_a_robot_that_is_its_nominal_model_is_not_failed_as_worse_in_use():
    """A robot exactly as its nominal model, measured by a tracker and on a socket plate: the
    calibration has nothing to correct, and its held-out errors are worse than the nominal's by what
    the stated noise costs its estimates (6 um of 20 from 60 tracker poses, 0.6 um of 21 on the
    plate), beyond the paired bar: "worse than before calibration" failed both. Now a warning that
    says so, by one rule for both. Calibrated on another robot of the model (errors of a tenth of a
    millimetre) and held out on this one, it is worse beyond that cost: a failure, from both."""
    m = rc.read_model(Path(__file__).resolve().parents[1] / "examples" / "arm7" / "model.yaml")
    small = dict(length_error=(2e-5, 1e-4), angle_error=(np.radians(0.001), np.radians(0.01)))
    other = rc.perturb_model(m, rc.identifiability(m).identified, rng=1, **small)
    tracker = rc.measure(m, rc.random_configurations(m, 60, 0), noise=NOISE, rng=0)
    plate = socket_campaign(m, placements=3, poses_per_socket=20, joint_noise=2e-5, rng=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        nominal = [rc.calibrate(m, tracker), rc.calibrate(m, contacts=plate)]
        elsewhere = [rc.calibrate(m, rc.measure(other, rc.random_configurations(m, 60, 1), noise=NOISE, rng=1),
                                  validation=tracker),
                     rc.calibrate(m, contacts=socket_campaign(other, placements=3, poses_per_socket=20,
                                                              joint_noise=2e-5, rng=1), validation=plate)]
    for result in nominal:
        use = next(c for c in result.checks if c.name == "accuracy in use")
        gain, se = result.in_use.improvement
        assert gain < -2.1 * se, (gain, se)        # worse beyond the paired bar: the case at hand
        assert use.status == "warn" and "nothing these data show needs correcting" in use.summary, use.summary
        assert result.verdict == "warn", [c.summary for c in result.checks if c.status != "pass"]
    for result in elsewhere:
        use = next(c for c in result.checks if c.name == "accuracy in use")
        assert use.status == "fail" and use.summary.endswith("worse than before calibration"), use.summary
        assert result.in_use.position_after.mean > result.in_use.position_before.mean + 30e-6


def test_worse_than_before_takes_students_bar_on_few_points():
    """Held-out errors 3 standard errors of the paired difference worse after calibration: a failure
    on 60 points (the bar 2.04), a warning on 3 (the bar 4.5: three points' spread says little of
    the standard error), and nothing established on one."""
    from robocal._identification.checks import in_use_check, paired_sigmas
    from robocal._identification.holdout import HeldOut, accuracy_in_use
    assert paired_sigmas(60) == pytest.approx(2.04, abs=0.01) and paired_sigmas(3) == pytest.approx(4.53, abs=0.01)
    for n, status in ((60, "fail"), (3, "warn"), (1, "warn")):
        rng = np.random.default_rng(n)
        before = rng.normal(scale=1e-3, size=(n, 1, 3))
        d = rng.normal(size=n)
        d = (d - d.mean()) / (d.std(ddof=1) if n > 1 else 1.0) * 1e-5 + (3 * 1e-5 / np.sqrt(n))
        norms = np.linalg.norm(before, axis=2)[:, 0]
        after = before * ((norms + d) / norms)[:, None, None]       # each error d longer: 3 se worse
        held = [HeldOut(v, None, np.sum(v ** 2, axis=2)) for v in (before, after)]
        record = accuracy_in_use("validation", None, "set", *held, np.full(n, 1e-3))
        check = in_use_check(record)
        assert check.status == status, (n, check.summary)
        if n == 1:
            assert "one held-out point has no standard error" in check.summary
        # worse by no more than the stated noise costs the estimates: a warning saying so
        worse = -record.improvement[0]
        within = in_use_check(record, noise_cost=1.01 * worse)
        assert within.status == "warn" and ("no more than the stated noise costs" in within.summary) == (n == 60)
        assert in_use_check(record, noise_cost=0.99 * worse).status == status


def test_no_held_out_point_is_named_a_blunder_on_robots_beyond_the_model():
    """Validation sets of 30 poses of simulated robots with effects beyond the model (every preset):
    their held-out errors are predictions, heavier-tailed than a fit's residuals (at the fit's own bar
    of 5 robust standard deviations, 1 draw in 10 of the elastic and the geared robot named a point at
    5.1); at the blunders' bar none is named."""
    m = arm6r()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for kind, robot in PRESETS.items():
            for seed in range(6):
                rng = np.random.default_rng(seed)
                true = rc.perturb_model(m, rc.identifiability(m).identified, rng=seed)
                data = measure_campaign(true, rc.random_configurations(m, 130, rng), robot, rng=seed + 1)
                result = rc.calibrate(m, data.subset(np.arange(100)), validation=data.subset(np.arange(100, 130)))
                check = next(c for c in result.checks if c.name == "outliers among the held-out points")
                assert check.status == "pass", (kind, seed, check.summary)


def test_held_out_errors_beside_an_exact_fit_are_overfitting_without_a_ratio():
    """Fitted poses fitted exactly (as many equations as parameters) and held-out errors: overfitting,
    said without dividing by the fitted error (a ZeroDivisionError once the check named another set-up
    first)."""
    from robocal._identification.checks import in_use_check
    from robocal._identification.holdout import HeldOut, accuracy_in_use
    before = np.random.default_rng(1).normal(scale=1e-4, size=(60, 1, 3))
    held = [HeldOut(v, None, np.sum(v ** 2, axis=2)) for v in (before, 0.5 * before)]
    check = in_use_check(accuracy_in_use("cross-validation", 5, "5 folds", *held, np.zeros(60)))
    assert check.status == "warn" and "the fitted poses fitted exactly (overfitting)" in check.summary


def test_a_campaign_in_a_small_cube_says_where_the_model_holds():
    m = arm6r()
    true = rc.perturb_model(m, rc.identifiability(m).identified, rng=1)
    rng = np.random.default_rng(2)
    q0 = rc.random_configurations(m, 1, rng)[0]
    q = q0 + rng.uniform(-0.03, 0.03, (60, 6))          # a few centimetres of tool motion
    data = rc.measure(true, q, noise=NOISE, rng=3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = rc.calibrate(m, data)
    where = next(c for c in result.checks if c.name == "where the model holds")
    assert where.status == "warn" and "near the measured poses only" in where.summary
    assert result.coverage.extrapolation > 3 and result.coverage.spread_ratio < 0.25


def test_a_limit_not_reached_cannot_stand_under_a_clean_pass():
    m, true, data = _real_campaign(PRESETS["gears"], 5)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = rc.calibrate(m, data, limit=1e-5)
    limit = next(c for c in result.checks if c.name == "limit of absolute accuracy")
    assert not result.limit.reached and limit.status == "warn" and result.verdict != "pass"


def test_a_limit_reached_within_the_margin_says_so():
    # 1.03 times the limit read "(reached)", as if below it
    from robocal._identification.checks import limit_check
    from robocal._identification.result import LimitJudgement

    near = limit_check(LimitJudgement(1e-4, "cross-validation", 1.03e-4, 1.03, True))
    below = limit_check(LimitJudgement(1e-4, "cross-validation", 0.9e-4, 0.9, True))
    assert near.status == "pass" and "(reached, within the 1.15 times it the check allows)" in near.summary
    assert below.status == "pass" and below.summary.endswith("(reached)")


def test_a_noise_stated_ten_times_too_large_is_said_and_hides_no_blunder():
    m = arm6r()
    true, data = rc.simulate(m, 60, seed=9, noise=NOISE)
    pos = data.positions.copy()
    pos[17, 0] += 40 * NOISE * np.array([0.6, 0.8, 0.0])          # 40 standard deviations
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = rc.calibrate(m, replace(data, positions=pos), noise=rc.Noise.of(position=10 * NOISE))
    outliers = next(c for c in result.checks if c.name == "outliers")
    fit = next(c for c in result.checks if c.name == "fit against the instrument")
    assert outliers.status == "warn" and outliers.items[0].startswith(data.labels[17])
    assert fit.status == "warn" and "below what was stated" in fit.summary


def test_a_run_of_consecutive_rows_is_a_systematic_error_not_blunders():
    """A base-and-tool fit over a campaign where 16 consecutive poses carry an offset (a bump of the
    instrument): named as a run and kept, not set aside as blunders; a systematic effect, which the
    accuracy in use judges, so the outlier check says it without warning."""
    m = arm6r()
    true, data = rc.simulate(m, 80, seed=3, noise=NOISE, parameters=("base",))
    pos = data.positions.copy()
    pos[30:46, 0] += [2e-3, 0, 0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = rc.calibrate(m, replace(data, positions=pos), parameters=("base", "markers"))
    outliers = next(c for c in result.checks if c.name == "outliers")
    assert outliers.status == "pass" and "runs of consecutive poses" in outliers.summary
    assert {item.split(",")[0] for item in outliers.items} <= {f"pose {i}" for i in range(30, 46)}
    assert not any("set aside" in n for n in result.notes)
    assert any("a systematic error, not blunders" in n for n in result.notes)


def test_plausibility_judges_what_the_robot_does_not_raw_numbers():
    """An equivalent parametrisation (a large change of two parameters that moves the tool nowhere)
    passes; a marker rotation declared unknown gets no tolerance; a 100 mm model error fails."""
    from robocal._identification.checks import (  # the check alone
        DEFAULT_TOLERANCES,
        WorkspaceChange,
        plausibility_check,
    )
    from robocal.identification import ParameterEstimate
    turn = ParameterEstimate("j5.theta", "rad", 0.0, np.pi, 1e-4, family="frames", quantity="angle")
    still = WorkspaceChange(max_m=2.2e-4, rms_m=1e-4, tolerance_m=0.045, reach_m=1.0, n_poses=300)
    assert plausibility_check([turn], DEFAULT_TOLERANCES, {}, workspace=still).status == "pass"
    tool = ParameterEstimate("tool.rz", "rad", 0.0, np.deg2rad(120), 1e-3, family="markers", quantity="angle")
    assert plausibility_check([tool], DEFAULT_TOLERANCES, {}).status == "fail"
    assert plausibility_check([tool], DEFAULT_TOLERANCES, {}, unknown_rotations=("tool",)).status == "pass"
    moved = replace(still, max_m=0.1)
    check = plausibility_check([turn], DEFAULT_TOLERANCES, {}, workspace=moved)
    assert check.status == "fail" and "moves the tool up to 100 mm" in check.summary


def test_a_wrong_link_length_of_100_mm_is_said_by_what_the_robot_does():
    """The data correct a link 100 mm off and the model places the robot right in use: the change is
    said with what it does to the tool and the key of its tolerance, not failed."""
    m = arm6r()
    true, data = rc.simulate(m, 60, seed=2, noise=NOISE)
    wrong = m.replace(frames=tuple(replace(f, d=f.d + 0.1) if f.name == "j3" else f for f in m.frames))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = rc.calibrate(wrong, data)
    check = next(c for c in result.checks if c.name == "plausible changes")
    assert check.status == "warn" and result.verdict == "warn"
    assert "moves the tool up to" in check.summary and "tolerances.frames.length" in check.summary + check.fix
    assert result.in_use.position_after.mean < 1e-4


def test_interchangeable_parameters_cannot_pass_as_identified():
    from robocal._identification.checks import correlation_check, identifiability_check, interchangeable_pairs
    corr = np.array([[1.0, -1.0], [-1.0, 1.0]])
    names = ["j2.d", "j3.d"]
    assert correlation_check(names, corr, loose={"j2.d"}).status == "warn"
    pairs = interchangeable_pairs(names, corr, loose={"j2.d"})
    assert identifiability_check((), (), interchangeable=pairs).status == "warn"
    # two well-determined parameters that correlated are information, not a fault
    assert correlation_check(names, corr, loose=set()).status == "pass"


def test_cross_validation_costs_little_and_is_said():
    m, true, data = _real_campaign(PRESETS["scatter"], 1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = rc.calibrate(m, data)
    use = result.in_use
    assert use.method == "cross-validation" and use.folds == 5 and use.position_after.n == 150
    assert use.position_after.mean < use.position_before.mean
    assert "folds drawn at random" in use.grouping        # a random plan: no block holds out a region
    series = replace(data, extra={**data.extra, "series": np.array(["a"] * 50 + ["b"] * 50 + ["c"] * 50)})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        by_series = rc.calibrate(m, series)
    assert by_series.in_use.folds == 3 and by_series.in_use.grouping == "3 folds by series"


def test_a_row_written_many_times_keeps_the_standard_deviations_honest():
    """One pose's row copied 30 times: counted once, the estimates' z-scores stay standard (RMS z
    about 1 over 20 seeds; counting the copies gave 1.67)."""
    from conftest import z_scores
    m = arm6r()
    zs = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for seed in range(20):
            true, data = rc.simulate(m, 60, seed=seed, noise=NOISE)
            result = rc.calibrate(m, data.subset(np.r_[np.arange(60), np.full(29, 7)]))
            zs.append(z_scores(result, true, m))
    assert any("counted once" in n for n in result.notes)
    assert 0.8 < np.sqrt(np.mean(np.concatenate(zs) ** 2)) < 1.25


def test_a_tool_orientation_declared_unknown_gets_no_tolerance(tmp_path):
    """A 6D campaign whose tool is turned 25 deg from the model's: implausible where the model states
    the orientation, a pass where it declares it unknown (``rotation: unknown``), which reads back."""
    from scipy.spatial.transform import Rotation
    m = arm6r()
    turned = tuple(map(tuple, Rotation.from_euler("z", 25, degrees=True).as_matrix()))
    true = rc.perturb_model(m.replace(markers=(replace(m.markers[0], rotation=turned),)),
                            rc.identifiability(m, orientation=True).identified, rng=1)
    data = rc.measure(true, rc.random_configurations(m, 40, np.random.default_rng(2)), noise=NOISE,
                      orientation=True, noise_rot=1e-4, rng=3)
    unknown = m.replace(markers=(replace(m.markers[0], rotation_known=False),))
    rc.write_model(unknown, tmp_path / "m.yaml")
    assert "rotation: unknown" in (tmp_path / "m.yaml").read_text()
    assert not rc.read_model(tmp_path / "m.yaml").markers[0].rotation_known
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        stated, declared = rc.calibrate(m, data), rc.calibrate(rc.read_model(tmp_path / "m.yaml"), data)
    said = next(c for c in stated.checks if c.name == "plausible changes")
    # better in use, so said rather than failed, with the way to declare it
    assert said.status == "warn" and "rotation: unknown" in said.fix
    assert next(c for c in declared.checks if c.name == "plausible changes").status == "pass"
    assert declared.verdict != "fail"


def test_a_worse_worst_error_in_use_is_said():
    """Another series whose mean error falls but whose worst grows (2.71 -> 3.62 mm on a UR10): a
    warning naming it."""
    from robocal._identification.checks import in_use_check  # the check on its own, with figures made to order
    from robocal._identification.holdout import HeldOut, accuracy_in_use
    rng = np.random.default_rng(1)
    before = rng.normal(scale=1e-3, size=(80, 1, 3))
    before *= np.minimum(1.0, 2.71e-3 / np.linalg.norm(before, axis=2, keepdims=True))   # worst 2.71 mm
    after = 0.5 * before
    after[5, 0] = [3.62e-3, 0.0, 0.0]                                                   # worst 3.62 mm
    held = [HeldOut(v, None, np.sum(v ** 2, axis=2)) for v in (before, after)]
    check = in_use_check(accuracy_in_use("validation", None, "set", *held, np.full(80, 5e-4)))
    assert check.status == "warn" and "the worst error grew" in check.summary


def test_a_limit_does_not_turn_a_mistake_into_a_pass():
    m, true, data = _real_campaign(PRESETS["gears"], 6, n=60)
    wrong = m.replace(frames=tuple(replace(f, d=-f.d) if f.name == "j3" else f for f in m.frames))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = rc.calibrate(wrong, data, limit=0.15e-3)
    assert result.verdict == "fail" and not result.limit.reached


@pytest.mark.parametrize("chunked", [False, True])
def test_point_losses_from_the_errors_at_hand_are_the_residuals_own(chunked):
    """A held-out evaluation takes each point's loss from the errors it has just computed: the
    same numbers, bit for bit, as from the residuals (weighted, masked, two markers, in chunks)."""
    from robocal._identification.holdout import point_loss

    robot = arm6r(markers=(("a", (0.05, 0.02, 0.12)), ("b", (0.0, 0.1, 0.05))))
    _, data = rc.simulate(robot, 300, seed=3)
    rng = np.random.default_rng(4)
    mask = data.mask & (rng.random(data.mask.shape) > 0.2)
    data = replace(data, mask=mask, positions=np.where(mask[..., None], data.positions, np.nan),
                   sigma=rng.uniform(1e-5, 3e-5, mask.shape))
    prob = Points(robot, data, ("j2.d", "j3.theta"), compliance=False, chunked=chunked)
    p = rc.parameter_vector(robot) + 1e-4
    a, b = point_loss(prob, p), point_loss(prob, p, prob.errors(p))
    assert a.shape == mask.shape and np.array_equal(a, b) and np.all(a[~mask] == 0) and np.all(a[mask] > 0)


def test_a_configuration_repeated_exactly_is_held_out_with_its_first_occurrence():
    """Folds drawn at random or of consecutive poses: a configuration measured again goes to the
    fold of its first occurrence (held out with it, it cannot vouch for itself); distinct ones keep
    their fold, one apart from another along a direction that ties their projection included."""
    from robocal._identification.holdout import FOLD_SEED, fold_labels

    m = rc.serial_model("r3", [dict(), dict(alpha=np.pi / 2), dict(d=0.4)])
    q = np.random.default_rng(2).uniform(-1, 1, size=(40, 3))
    q[7] = q[30] = q[3]                              # the same configuration three times
    q[12] = q[5] + np.array([np.sqrt(2.0), 0.0, -2.0]) * 1e-3
    moved = []
    for order in (q, q[np.argsort(q[:, 0], kind="stable")]):
        data = rc.Measurements(q=order, positions=np.zeros((40, 1, 3)), marker_names=("tool",),
                               joint_names=m.joint_names)
        labels, k, how = fold_labels(data, 4)
        drawn = np.random.default_rng(FOLD_SEED).permutation(40) % 4
        plain = np.arange(40) * 4 // 40 if "consecutive" in how else drawn
        first = {tuple(row): i for i, row in reversed(list(enumerate(order)))}
        assert len(first) == 38
        expected = np.array([plain[first[tuple(row)]] for row in order])
        assert k == 4 and np.array_equal(labels, expected)
        moved.append(not np.array_equal(labels, plain))
    assert any(moved)
