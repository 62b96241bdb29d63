"""The verdict judges the robot in use: it never fails a calibration that places the robot better,
never passes one that cannot be right, names what happened, and says no more than its figures show
(docs/checks.md). Real campaigns where the behaviour comes from them (tests/data/real), simulated
robots with effects beyond the model elsewhere."""

from __future__ import annotations

import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from real_campaigns import campaign, nominal
from robots import arm6r, humanoid

import robocal as rc
from robocal.sim import RobotImperfections, measure_campaign

TH8 = Path(__file__).resolve().parent.parent / "examples" / "th8"


def _quiet(fn, *a, **k):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fn(*a, **k)


def _checks(res) -> dict:
    return {c.name: c for c in res.checks}


# -- never fail what places the robot better --------------------------------------------------------

def test_an_elastic_humanoid_calibrated_with_compliance_is_not_failed():
    """Joints that deflect degrees under gravity (a humanoid's): the compliance the calibration finds
    is beyond a gear-driven arm's, but the robot is placed far better in use, so a tolerance of its
    own may warn (naming the model file's key that sets it), never fail."""
    model = humanoid()
    true = rc.perturb_model(model, rc.identifiability(model).identified, rng=3)
    q = rc.random_configurations(model, 300, rng=4)
    robot = RobotImperfections(elasticity=4e-4, load_scale=1e9, repeatability_sigma=1e-4, instrument_noise=2e-4)
    data = measure_campaign(true, q, robot, rng=5, robot_seed=1)
    res = _quiet(rc.calibrate, model, data, parameters=("geometric", "compliance"), noise="camera")
    assert res.verdict != "fail", [c.summary for c in res.checks if c.status == "fail"]
    assert res.in_use.position_after.mean < res.in_use.position_before.mean / 5
    tight = model.replace(tolerances=(("compliance", "compliance", np.deg2rad(0.2)),))
    strict = _quiet(rc.calibrate, tight, data, parameters=("geometric", "compliance"), noise="camera")
    check = _checks(strict)["plausible changes"]
    assert check.status == "warn" and "tolerances.compliance.deflection" in check.summary


def test_a_wrong_nominal_link_that_the_calibration_corrects_warns_not_fails():
    """An elbow 100 mm off in the model file: the calibration moves it back, which no tolerance allows,
    and places the robot far better in use: the changes warn, naming the parameter."""
    model = arm6r()
    wrong = model.replace(frames=tuple(replace(f, d=f.d + 0.1) if i == 2 else f for i, f in enumerate(model.frames)))
    data = rc.measure(model, rc.random_configurations(model, 80, 2), noise=2e-5, rng=2)
    res = _quiet(rc.calibrate, wrong, data)
    check = _checks(res)["plausible changes"]
    assert check.status == "warn" and res.verdict != "fail" and "places the robot better in use" in check.summary


# -- the accuracy in use, never below what held-out data show ---------------------------------------

@pytest.mark.parametrize("robot, repeatability", [("UR5", 0.1e-3), ("WAM", 2e-3)])
def test_a_stated_noise_at_the_robots_repeatability_leaves_the_accuracy_in_use(robot, repeatability):
    """--noise-mm at the robot's repeatability (the UR5's 0.1 mm) once took all of the held-out error
    away (0 mm in use against 0.100 mm measured on the test poses): only the instrument's share goes."""
    model = nominal(robot)
    grid, test = campaign(robot, "grid", model), campaign(robot, "random", model)
    for noise in (None, rc.Noise.of("tracker", position=repeatability)):
        res = _quiet(rc.calibrate, model, grid, noise=noise)
        truth = np.linalg.norm(rc.forward_kinematics(res.calibrated_model, test.q).positions[:, 0]
                               - test.positions[:, 0], axis=1).mean()
        assert abs(res.in_use.position_after.mean / truth - 1.0) <= 0.2, (noise, res.in_use.position_after.mean, truth)


