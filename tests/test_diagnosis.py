"""The diagnosis decides (docs/diagnosis.md): every calibration is diagnosed, a clean one without a refit;
a cause is named only when its repair explains the data and places the robot better in use; a decisive
cause fails the calibration, in Python as on the command line; mistakes of the model file are named as
the model's, with the value the data say; what the data cannot tell is said as such. Mistakes injected
into the published UR5 and WAM campaigns (tests/real_mistakes.py) and simulated ones
(tests/diagnosis_corpus.py); the whole corpus is benchmarks/diagnosis_corpus.py."""

import importlib.util
import json
import re
import warnings
from dataclasses import replace
from functools import partial
from types import SimpleNamespace

import diagnosis_corpus as corpus
import numpy as np
import pytest
import real_campaigns as real
import real_mistakes as rm
import robots
from scipy.spatial.transform import Rotation

import robocal as rc
from robocal._diagnosis import campaign, reference
from robocal.errors import InputError

pytestmark = pytest.mark.skipif(not real.FILES.exists(), reason="the real campaigns are not here")


def _calibrated(model, data, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return rc.calibrate(model, data, **kw)


def _first(result):
    return result.diagnosis.cause


# -- every calibration, cheaply ----------------------------------------------------------------------

@pytest.mark.parametrize("robot", ["UR5", "WAM"])
def test_every_calibration_is_diagnosed_and_a_clean_one_without_a_refit(robot):
    """The published grids calibrate to a pass; the diagnosis ran all the same (its check passes), the
    statistics ruled every repair out without a refit, and it names no cause."""
    model = real.nominal(robot)
    result = _calibrated(model, real.campaign(robot, "grid", model))
    assert result.verdict == "pass"
    diagnosis = result.diagnosis
    assert diagnosis.findings == () and diagnosis.refitted == (), diagnosis.summary
    assert [c.status for c in result.checks if c.name == "diagnosis"] == ["pass"]
    assert diagnosis.summary.startswith("nothing tested explains the misfit")


def test_a_copied_marker_fails_and_is_named():
    """One marker's columns copied from another's, 62 mm apart on the tool: the fit passes (the marker's
    position is free, within its tolerance: 32a3abb passed it), the model puts that marker where the
    other is; the diagnosis sees it without a misfit, and fails the calibration."""
    m, _, d = corpus._sim("6r", 0, markers=(("tool", (0.05, 0.02, 0.12)), ("tool2", (0.0, 0.04, 0.09))))
    pos = d.positions.copy()
    pos[:, 1] = pos[:, 0]
    result = _calibrated(m, replace(d, positions=pos))
    found = _first(result)
    assert result.verdict == "fail" and found.hypothesis == "marker copied" and found.status == "fail"
    assert "tool2's values equal marker tool's" in found.cause and "35.6 mm apart" in found.evidence


def test_a_reflector_moved_in_its_nest_is_named_on_the_real_ur5():
    """The reflector moved 1 mm in its nest from a quarter of the UR5 grid on: found at that row."""
    case = rm.reflector_moved("UR5")
    result = case.run()
    found = _first(result)
    assert result.verdict == "fail" and found.hypothesis == "marker moved" and found.status == "fail"
    assert "from step 240 on" in found.cause and found.rms_after < 0.07e-3 < found.rms_before


# -- a decisive cause decides ---------------------------------------------------------------------------

def _files(tmp_path, model, data):
    rc.write_model(model, tmp_path / "model.yaml", force=True)
    (tmp_path / "data.csv").write_text(rc.io.measurements_to_csv(data, model=model))
    return tmp_path / "model.yaml", tmp_path / "data.csv"


def test_a_decisive_cause_fails_the_calibration_on_the_command_line_as_in_python(tmp_path, cli):
    """A UR5 joint turning 1.02 times its reading: named, and the calibration fails (exit 3, no
    calibrated model unless --write-failed), the cause and its fix printed first, the family that
    would carry the scale named; Python's calibrate decides the same."""
    case = rm.gear_ratio("UR5")
    assert case.run().verdict == "fail"
    model, data = _files(tmp_path, case.model, case.data)
    code, out, _ = cli("calibrate", model, data, "--out", tmp_path / "out")
    assert code == 3 and not (tmp_path / "out" / "calibrated.yaml").exists()
    lines = out.splitlines()
    assert lines[0] == "diagnosis:" and lines[1].startswith("  DECISIVE: joint shoulder_lift moves 1.02")
    assert lines[2].startswith("    fix: ") and "--parameters geometric,transmission" in lines[2]
    saved = json.loads((tmp_path / "out" / "result.json").read_text())
    assert saved["verdict"] == "fail" and saved["diagnosis"]["findings"][0]["hypothesis"] == "joint scale"
    assert rc.read_result(tmp_path / "out" / "result.json").diagnosis.cause.hypothesis == "joint scale"
    code, _, _ = cli("calibrate", model, data, "--out", tmp_path / "written", "--write-failed")
    assert code == 3 and (tmp_path / "written" / "calibrated.yaml").exists()


def test_a_robots_own_gear_error_warns_with_the_family_that_carries_it():
    """A cylindrical arm whose joints have gear errors of 0.02 deg (the judgement corpus' campaign 41):
    a scale of j1 lowers the cross-validated error from 0.157 to 0.074 mm, but the geometric
    calibration places the robot 12x better than the nominal: a possible cause that names the
    transmission parameters, not a failure (8fee3fe failed it). A scale no robot has of its own
    decides, as a gear ratio 1.02 (the test above)."""
    nominal = robots.cylindrical(masses=True)
    true = rc.perturb_model(nominal, rc.identifiability(nominal).identified, rng=451231239)
    q = rc.random_configurations(nominal, 187, rng=247226356)
    data = rc.sim.measure_campaign(true, q, rc.sim.PRESETS["gears"], rng=843730971, robot_seed=41)
    result = _calibrated(nominal, data)
    cause = _first(result)
    assert cause.hypothesis == "joint scale" and cause.status == "warn" and "transmission" in cause.fix
    assert result.verdict == "warn" and "the robot's own effect, not a mistake in the data" in cause.evidence
    gain, se = result.in_use.improvement
    assert gain > 10 * se


def _combined(seed: int, k: int):
    """Campaign ``k`` of ``robots.combined_effects`` drawn with ``seed``: (effects, nominal, true, imp, data)."""
    for _, effects, j, nominal, true, imp, data in robots.combined_effects(k + 1, np.random.default_rng(seed)):
        if j == k:
            return effects, nominal, true, imp, data


def _placed(true, model, imp, k: int) -> float:
    """The mean distance between where ``model`` puts the marker and where the true robot goes, over the limits."""
    return float(rc.sim.placement_errors(true, model, imp, rng=7, robot_seed=k).mean())


@pytest.mark.parametrize("seed, k, hypothesis", [(3, 86, "drift"), (1, 34, "lost motion")])
def test_a_robots_own_drift_or_lost_motion_warns_and_never_fails_a_calibration_better_in_use(seed, k, hypothesis):
    """Robots with several effects beyond the model (the judgement corpus' combined group): a 7-joint
    arm growing 0.05 % as it warms up over the campaign, and a cylindrical arm whose j1 has 0.028 deg
    of lost motion (its repair 4.02 times better in use). Each geometric calibration places its robot
    many times better than the nominal in truth (1.9 -> 0.1 mm, 1.2 -> 0.15 mm), and the diagnosis
    failed both, the drift as a mistake in the data and the lost motion beyond 4 times its repair's
    error: the robot's own effects warn with their fix, the calibration stands."""
    effects, nominal, true, imp, data = _combined(seed, k)
    assert hypothesis.split()[0].replace("lost", "backlash") in " ".join(effects)
    result = _calibrated(nominal, data)
    cause = _first(result)
    assert cause.hypothesis == hypothesis and cause.status == "warn", cause
    assert result.verdict == "warn" and "the robot's own effect, not a mistake in the data" in cause.evidence
    registered = rc.register_base(nominal, data)
    assert _placed(true, result.calibrated_model, imp, k) < 0.2 * _placed(true, registered, imp, k)


def test_a_scale_no_robot_carries_decides_though_the_calibration_is_close_in_use():
    """The UR5's elbow turning 0.99 times its reading: the geometric calibration is within 2.1 times
    the repair in use (0.231 against 0.109 mm), which alone would only warn, but a 1 % scale is a
    ratio set wrong or readings scaled, and then the model is 9.7 mm wrong where the readings are
    right: it fails."""
    result = rm.gear_ratio("UR5", ratio=0.99, joint=2).run()
    cause = _first(result)
    assert cause.hypothesis == "joint scale" and "elbow" in cause.cause and cause.status == "fail"
    assert result.verdict == "fail" and "within 4 times" not in cause.evidence


@pytest.mark.parametrize("ratio, joint", [(0.99, 2), (1.02, 1)])
def test_a_scale_no_robot_carries_is_named_through_the_robots_own_scatter(ratio, joint):
    """The WAM's j3 turning 0.99 times its reading: its own 1.3 mm scatter keeps the repair's variance
    factor at 2 (below the naming factor 4; e997863 named nothing and passed), but a 1 % scale is
    no robot's and the cross-validated error falls by 10 standard errors: a possible cause. Its j2
    at 1.02: the screen predicts 1.91, below the factor 2 that refits (b01d1cb named nothing), the
    refit 2.3 and 9 standard errors."""
    result = rm.gear_ratio("WAM", ratio=ratio, joint=joint).run()
    cause = _first(result)
    assert cause.hypothesis == "joint scale" and f"j{joint + 1}" in cause.cause and cause.status == "warn"
    assert result.verdict == "warn"


@pytest.mark.parametrize("make, where, moved", [
    (partial(rm.tool_changed, "WAM", row_share=0.3, offset=(0.0, 0.01, 0.0)), "from step 64 on", 10.0),
    (partial(rm.second_nest, "WAM"), "on 54 rows", 8.0),
])
def test_a_marker_moved_is_named_through_the_robots_own_scatter(make, where, moved):
    """On the WAM, the tool 10 mm elsewhere from row 64 on, or the reflector in a second nest 8 mm
    away on a quarter of the rows: the 1.3 mm scatter keeps the repair's variance factor at 2.5 to
    2.9 (below the naming factor 4: b01d1cb passed naming nothing, the model 7.2 and 2.5 mm from the
    clean grid's), while the cross-validated error falls by 11 to 14 standard errors. A marker that
    moves on some rows is never the robot's own: a possible cause. How far it moved is the refit's
    (b01d1cb said 3.94 mm for the tool, from what the calibration had left)."""
    result = make().run()
    cause = _first(result)
    assert cause.hypothesis == "marker moved" and where in cause.cause and cause.status == "warn"
    assert result.verdict == "warn"
    said = float(re.search(r"\(([0-9.]+) mm away\)", cause.cause).group(1))
    assert said == pytest.approx(moved, abs=0.5)     # a few hundred rows at the WAM's 1.3 mm

# -- no cause where there is none -------------------------------------------------------------------------

def test_a_correct_real_calibration_names_nothing_and_says_what_it_cannot_tell():
    """A UR5 grid with one reading mistyped: the calibration sets the point aside and places the robot
    as the clean one does. The blunders are its only cause; the sign of a base-frame length the base
    absorbs (shoulder_pan.r: 32a3abb called it likely wrong) is said not testable."""
    case = rm.reading_typo("UR5")
    result = case.run()
    assert case.model_error(result) < 1e-5
    assert [f.hypothesis for f in result.diagnosis.findings] == ["blunders"]
    assert result.verdict == "warn" and _first(result).status == "warn"
    assert "the sign of the model's shoulder_pan.r: these data cannot tell it, base.z absorbs it" in \
        result.diagnosis.untestable


def test_a_blunder_set_aside_is_the_only_cause():
    """A 10 mm blunder on the UR5 grid: the calibration sets it aside; the diagnosis works on what the
    calibration fitted (32a3abb kept the blunder and named a joint's scale beside it)."""
    _, grid, _, _ = rm.clean("UR5")
    pos = grid.positions.copy()
    pos[17, 0, 0] += 10e-3
    result = _calibrated(real.nominal("UR5"), replace(grid, positions=pos))
    assert [f.hypothesis for f in result.diagnosis.findings] == ["blunders"]
    assert result.diagnosis.rms < 0.07e-3
    # a fact the calibration carries: noted (docs/diagnosis.md), not printed as a possible cause; the
    # check warns, as the outliers check does
    assert _first(result).noted and result.diagnosis.summary.startswith("noted: ")
    summary = rc.report.calibration_summary(result)
    assert "  noted: 1 measured point(s) are blunders" in summary and "possible cause" not in summary
    if importlib.util.find_spec("matplotlib") is not None:       # the report extra draws the report
        assert "<b>Noted:</b> 1 measured point(s) are blunders" in rc.report.render_report(result)
    assert next(c for c in result.checks if c.name == "diagnosis").status == "warn"


def test_a_refit_that_barely_helps_is_not_named():
    """WAM subsets where a joint's scale lowered the residual RMS by 5 to 12 % (32a3abb named it, lifted
    by a fixed bonus for plausible changes): no cause."""
    picked = [(model, s) for robot, k, model, s in real.subsets(12, np.random.default_rng(0))
              if robot == "WAM" and k in (4, 11)]
    for model, subset in picked:
        result = _calibrated(model, subset)
        assert result.diagnosis.findings == () and result.verdict != "fail", result.diagnosis.summary


def test_a_trackers_per_point_deviations_name_no_cause():
    """The WAM grid with each point's deviation stated as its tracker's (15 um + 6 um/m): the robot's
    own scatter is not the stated noise's fault (32a3abb: "the stated noise is too small")."""
    model = real.nominal("WAM")
    grid = real.campaign("WAM", "grid", model)
    sigma = 15e-6 + 6e-6 * np.linalg.norm(grid.positions[:, 0], axis=1)
    result = _calibrated(model, replace(grid, sigma=sigma[:, None]))
    assert result.diagnosis.findings == () and result.verdict == "pass", result.diagnosis.summary


@pytest.mark.parametrize("make", [corpus.quaternion_order, corpus.euler_convention],
                         ids=["quaternion order", "Euler sequence"])
def test_a_wrong_orientation_convention_is_named_not_the_stated_noise(make):
    result, diagnosis = make("6r", 1).run()
    assert diagnosis.cause.hypothesis == "rotation convention" and diagnosis.cause.status == "fail"
    assert result.verdict == "fail"


def test_a_lagging_joint_log_is_not_called_a_joint_scale():
    """On a path, readings that lag the tracker by half a row: named as such, not as a gear ratio."""
    _, diagnosis = corpus.readings_lag("cylindrical", 0).run()
    assert diagnosis.cause.hypothesis == "readings lag"
    assert all(f.hypothesis != "joint scale" for f in diagnosis.findings)


def test_a_repair_that_leaves_a_tenth_of_the_error_in_use_decides_though_something_is_left():
    """A repair dividing the variance 8,800 times and the cross-validated error per pose from 47 to
    0.5 mm, leaving 0.145 mm against the tracker's 0.02 mm (and 2.5 times its fitted errors held
    out): not explained, so a0cec0b only warned (the 6R arm's log half a row behind, its lag then
    screened at 0.49). At most a tenth of the calibration's error in use decides; a sixth warns."""
    rng = np.random.default_rng(3)
    ref = SimpleNamespace(expected=2e-5)
    base = 0.047 + 0.01 * rng.standard_normal(120)
    for held_mean, status in ((0.0005, "fail"), (0.047 / 6, "warn")):
        held = held_mean * (1 + 0.2 * rng.standard_normal(120))
        verdict = reference.judged(ref, 8.8e3, base, held, 1.45e-4, held / 2.5)
        assert not verdict.explained and verdict.gain > reference.REFIT_GAIN_SIGMAS * verdict.se
        assert verdict.status == status, held_mean


@pytest.mark.parametrize("robot, seed", [("6r", 0), ("6r", 1), ("6r", 2), ("cylindrical", 0), ("cylindrical", 1),
                                         ("cylindrical", 2)])
def test_a_lag_is_found_as_it_is_and_decides(robot, seed):
    """Joint logs half a row behind along fast paths: the screen's one step from no lag says 0.41 to
    0.51 of a row, and the readings moved by that left up to 1.85 mm against the tracker's 0.02 mm
    (a0cec0b: two of these six only warned, writing models 56 and 99 mm from the true robots). Refits
    at 0.8, 1 and 1.2 times it and their parabola's vertex find the lag, and the repair decides."""
    result, diagnosis = corpus.readings_lag(robot, seed).run()
    cause = diagnosis.cause
    assert cause.hypothesis == "readings lag" and cause.status == "fail" and result.verdict == "fail"
    lag = float(re.search(r"by about ([0-9.]+) of a row", cause.cause).group(1))
    assert lag == pytest.approx(0.5, abs=0.015)

def test_a_joint_a_whole_turn_off_is_named_as_such():
    """A UR5 joint's readings one turn off: the calibration is the clean one (a turn changes nothing),
    the readings are beyond the limits; named a turn count, not degrees read as radians."""
    case = rm.whole_turn("UR5")
    result = case.run()
    assert case.model_error(result) < 1e-6
    assert _first(result).hypothesis == "whole turns" and "wrist_1 (+1 turn" in _first(result).cause
    limits = next(c for c in result.checks if c.name == "joint readings within the limits")
    assert "whole number of turns" in limits.cause and "degrees" not in limits.cause


# -- mistakes of the model file -------------------------------------------------------------------------------

def test_a_link_off_in_the_model_file_is_named_with_the_value_the_data_say():
    """The UR5's elbow 100 mm off in the model file: the calibration places the robot as the clean one
    (it warns, and writes its model: 32a3abb failed it); the diagnosis names elbow.d and its value."""
    case = rm.link_off("UR5")
    result = case.run()
    assert result.verdict == "warn" and case.model_error(result) < 1e-5
    found = _first(result)
    assert found.hypothesis == "model values" and found.items == ("elbow.d",)
    assert "elbow.d is off: the data say -425.66 mm, the file -325 mm" in found.cause


def test_a_model_file_in_metres_is_the_model_files_mistake():
    """The UR5's DH table in metres where millimetres were declared: named as the model file's unit
    (32a3abb blamed the positions' unit, a fix that makes it worse)."""
    result = rm.model_in_metres("UR5").run()
    found = _first(result)
    assert found.hypothesis == "model unit" and "metres where millimetres were declared" in found.cause
    assert all(f.hypothesis != "unit factor" for f in result.diagnosis.findings)


def test_a_mistake_the_model_absorbs_exactly_prints_no_rounding_as_a_change_in_use():
    """A joint's sign flipped, which the model absorbs with a mirrored joint: the repair fits and
    predicts as well, so the cross-validated error is unchanged; aa41f36 printed the two fits' rounding
    as a fall ("falls by 6.49e-13 mm per pose ... (0.499 standard errors)")."""
    diagnosis = corpus.joint_sign("cylindrical", 8).run()[1]
    found = [f for f in diagnosis.findings if f.hypothesis == "joint sign"]
    assert found and found[0].status == "fail"
    assert "the cross-validated error is unchanged" in found[0].evidence
    for f in diagnosis.findings:
        for fall, before in re.findall(r"(?:falls|rises) by ([-\d.e+]+) mm per pose from ([-\d.e+]+) mm", f.evidence):
            assert float(fall) > 1e-6 * float(before)


def test_the_fall_in_use_is_said_from_the_error_of_the_poses_it_is_taken_over():
    """A missed shot: the repair drops the row that has no pose, so its fall is taken over the other
    poses; the error it falls from is theirs (aa41f36 said "falls by 499 mm per pose from 497 mm",
    the second figure over every pose)."""
    diagnosis = corpus.missed_shot("6r", 7).run()[1]
    said = [re.search(r"falls by ([-\d.e+]+) mm per pose from ([-\d.e+]+) mm", f.evidence) for f in diagnosis.findings]
    assert diagnosis.findings[0].hypothesis == "rows shifted" and said[0]
    for m in filter(None, said):
        assert float(m.group(1)) <= float(m.group(2))


# -- the new hypotheses ------------------------------------------------------------------------------------------

def test_the_nominal_models_predictions_as_measurements_fail():
    result = rm.targets("UR5").run()
    assert result.verdict == "fail" and _first(result).hypothesis == "nominal predictions"


def test_marker_labels_swapped_on_a_third_of_the_poses_fail():
    case = corpus.labels_swapped("6r", 0)
    result, diagnosis = case.run()
    assert result.verdict == "fail" and diagnosis.cause.hypothesis == "labels swapped"
    assert f"on {corpus.N_POSES // 3} of the rows" in diagnosis.cause.cause


def test_a_reflector_in_a_second_nest_on_some_rows_is_named():
    result = rm.second_nest("UR5").run()
    found = _first(result)
    assert result.verdict == "fail" and found.hypothesis == "marker moved" and "on 250 rows" in found.cause
    assert found.fix.startswith("calibrate the 250 rows (")


def test_a_tool_changed_halfway_on_the_real_ur5_fails():
    """A tool 2.2 mm elsewhere from the middle of the UR5 grid: the model is 1.1 mm off in use
    (32a3abb warned and wrote it)."""
    case = rm.tool_changed("UR5", 0.5, (0.002, 0.0, 0.001))
    result = case.run()
    found = _first(result)
    assert result.verdict == "fail" and found.hypothesis == "marker moved" and "from step 500 on" in found.cause
    assert found.fix.startswith("calibrate the rows from step 500 on as a marker of their own")


@pytest.mark.parametrize("joint, name, offset", [(1, "shoulder_lift", 0.1), (2, "elbow", -0.1)])
def test_a_joint_rehomed_partway_on_the_real_ur5_is_named_with_its_step(joint, name, offset):
    """The UR5's shoulder or elbow rehomed at 40 % of the grid (its readings 0.1 deg off from
    then on): the calibration is 0.6 mm from the clean grid's in use. 4befe96 named the measurement
    frame (the tracker bumped), sending the user to the wrong instrument; the joint's own step takes
    one parameter, and its size is the one injected."""
    case = rm.joint_rehomed("UR5", joint=joint, offset_deg=offset)
    result = case.run()
    found = _first(result)
    assert result.verdict == "fail" and found.hypothesis == "joint rehomed" and found.status == "fail"
    said = re.search(rf"from step 400 on, joint {name} reads ([0-9.]+) deg (more|less) than before", found.cause)
    assert said is not None, found.cause
    assert float(said.group(1)) == pytest.approx(abs(offset), rel=0.05)
    assert said.group(2) == ("more" if offset > 0 else "less")
    assert found.fix.startswith(f"home joint {name} again")


def test_a_joint_drifting_on_the_real_ur5_is_named_not_the_instrument():
    """The UR5's shoulder reading 0.1 deg more by the end of the grid than at its start (warming up):
    0.5 mm from the clean grid's model in use. 6d05b8e blamed the measurement frame's drift; the
    joint's own drift is one parameter, and its size the one injected."""
    result = rm.joint_drifting("UR5", joint=1, drift_deg=0.1).run()
    found = _first(result)
    assert result.verdict == "fail" and found.hypothesis == "drift" and found.status == "fail"
    said = re.search(r"joint shoulder_lift's readings drift slowly off its position along the campaign, ([0-9.]+) deg "
                     r"more at step 999 than at step 0", found.cause)
    assert said is not None, found.cause
    assert float(said.group(1)) == pytest.approx(0.1, rel=0.05)
    assert "check joint shoulder_lift's encoder" in found.fix


@pytest.mark.parametrize("robot, make, seed, joint, side", [("6r", corpus.lost_motion, 5, "j1", "approach"),
                                                            ("cylindrical", corpus.lost_motion, 5, "j1", "approach"),
                                                            ("6r", corpus.lost_motion_gravity, 0, "j2", "gravity")])
def test_lost_motion_the_model_leaves_out_is_named_and_calibrating_it_as_said_clears_it(robot, make, seed, joint,
                                                                                         side):
    """A joint stopping 0.05 deg apart (the campaign simulator's lost motion, not the model's) behind
    its last move or under its gravity load, calibrated as rigid: 00ce07c named nothing and passed
    with a misfit four to eight times the noise. The joint's lost motion takes one column (its
    reading's column times its side); its size is the one simulated, and the calibration the fix asks
    for passes with it. The robot's own effect, it warns: the rigid calibration places the robot 4.5 to
    7 times better in use than the nominal (1.5 -> 0.2 mm), within 0.1 to 0.23 mm of the truth."""
    case = make(robot, seed)
    result = case.run()[0]
    found = _first(result)
    assert result.verdict == "warn" and found.hypothesis == "lost motion" and found.items == (joint,)
    assert found.status == "warn" and case.model_error(result) < 0.25e-3
    gain, se = result.in_use.improvement
    assert gain > 10 * se and result.in_use.position_after.rms < 0.25 * result.in_use.position_before.rms
    when = "when approached from either side" if side == "approach" else "as its gravity load turns over"
    said = re.search(rf"joint {joint} stops about ([0-9.]+) deg apart {when}", found.cause)
    assert said is not None, found.cause
    assert float(said.group(1)) == pytest.approx(0.05, rel=0.05)
    assert f"--parameters geometric,backlash --backlash-side {side}" in found.fix
    fixed = _calibrated(case.model.replace(backlash_side=side), case.data, parameters=("geometric", "backlash"))
    assert fixed.verdict == "pass" and not fixed.diagnosis.findings, fixed.diagnosis.summary
    lost = next(e for e in fixed.parameters if e.name == f"{joint}.backlash_theta")
    assert abs(2 * lost.estimate - np.radians(0.05)) < 3 * 2 * lost.std


def test_a_side_that_never_changes_is_no_lost_motion():
    """Every pose approached from above (the file's approach columns all +1) on clean campaigns: a
    lost motion would be a joint offset the calibration already holds, and no size is made up from
    rounding (a screen without the span guard proposed j6 at 9e11 deg here)."""
    for robot in corpus.ROBOTS:
        for seed in range(3):
            model, _, data = corpus._sim(robot, seed)
            data = replace(data, extra={**data.extra, "approach": np.ones_like(data.q)})
            ref = reference.reference(model, data, _calibrated(model, data))
            assert campaign.lost_motion(ref) == [], (robot, seed)


def test_lost_motion_is_judged_by_the_files_approach_columns_when_it_has_them(tmp_path, cli):
    """The rows of the lost-motion campaign shuffled: with the approach directions the robot moved by
    (the file's `approach_` columns) the cause is still named, through the command line as in Python;
    without them the rows' order says nothing of the sides, and nothing is named (no false cause)."""
    case = corpus.lost_motion("6r", 5)
    shuffled = case.data.subset(np.random.default_rng(0).permutation(case.data.n_poses))
    rc.write_model(case.model, tmp_path / "m.yaml")
    rc.write_measurements(shuffled, tmp_path / "d.csv", model=case.model)
    assert "approach_j1" in (tmp_path / "d.csv").read_text().splitlines()[0]
    code, out, _ = cli("calibrate", tmp_path / "m.yaml", tmp_path / "d.csv", "--out", tmp_path / "a")
    assert code == 0 and out.splitlines()[1].startswith("  possible cause: joint j1 stops about 0.0")
    bare = replace(shuffled, extra={k: v for k, v in shuffled.extra.items() if k != "approach"})
    result = _calibrated(case.model, bare)
    assert not any(f.hypothesis == "lost motion" for f in result.diagnosis.findings), result.diagnosis.summary


@pytest.mark.parametrize("joint, name", [(1, "shoulder_lift"), (2, "elbow")])
def test_lost_motion_added_to_the_real_ur5_is_a_possible_cause_with_its_size(joint, name):
    """0.05 deg more lost motion on the UR5's shoulder or elbow, along the grid's own order: the
    calibration stays within 0.07 mm of the clean grid's in use, so the cause warns (a model that
    carries it does better) rather than fails, with the joint and the size injected."""
    result = rm.lost_motion("UR5", joint=joint).run()
    found = _first(result)
    assert result.verdict == "warn" and found.hypothesis == "lost motion" and found.status == "warn"
    said = re.search(rf"joint {name} stops about ([0-9.]+) deg apart", found.cause)
    assert said is not None, found.cause
    assert float(said.group(1)) == pytest.approx(0.05, rel=0.1)


def test_a_prismatic_joint_rehomed_under_three_times_the_noise_is_named():
    """The cylindrical arm's radial (prismatic) joint reads 0.2 mm more from the middle of 60 poses on:
    the fit's residuals stay under 3 times the tracker's, where the whole robot's step is not tried,
    and 4befe96 passed it naming nothing (0.11 mm from the true robot in use, against 0.03 clean)."""
    m = corpus.ROBOTS["cylindrical"]()
    _, d = rc.simulate(m, 60, seed=0, noise=corpus.NOISE)
    q = d.q.copy()
    q[30:, 2] += 0.2e-3
    result = rc.calibrate(m, replace(d, q=q))
    found = _first(result)
    assert result.verdict == "fail" and found.hypothesis == "joint rehomed"
    said = re.search(r"from pose 30 on, joint j3 reads ([0-9.]+) mm more than before", found.cause)
    assert said is not None, found.cause
    assert float(said.group(1)) == pytest.approx(0.2, rel=0.05)


def test_a_validation_file_repeating_the_fitted_one_is_refused():
    """The fitted file's last fifth, written again with fewer digits, given as the validation set."""
    case = rm.validation_repeated("UR5")
    with pytest.raises(InputError, match="repeats a fitted pose"):
        case.run()


# -- the corpus, and the real campaigns ------------------------------------------------------------------------

@pytest.mark.parametrize("robot, seed", [("6r", 7), ("cylindrical", 8)])
def test_the_true_cause_comes_first_in_nearly_every_simulated_mistake(robot, seed):
    cases = corpus.mistakes(robot, seed)
    missed = []
    for case in cases:
        _, diagnosis = case.run()
        if diagnosis.cause is None or diagnosis.cause.hypothesis not in case.expected:
            missed.append((case.name, diagnosis.summary))
    assert len(missed) <= 0.1 * len(cases), missed


@pytest.mark.parametrize("make", corpus.NO_CAUSE, ids=[m.__name__ for m in corpus.NO_CAUSE])
def test_no_cause_is_named_where_there_is_none(make):
    named = []
    for robot in corpus.ROBOTS:
        for seed in (11, 12):
            result, diagnosis = make(robot, seed).run()
            if diagnosis.findings or result.verdict == "fail":
                named.append(diagnosis.summary)
    assert not named, named


@pytest.mark.parametrize("preset", ["elastic", "gears", "cable", "scatter", "thermal"])
def test_no_cause_on_robots_with_effects_beyond_the_model(preset):
    """No mistake is named where the data hold none; an elastic robot calibrated as rigid may be said
    to give under its weight (the robot's own, a warning with compliance as the fix), nothing else."""
    named, elastic = [], rc.sim.PRESETS[preset].elasticity > 0
    for make in corpus.ROBOTS.values():
        m = make(masses=True)
        true, d = rc.simulate(m, corpus.N_POSES, seed=3, noise=corpus.NOISE)
        data = rc.sim.measure_campaign(true, d.q, rc.sim.PRESETS[preset], rng=3, robot_seed=3)
        result = _calibrated(m, data)
        named += [f.cause for f in result.diagnosis.findings
                  if not (elastic and f.hypothesis == "compliance left out" and f.status == "warn")]
    assert not named, named


@pytest.mark.parametrize("robot", ["UR5", "WAM"])
def test_the_real_test_poses_get_no_false_cause(robot):
    model = real.nominal(robot)
    result = _calibrated(model, real.campaign(robot, "random", model))
    assert result.diagnosis.findings == () and result.verdict != "fail", result.diagnosis.summary


def test_a_large_campaign_is_diagnosed_on_a_bounded_share_of_its_poses():
    m = corpus.ROBOTS["6r"]()
    _, data = rc.simulate(m, 3000, seed=4, noise=corpus.NOISE)
    result = _calibrated(m, replace(data, positions=data.positions * [-1, 1, 1]))
    assert _first(result).hypothesis == "mirrored frame"


# -- the pieces ----------------------------------------------------------------------------------------------

def test_shifted_rows_pair_each_reading_with_the_point_it_was_measured_at():
    from robocal._diagnosis import campaign

    # rows 3.. of a file hold the point of the pose one row later: reading 4 goes with point 3
    q_rows, p_rows = campaign.shifted_rows(8, 3, 1)
    assert dict(zip(p_rows.tolist(), q_rows.tolist())) == {0: 0, 1: 1, 2: 2, 3: 4, 4: 5, 5: 6, 6: 7}
    q_rows, p_rows = campaign.shifted_rows(6, 2, -1)
    assert dict(zip(p_rows.tolist(), q_rows.tolist())) == {0: 0, 1: 1, 3: 2, 4: 3, 5: 4}


def test_the_rigid_match_from_sums_is_the_closed_form_registration():
    from robocal._diagnosis import rigid

    rng = np.random.default_rng(3)
    P = rng.normal(size=(30, 1, 3))
    Q = Rotation.from_rotvec([0.3, -0.2, 0.5]).apply(P[:, 0])[:, None] + [1.0, 2.0, 3.0] + rng.normal(0, 1e-3, P.shape)
    _, rssd = Rotation.align_vectors(Q[:, 0] - Q[:, 0].mean(0), P[:, 0] - P[:, 0].mean(0))
    mask = np.ones((30, 1), bool)
    assert rigid.rigid_misfit(rigid.moments(P, Q, mask).sum(0)) == pytest.approx(rssd ** 2, rel=1e-6)
    mirrored = rigid.rigid_misfit(rigid.moments(P, Q * [-1, 1, 1], mask).sum(0))
    assert mirrored > 1e4 * rssd ** 2        # a mirror image is no rigid motion
    moved = rigid.registered(P, Q, mask)
    assert np.sum((moved - Q) ** 2) == pytest.approx(rssd ** 2, rel=1e-6)


def test_the_report_shows_the_decisive_cause(tmp_path, cli):
    pytest.importorskip("matplotlib")
    case = corpus.missed_shot("6r", 0)
    model, data = _files(tmp_path, case.model, case.data)
    code, out, _ = cli("calibrate", model, data, "--out", tmp_path / "out", "--report", "--diagnose")
    assert code == 3 and "DECISIVE: rows from pose 20 on hold the next pose's point" in out
    assert "  refitted: " in out
    report = (tmp_path / "out" / "report.html").read_text()
    assert 'data-key="diagnosis.0"' in report and "<b>Decisive:</b>" in report and "pose 20 on hold" in report


def test_a_unit_repaired_says_what_is_left_in_that_unit():
    """Millimetres read as metres: the refit's residual was shown in the declared unit only (65.1 mm on
    the UR5 grid, where the instrument's is 0.065 mm), a thousand times what the repair leaves."""
    model = robots.arm6r()
    _, data = rc.simulate(model, 80, seed=4, noise=2e-5)
    wrong = replace(data, positions=data.positions * 1e3)
    first = _first(_calibrated(model, wrong))
    assert first.hypothesis == "unit factor" and first.status == "fail"
    left = float(re.search(r"refitted in that unit: .*?([\d.e+-]+) mm RMS per axis in it, ", first.evidence).group(1))
    assert 0.01 < left < 0.04, first.evidence         # the 0.02 mm noise, in millimetres
    # what decides first: the figures in the declared unit beside it are no better, which read as
    # evidence against the cause when they came first
    assert first.evidence.index("it fits as well") < first.evidence.index("as declared"), first.evidence


def test_joints_that_give_under_the_robots_weight_are_named_with_compliance_as_the_fix():
    """An elastic 6R arm with masses calibrated as rigid (the judgement corpus' combined group, seed
    1, campaign 20): the diagnosis named a joint scale of 1.0004 with the fix "correct the gear ratio",
    a cause that is not there, for no hypothesis let the joints give under the robot's own weight.
    Each loaded joint's reading column times its gravity load now does (all together, as a
    calibration with compliance frees them); it comes first, and the calibration it asks for places
    the robot better in truth than the rigid one."""
    effects, nominal, true, imp, data = _combined(1, 20)
    assert "elasticity" in effects and "gears" not in effects
    rigid = _calibrated(nominal, data)
    cause = _first(rigid)
    assert cause.hypothesis == "compliance left out" and cause.status == "warn", rigid.diagnosis.summary
    assert cause.fix == "calibrate it (--parameters geometric,compliance)"
    elastic = _calibrated(nominal, data, parameters=("geometric", "compliance"))
    assert not any(f.hypothesis == "compliance left out" for f in elastic.diagnosis.findings)
    assert _placed(true, elastic.calibrated_model, imp, 20) < 0.5 * _placed(true, rigid.calibrated_model, imp, 20)


def test_a_rigid_robot_with_masses_is_not_said_to_give_under_its_weight():
    """The 6R and cylindrical arms with masses, clean or with a rigid robot's effects beyond the model
    (gear errors, scatter, thermal growth), calibrated as rigid: no compliance is named where the
    robot has none."""
    campaigns = list(robots.beyond_model(6, np.random.default_rng(3), presets=("gears", "scatter", "thermal")))
    for model in (robots.arm6r(masses=True), robots.cylindrical(masses=True)):
        campaigns.append(("clean", "none", 0, model, rc.simulate(model, 120, seed=4)[1]))
    for name, preset, k, model, data in campaigns:
        assert model.has_masses
        result = _calibrated(model, data)
        assert not any(f.hypothesis == "compliance left out" for f in result.diagnosis.findings), (name, preset, k)