def test_the_in_use_table_prints_the_measured_figure_beside_the_robots_and_keeps_its_columns():
    from robocal.report import calibration_summary

    model = nominal("UR5")
    res = _quiet(rc.calibrate, model, campaign("UR5", "grid", model))
    text = calibration_summary(res)
    assert "after, as measured" in text
    far = replace(res.in_use, position_before=replace(res.in_use.position_before, mean=1.2345, rms=2.3456,
                                                      p95=3.4567, max=4.5678))
    from robocal._presentation.text import in_use_lines

    row = next(line for line in in_use_lines(far) if line.strip().startswith("before"))
    assert all(v in row.split() for v in ("1234.500", "2345.600", "3456.700", "4567.800")), row


def test_the_held_out_errors_as_measured_and_the_robots_are_named_apart():
    """The UR5 validated on its 20 test poses: the summary printed "validation, after" 0.101 mm and,
    under "accuracy in use", "after" 0.095 mm, with nothing to say that the first is as the tracker
    measured it and the second the robot's, the tracker's noise taken out (the same poses, the same
    registration); the limit's line called the robot's figure "validation after"."""
    from robocal.report import calibration_summary

    model = nominal("UR5")
    res = _quiet(rc.calibrate, model, campaign("UR5", "grid", model), validation=campaign("UR5", "random", model),
                 limit=1e-4)
    use, held = res.in_use, res.stats.validation_after
    lines = calibration_summary(res).splitlines()

    def row(label):
        """The figures of the row ``label`` (n first in the first table)."""
        return next(line.strip()[len(label):].split() for line in lines if line.strip().startswith(label + "  "))

    assert lines[1].split()[:5] == ["position", "error", "as", "measured", "(mm)"]
    assert row("validation, after")[:2] == ["20", f"{held.mean * 1e3:.3f}"] and f"{held.mean * 1e3:.3f}" == "0.101"
    heading = next(line for line in lines if line.startswith("accuracy in use"))
    assert heading == ("accuracy in use (validation), on 20 held-out point(s): the robot's error, the instrument's "
                       f"noise ({use.noise * 1e3:.4g} mm RMS) taken out")
    assert row("after")[0] == f"{use.position_after.mean * 1e3:.3f}" == "0.095"
    assert row("after, as measured")[0] == "0.101"        # the first table's figure, named as it
    limit = next(line for line in lines if line.startswith("limit of absolute accuracy"))
    assert "validation after" not in limit and f"the robot's, as the accuracy in use says) " \
        f"{use.position_after.mean * 1e3:.3f} mm" in limit


# -- where the model holds: against use ------------------------------------------------------------

@pytest.mark.parametrize("robot", ["UR5", "WAM"])
def test_a_real_campaign_is_not_warned_for_not_covering_its_nominal_plus_minus_360(robot):
    """DH tables state +-360 deg: coverage is judged against the campaign's range of such joints (the
    robot's use), not against every turn they could make."""
    model = nominal(robot)
    rng = np.random.default_rng(1)
    grid = campaign(robot, "grid", model)
    for size in (150, 250):
        sub = grid.subset(np.sort(rng.choice(grid.n_poses, min(size, grid.n_poses), replace=False)))
        check = _checks(_quiet(rc.calibrate, model, sub))["where the model holds"]
        assert check.status == "pass"
        # the span of such a joint over a range of use made from the campaign is 1 / 1.2 whatever
        # the campaign: it printed "joints over 83 %, 83 %, ..." as if measured
        assert "every joint's limits allow a full turn or more" in check.summary and " 83 %" not in check.summary


def test_a_correction_far_beyond_what_the_measured_poses_show_fails():
    """Two wrist joints never moved and the tool declared known: the calibration takes the tool's
    error up as a twist of the wrist, fits to the noise and holds out as well, yet is about 50 mm off
    where the wrist turns (the nominal: 4 mm). Its own figures show it: the geometry moves the tool
    there a dozen times what the nominal misses the fitted points by. With every joint moving,
    the same robot passes."""
    nominal_model, true = rc.read_model(TH8 / "model.yaml"), rc.read_model(TH8 / "true_model.yaml")
    rng = np.random.default_rng(1)
    q = rc.random_configurations(nominal_model, 60, rng=rng)
    still = q.copy()
    still[:, 3], still[:, 5] = 0.3, 0.1
    use = rc.random_configurations(nominal_model, 300, rng=5)
    for readings, verdict in ((still, "fail"), (q, "pass")):
        res = _quiet(rc.calibrate, nominal_model, rc.measure(true, readings, rng=rng), known=("markers",))
        if verdict == "fail":   # the diagnosis names what the still joints lose, not what the base takes up
            evidence = next(f.evidence for f in res.diagnosis.findings if f.hypothesis == "joint still")
            assert "cannot separate" in evidence and "j5.alpha" in evidence and "j1." not in evidence, evidence
        off = np.linalg.norm(rc.forward_kinematics(res.calibrated_model, use).positions
                             - rc.forward_kinematics(true, use).positions, axis=-1)
        check = _checks(res)["where the model holds"]
        assert (check.status, res.verdict) == (verdict, verdict), check.summary
        assert ("times what the nominal misses the fitted points by" in check.summary) == (verdict == "fail")
        # what the check judges, against the truth in use
        assert (np.sqrt(np.mean(off ** 2)) > 0.02) == (verdict == "fail")


def test_coverage_names_the_joints_whose_range_of_use_is_the_campaigns():
    from robocal._identification.checks import coverage_check
    from robocal._identification.holdout import Coverage, UseStats

    use = type("InUse", (), {"position_after": UseStats(10, 1e-3, 1e-3, 2e-3, 3e-3)})()
    cover = Coverage(np.array([0.5, 1 / 1.2, 0.25]), ((0, 1),) * 3, ((0, 0, 0), (1, 1, 1)), 0.9, 1e-4, 1e-4,
                     joint_names=("a", "b", "c"), use_from_campaign=(False, True, False))
    summary = coverage_check(cover, use).summary
    assert "joints over their ranges of use: a 50 %, c 25 %; the limits of b allow a full turn" in summary
    assert "83 %" not in summary


def test_coverage_names_the_cause_its_figures_show():
    from robocal._identification.checks import coverage_check
    from robocal._identification.holdout import Coverage, UseStats

    use = type("InUse", (), {"position_after": UseStats(10, 1e-3, 1e-3, 2e-3, 3e-3)})()
    wide = Coverage(np.ones(3), ((0, 1),) * 3, ((0, 0, 0), (1, 1, 1)), 1.26, 1e-4, 2e-3)
    check = coverage_check(wide, use)
    assert check.status == "warn" and "small part" not in check.cause and "only where they were measured" in check.cause
    narrow = Coverage(np.ones(3), ((0, 1),) * 3, ((0, 0, 0), (1, 1, 1)), 0.1, 1e-4, 1.2e-4)
    assert "small part" in coverage_check(narrow, use).cause


# -- the right names ------------------------------------------------------------------------------

def test_a_validation_of_another_set_up_names_register_validation_not_overfitting():
    """Held-out poses measured with the tracker set up again (0.3 mm and 0.03 deg elsewhere): held-out
    errors well above the fitted ones, which registering base and tool on them explains."""
    model = arm6r()
    true = rc.perturb_model(model, rc.identifiability(model).identified, rng=6)
    fit = rc.measure(true, rc.random_configurations(model, 60, 6), noise=2e-5, rng=6)
    moved = true.replace(base_position=tuple(np.add(true.base_position, (3e-4, -2e-4, 1e-4))))
    held = rc.measure(moved, rc.random_configurations(model, 30, 7), noise=2e-5, rng=7)
    check = _checks(_quiet(rc.calibrate, model, fit, validation=held))["accuracy in use"]
    assert "--register-validation" in check.fix and "overfitting" not in check.summary
    registered = _quiet(rc.calibrate, model, fit, validation=held, register_validation=True)
    assert registered.in_use.position_after.mean < 0.1e-3
    assert np.nanmax(registered.validation.errors_after) < 0.2e-3        # the rows shown are the registered ones


def test_an_implausible_tool_rotation_names_rotation_unknown():
    from scipy.spatial.transform import Rotation

    model = arm6r()
    R = Rotation.from_euler("x", 40, degrees=True).as_matrix()            # the tool turned 40 deg about its x
    true = model.replace(markers=(replace(model.markers[0], rotation=tuple(map(tuple, R))),))
    data = rc.measure(true, rc.random_configurations(model, 60, 3), noise=2e-5, rng=3, orientation=True)
    check = _checks(_quiet(rc.calibrate, model, data))["plausible changes"]
    assert check.status != "pass" and "rotation: unknown" in check.fix


# -- no pass on the impossible -------------------------------------------------------------------

def test_the_fitted_file_given_again_as_validation_is_refused():
    model = rc.read_model(TH8 / "model.yaml")
    data = rc.read_measurements(TH8 / "measurements.csv", model)
    with pytest.raises(rc.InputError, match="nothing is held out") as e:
        rc.calibrate(model, data, validation=data)
    assert e.value.where == "validation"
    some = data.subset(np.r_[np.arange(5), 10])               # pose 11 is also fitted
    rest = data.subset(np.arange(5, data.n_poses))
    check = _checks(_quiet(rc.calibrate, model, rest, validation=some))["validation set apart from the fitted one"]
    assert check.status == "warn" and check.summary.startswith("1 of its 6 poses")


def test_two_markers_calibrated_to_one_point_fail():
    """One marker's columns copied from another: the two are calibrated to one point, which no tool
    does, whatever the fit says."""
    model = arm6r(markers=(("a", (0.05, 0.02, 0.12)), ("b", (0.0, 0.05, 0.1))))
    data = rc.measure(model, rc.random_configurations(model, 60, 8), noise=2e-5, rng=8)
    copied = replace(data, positions=np.stack([data.positions[:, 0], data.positions[:, 0]], axis=1))
    res = _quiet(rc.calibrate, model, copied)
    assert _checks(res)["markers apart"].status == "fail" and res.verdict == "fail"


def test_no_gain_in_use_with_a_misfit_far_beyond_the_instrument_fails_and_only_then():
    """A model no better than the nominal one in use: a warning when the fit leaves what a robot
    leaves (tens of times the instrument), a failure at a thousand times it, where it cannot be the
    robot's own errors (a mistake in the data or the model file)."""
    from robocal._identification.checks import in_use_check  # the check on its own, figures made to order
    from robocal._identification.holdout import HeldOut, accuracy_in_use
    rng = np.random.default_rng(0)
    before = rng.normal(scale=1e-3, size=(60, 1, 3))
    after = before * rng.uniform(0.97, 1.03, size=(60, 1, 1))        # no better within a standard error
    held = [HeldOut(v, None, np.sum(v ** 2, axis=2)) for v in (before, after)]
    record = accuracy_in_use("validation", None, "set", *held, np.full(60, 1e-3))
    assert in_use_check(record, misfit=30.0).status == "warn"
    mistaken = in_use_check(record, misfit=1000.0)
    assert mistaken.status == "fail" and "1e+03 times what the instrument explains" in mistaken.summary


def test_a_misfit_far_beyond_the_instrument_with_a_model_no_better_fails():
    """Joint readings shuffled against the points: the fit leaves a thousand times the instrument and
    the model places the robot no better than the nominal one."""
    model = arm6r()
    data = rc.measure(model, rc.random_configurations(model, 80, 9), noise=2e-5, rng=9)
    shuffled = replace(data, q=data.q[np.random.default_rng(1).permutation(data.n_poses)])
    res = _quiet(rc.calibrate, model, shuffled)
    assert res.verdict == "fail", [(c.name, c.status) for c in res.checks]


# -- contacts judged in use like points ------------------------------------------------------------

MUKCA = Path(__file__).resolve().parent / "data" / "real" / "mukca"


def _panda_held_out(**kw):
    model = rc.read_urdf(MUKCA / "panda.urdf", tip_link="ball_link", markers=[("ball", (0.0, 0.0, 0.0))])
    fit, held = rc.io.read_contacts(MUKCA / "panda_3", model).split_placements(["frontleft", "backright"])
    return _quiet(rc.calibrate, model, contacts=fit, validation=held, **kw)


def test_a_limit_given_with_contacts_is_judged_and_changes_nothing_else():
    """The MUKCa Panda with a limit of absolute accuracy: judged against the held-out placements like
    measured points (it was not judged at all), the same parameters held, the same accuracy in use."""
    plain, limited = _panda_held_out(), _panda_held_out(limit=0.3e-3)
    assert plain.limit is None and limited.limit is not None and limited.limit.reached
    assert _checks(limited)["limit of absolute accuracy"].status == "pass"
    assert [e.name for e in limited.parameters] == [e.name for e in plain.parameters]
    assert limited.in_use.position_after.mean == pytest.approx(plain.in_use.position_after.mean, rel=1e-6)
    beyond = _panda_held_out(limit=0.1e-3)
    assert not beyond.limit.reached and _checks(beyond)["limit of absolute accuracy"].status != "pass"


def test_the_held_out_spacing_is_part_of_the_accuracy_in_use():
    """The known spacing between the sockets of the placements the fit did not see, before and after
    calibration, judged beside the socket consistency; worse after fails like worse in use."""
    from robocal._identification.checks import spacing_check

    res = _panda_held_out()
    spacing = _checks(res)["spacing in use"]
    assert spacing.status == "pass" and "over 2 held-out placement" in spacing.summary
    after = res.in_use.spacing_after
    assert len(after) == 2 and after.mean() < res.in_use.spacing_before.mean() / 5
    shrunk = replace(res.in_use, spacing_after=res.in_use.spacing_before + 5e-3)     # a robot scaled wrong
    assert spacing_check(shrunk)[0].status == "fail"


# -- clean campaigns say so -----------------------------------------------------------------------

def test_clean_campaigns_of_robots_with_effects_beyond_the_model_name_no_blunder():
    """An elastic arm (its joints deflect under gravity, its links bend) and a cable-driven one
    measured by a tracker, calibrated with compliance: their extreme poses leave a tail of residuals
    beyond the outlier bar, which is the robot, not blunders: none is set aside, the outlier check
    does not warn."""
    from robocal.sim import PRESETS

    rng = np.random.default_rng(0)
    nominal = arm6r(masses=True)
    for k, preset in enumerate(["elastic", "cable"] * 4):
        true = rc.perturb_model(nominal, rc.identifiability(nominal).identified, rng=int(rng.integers(1 << 30)))
        q = rc.random_configurations(nominal, int(rng.integers(150, 260)), rng=int(rng.integers(1 << 30)))
        data = measure_campaign(true, q, PRESETS[preset], rng=int(rng.integers(1 << 30)), robot_seed=k)
        res = _quiet(rc.calibrate, nominal, data, parameters=("geometric", "compliance"))
        assert not any("set aside" in n for n in res.notes), (k, preset, res.notes)
        assert _checks(res)["outliers"].status == "pass", (k, preset, _checks(res)["outliers"].summary)


def test_the_held_out_errors_as_measured_are_written_beside_the_robots_and_read_back(tmp_path):
    """A stated noise takes the instrument's share out of the accuracy in use: the check, result.json
    and the result read back keep the figure as measured beside it."""
    from robocal.io import read_result, write_result

    model = arm6r()
    data = rc.measure(model, rc.random_configurations(model, 60, 4), noise=5e-5, rng=4)
    res = _quiet(rc.calibrate, model, data, noise=rc.Noise.of("tracker", position=5e-5))
    seen, robot = res.in_use.measured_after, res.in_use.position_after
    assert seen.mean > robot.mean
    assert "as measured" in _checks(res)["accuracy in use"].summary
    write_result(res, tmp_path / "result.json")
    back = read_result(tmp_path / "result.json")
    assert back.in_use.measured_after.mean == pytest.approx(seen.mean, rel=1e-12)
    assert back.in_use.cross_validated is None and back.in_use.spacing_after is None
