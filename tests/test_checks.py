"""Results that can say they are wrong: a corpus of realistic mistakes, each caught through the
command line; no false alarm on clean campaigns; outliers named; weak parameters handled."""

import json
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from conftest import z_scores
from robots import DEG, arm6r, cylindrical

import robocal as rc

NOISE = 2e-5


def _campaign(make=arm6r, n=48, seed=0, **kw):
    m = make(**kw)
    true, data = rc.simulate(m, n, seed=seed, noise=NOISE)
    return m, true, data


def _csv(data, model, units="mm-deg") -> list[str]:
    return rc.io.measurements_to_csv(data, model=model, units=units).splitlines()


def _rename(lines, old, new, *, where=lambda c: True):
    """The header with ``old`` replaced by ``new`` in the columns ``where`` accepts."""
    head = [new.join(c.rsplit(old, 1)) if c.endswith(old) and where(c) else c for c in lines[0].split(",")]
    return [",".join(head)] + lines[1:]


def _set(lines, row, column, value):
    head = lines[0].split(",")
    cells = lines[row + 1].split(",")
    cells[head.index(column)] = str(value)
    return lines[:row + 1] + [",".join(cells)] + lines[row + 2:]


def _swap_columns(lines, a, b):
    head = lines[0].split(",")
    i, j = head.index(a), head.index(b)
    head[i], head[j] = head[j], head[i]
    return [",".join(head)] + lines[1:]


def _map_column(lines, column, f):
    """The CSV lines with ``f`` applied to every value of ``column``."""
    k = lines[0].split(",").index(column)
    rows = [line.split(",") for line in lines[1:]]
    for r in rows:
        r[k] = repr(float(f(float(r[k]))))
    return [lines[0]] + [",".join(r) for r in rows]


def _calibrate(tmp_path, cli, model, lines, *args):
    """Run ``robocal calibrate`` on ``model`` and the CSV ``lines``; (code, stdout, stderr, result dict)."""
    rc.write_model(model, tmp_path / "model.yaml", force=True)
    (tmp_path / "data.csv").write_text("\n".join(lines) + "\n")
    out = tmp_path / "out"
    code, stdout, stderr = cli("calibrate", tmp_path / "model.yaml", tmp_path / "data.csv", "--out", out, "--force",
                               *args)
    result = json.loads((out / "result.json").read_text()) if (out / "result.json").exists() else None
    return code, stdout, stderr, result


def _failed(result) -> dict:
    return {c["name"]: c for c in result["checks"] if c["status"] == "fail"}


# what catches a mistake in the data or the model once solved: what the robot does over its workspace,
# the accuracy in use, or a solve that cannot settle (the fit's size alone never fails a calibration)
CAUGHT = {"plausible changes", "accuracy in use", "solver convergence", "orientation fit"}


def _assert_caught(code, out, result):
    """Exit code 3 and verdict fail from a check that judges the solved model (``CAUGHT``)."""
    assert code == 3 and result["verdict"] == "fail", out
    assert set(_failed(result)) & CAUGHT, list(_failed(result))
    assert "verdict: FAIL" in out


def _assert_fails(code, out, result, check, *words):
    """Exit code 3, verdict fail, ``check`` failed with ``words`` in what it says, and no calibrated model."""
    assert code == 3, out
    assert result["verdict"] == "fail" and check in _failed(result), [c["name"] for c in result["checks"]]
    said = json.dumps(_failed(result)[check])
    assert all(w in said for w in words), said
    assert "verdict: FAIL" in out


def _assert_warns(code, out, result, check, *words):
    """A model the data place right despite a large change: exit 0, verdict warn, ``check`` warns with
    ``words`` in what it says, and the calibrated model is written."""
    assert code == 0 and result["verdict"] == "warn", out
    said = json.dumps(next(c for c in result["checks"] if c["name"] == check))
    assert '"status": "warn"' in said and all(w in said for w in words), said
    assert "verdict: warn" in out


def test_clean_campaign_passes_and_writes_its_verdict(tmp_path, cli):
    m, true, data = _campaign()
    code, out, err, result = _calibrate(tmp_path, cli, m, _csv(data, m))
    assert code == 0 and result["verdict"] == "pass", out
    assert "verdict: pass" in out
    assert "verdict: pass" in (tmp_path / "out" / "calibrated.yaml").read_text().replace("'", "")


# -- the corpus: each mistake is an error before solving or a failed check naming the cause ---------

def _markers_only(column: str) -> bool:
    return column.startswith("tool")


# (mistake, how the file is written, header edit: old suffix, new suffix, columns; the failed check, its words)
UNIT_MISTAKES = [
    ("metres declared as millimetres", "m-deg", ("_m", "_mm", _markers_only),
     "measured points against the robot's size", "metres declared as millimetres"),
    ("millimetres declared as metres", "mm-deg", ("_mm", "_m", _markers_only),
     "measured points against the robot's size", "metres declared as millimetres"),
    ("degrees declared as radians", "mm-deg", ("_deg", "_rad", lambda c: True),
     "joint readings within the limits", "degrees declared as radians"),
    ("radians declared as degrees", "mm-rad", ("_rad", "_deg", lambda c: True),
     "joint reading units", "radians declared as degrees"),
]


@pytest.mark.parametrize("mistake, units, edit, check, words", UNIT_MISTAKES, ids=[m[0] for m in UNIT_MISTAKES])
def test_a_unit_declared_wrong(tmp_path, cli, mistake, units, edit, check, words):
    m, _, data = _campaign()
    old, new, where = edit
    lines = _rename(_csv(data, m, units=units), old, new, where=where)
    code, out, _, result = _calibrate(tmp_path, cli, m, lines)
    _assert_fails(code, out, result, check, words)
    assert not (tmp_path / "out" / "calibrated.yaml").exists()
    # asked for anyway, the calibrated model says it failed, and still reads
    code, out, _, result = _calibrate(tmp_path, cli, m, lines, "--write-failed")
    written = tmp_path / "out" / "calibrated.yaml"
    assert code == 3 and "verdict: fail" in written.read_text() and check in written.read_text()
    rc.read_model(written)


def test_one_joint_in_the_wrong_unit(tmp_path, cli):
    m, _, data = _campaign()
    code, out, _, result = _calibrate(tmp_path, cli, m, _map_column(_csv(data, m), "j4_deg", np.radians))
    _assert_caught(code, out, result)
    units = next(c for c in result["checks"] if c["name"] == "joint reading units")
    assert units["status"] == "warn" and units["items"] == ["j4"]


def test_prismatic_readings_in_millimetres_declared_as_metres(tmp_path, cli):
    m, _, data = _campaign(cylindrical)
    lines = _rename(_csv(data, m), "_mm", "_m", where=lambda c: c.startswith("j"))
    code, out, _, result = _calibrate(tmp_path, cli, m, lines)
    _assert_fails(code, out, result, "joint readings within the limits", "j2")


def test_sign_error_in_the_model(tmp_path, cli):
    m, _, data = _campaign()
    lines = _csv(data, m)
    wrong = m.replace(frames=tuple(replace(f, d=-f.d) if f.name == "j3" else f for f in m.frames))
    code, out, _, result = _calibrate(tmp_path, cli, wrong, lines)
    # the data correct the file's sign and the model places the robot right in use: said, not failed
    _assert_warns(code, out, result, "plausible changes", "moves the tool up to", "tolerances.")
    assert (tmp_path / "out" / "calibrated.yaml").exists()


def test_two_markers_swapped(tmp_path, cli):
    m, _, data = _campaign(markers=(("tool", (0.05, 0.02, 0.12)), ("tool2", (-0.06, 0.03, 0.1))))
    lines = _csv(data, m)
    for axis in "xyz":
        lines = _swap_columns(lines, f"tool_{axis}_mm", f"tool2_{axis}_mm")
    code, out, _, result = _calibrate(tmp_path, cli, m, lines, "--known", "markers")
    _assert_caught(code, out, result)


def test_reading_beyond_its_limit_is_named(tmp_path, cli):
    m, _, data = _campaign()
    m = m.replace(joint_limits=m.joint_limits[:5] + ((-360 * DEG, 360 * DEG),))
    lines = _set(_csv(data, m), 5, "j6_deg", 400.0)
    code, out, _, result = _calibrate(tmp_path, cli, m, lines)
    _assert_fails(code, out, result, "joint readings within the limits", "pose 5: j6 = 400 deg")


def test_joint_order_swapped(tmp_path, cli):
    m, _, data = _campaign()
    lines = _swap_columns(_csv(data, m), "j2_deg", "j3_deg")
    code, out, _, result = _calibrate(tmp_path, cli, m, lines)
    assert code == 3 and result["verdict"] == "fail"


def test_joint_sign_reversed(tmp_path, cli):
    m, _, data = _campaign()
    code, out, _, result = _calibrate(tmp_path, cli, m, _map_column(_csv(data, m), "j2_deg", lambda v: -v))
    assert code == 3 and (CAUGHT | {"joint readings within the limits"}) & set(_failed(result))


def test_marker_on_the_wrong_frame(tmp_path, cli):
    m, _, data = _campaign()
    wrong = m.replace(markers=(replace(m.markers[0], frame=4),))
    code, out, _, result = _calibrate(tmp_path, cli, wrong, _csv(data, m))
    _assert_caught(code, out, result)


def test_file_from_another_robot(tmp_path, cli):
    m, _, _ = _campaign()
    bigger = m.replace(frames=tuple(replace(f, d=f.d * 1.3, r=f.r * 1.3) for f in m.frames))
    _, data = rc.simulate(bigger, 48, seed=3, noise=NOISE)
    code, out, _, result = _calibrate(tmp_path, cli, m, _csv(data, bigger))
    # the model becomes the other robot's and places it right in use: said, not failed
    _assert_warns(code, out, result, "plausible changes", "moves the tool up to", "tolerances.")


def test_pose_column_shifted_by_one_row(tmp_path, cli):
    m, _, data = _campaign()
    lines = _csv(data, m)
    head = lines[0].split(",")
    joints = [k for k, c in enumerate(head) if c.startswith("j")]
    rows = [line.split(",") for line in lines[1:]]
    shifted = [[(rows[(i + 1) % len(rows)][k] if k in joints else c) for k, c in enumerate(r)]
               for i, r in enumerate(rows)]
    code, out, _, result = _calibrate(tmp_path, cli, m, [lines[0]] + [",".join(r) for r in shifted])
    _assert_caught(code, out, result)


def test_instrument_axes_swapped(tmp_path, cli):
    m, _, data = _campaign()
    lines = _swap_columns(_csv(data, m), "tool_x_mm", "tool_y_mm")   # a mirrored frame: no rotation fits
    code, out, _, result = _calibrate(tmp_path, cli, m, lines)
    _assert_caught(code, out, result)


def test_blunder_is_named_and_refitted_or_failed(tmp_path, cli):
    m, _, data = _campaign()
    lines = _csv(data, m)
    value = float(lines[8].split(",")[lines[0].split(",").index("tool_x_mm")])
    lines = _set(lines, 7, "tool_x_mm", value + 5.0)
    code, out, _, result = _calibrate(tmp_path, cli, m, lines)
    outliers = next(c for c in result["checks"] if c["name"] == "outliers")
    assert code == 0 and result["verdict"] == "warn" and result["loss"] == "linear"
    assert outliers["status"] == "warn" and outliers["items"][0].startswith("pose 7, marker tool")
    assert "set aside" in outliers["summary"] and any("set aside" in n for n in result["notes"])
    # the fit without that point is the one its deletion gives
    deleted = lines[:8] + lines[9:]
    (tmp_path / "deleted").mkdir()
    _, _, _, without = _calibrate(tmp_path / "deleted", cli, m, deleted)
    for a, b in zip(result["parameters"], without["parameters"]):
        assert a["name"] == b["name"] and abs(a["estimate"] - b["estimate"]) < 1e-3 * b["std"] + 1e-12
    code, out, _, result = _calibrate(tmp_path, cli, m, lines, "--on-outliers", "flag")
    outliers = next(c for c in result["checks"] if c["name"] == "outliers")
    assert outliers["status"] == "warn" and "kept in the fit" in outliers["summary"]
    # flag names them and warns, it does not fail; refit sets them aside with the linear loss, no
    # robust loss: the help and docs/cli.md say so
    assert code == 0 and result["verdict"] == "warn" and not any("set aside" in n for n in result["notes"])
    _, shown, _ = cli("calibrate", "--help")
    shown = " ".join(shown[shown.index("--on-outliers {refit,flag}\n"):].split("\n  --")[0].split())
    row = next(line for line in (Path(__file__).resolve().parents[1] / "docs" / "cli.md").read_text().splitlines()
               if line.startswith("| `--on-outliers"))
    for said in (shown, row):
        assert "set aside" in said and "robust loss" not in said and "fail" not in said.replace("does not fail", "")


def test_noise_only_data_calibrated_with_compliance(tmp_path, cli):
    m = arm6r(masses=True)
    true, data = rc.simulate(m, 60, seed=5, noise=NOISE)        # a rigid robot
    code, out, _, result = _calibrate(tmp_path, cli, m, _csv(data, m), "--parameters", "geometric,compliance")
    support = next(c for c in result["checks"] if c["name"] == "estimates supported by the data")
    # said, not warned: compliances at zero do the robot in use no harm, and the accuracy in use judges it
    assert code == 0 and support["status"] == "pass", out
    assert "no compliance differs from zero" in support["summary"] and "--compare" in support["fix"]


def test_marker_never_measured_is_named(tmp_path, cli):
    m, _, data = _campaign(markers=(("tool", (0.05, 0.02, 0.12)), ("tool2", (-0.06, 0.03, 0.1))))
    lines = _csv(data, m)
    keep = [k for k, c in enumerate(lines[0].split(",")) if not c.startswith("tool2")]
    lines = [",".join(c for k, c in enumerate(line.split(",")) if k in keep) for line in lines]
    code, out, _, result = _calibrate(tmp_path, cli, m, lines)
    check = next(c for c in result["checks"] if c["name"] == "every marker measured")
    assert code == 0 and result["verdict"] == "warn" and check["items"] == ["tool2"]
    assert not any(p["name"].startswith("tool2") for p in result["parameters"])
    assert "add poses" not in json.dumps(result["checks"])


def test_too_few_poses_and_a_bad_cell_stop_before_solving(tmp_path, cli):
    m, _, data = _campaign()
    lines = _csv(data, m)
    code, _, err, result = _calibrate(tmp_path, cli, m, lines[:6])
    assert code == 2 and result is None and "distinct poses are needed" in err
    code, _, err, result = _calibrate(tmp_path, cli, m, _set(lines, 3, "tool_y_mm", "nan"))
    assert code == 2 and result is None and "line 5, column 'tool_y_mm'" in err


def test_wrong_orientation_convention_fails(tmp_path, cli):
    m, _, _ = _campaign()
    true, data = rc.simulate(m, 40, orientation=True, noise=NOISE, noise_rot=1e-4, seed=2)
    # written as intrinsic XYZ Euler angles, declared extrinsic
    lines = [line if not line.startswith("# orientation") else "# orientation: euler:xyz" for line in
             rc.io.measurements_to_csv(data, model=m, orientation="euler:XYZ").splitlines()]
    code, out, _, result = _calibrate(tmp_path, cli, m, lines)
    _assert_fails(code, out, result, "orientation fit", "orientation convention")


# -- weakly identifiable parameters ------------------------------------------------------------------

def _held_out_rms(result, data):
    ev = rc.forward_kinematics(result.calibrated_model, data.q)
    return float(np.sqrt(np.mean(np.sum((ev.positions - data.positions) ** 2, axis=2))))


def test_two_step_workflow_gives_the_one_step_answer():
    # the tool point on the last axis: the one-step analysis eliminates what it cannot see
    m = arm6r(markers=(("tool", (0.0, 0.0, 0.12)),))
    true, data = rc.simulate(m, 60, seed=11, noise=NOISE)
    _, held = rc.simulate(m, 300, seed=11, noise=NOISE)
    held = rc.measure(true, held.q, noise=NOISE, rng=12)
    one = rc.calibrate(m, data)
    placed = rc.calibrate(m, data, parameters=("base", "markers")).calibrated_model   # step one
    assert np.hypot(*placed.markers[0].position[:2]) > 1e-5       # the tool left the axis
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        two = rc.calibrate(placed, data)                             # step two, from that model
        kept = rc.calibrate(placed, data, weak="flag")
    assert set(two.parameter_names) == set(one.parameter_names)
    ident = next(c for c in two.checks if c.name == "identifiability at these poses")
    assert ident.items and "weakly identifiable" in ident.summary and two.verdict != "fail"
    assert abs(_held_out_rms(two, held) - _held_out_rms(one, held)) < 0.1 * _held_out_rms(one, held)
    # kept instead, they are flagged and their estimates are poor
    flagged = next(c for c in kept.checks if c.name == "identifiability at these poses")
    assert flagged.status == "warn" and kept.verdict != "pass"


def test_poses_that_barely_turn_the_tool_name_its_weak_parameters():
    m = arm6r()
    rng = np.random.default_rng(4)
    q = rc.random_configurations(m, 60, rng=rng)
    q[:, 3:] = rng.uniform(-2 * DEG, 2 * DEG, (60, 3))              # the wrist barely moves
    true = rc.perturb_model(m, rc.identifiability(m).identified, rng=5)
    data = rc.measure(true, q, noise=NOISE, rng=6)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = rc.calibrate(m, data)
    ident = next(c for c in res.checks if c.name == "identifiability at these poses")
    units = next(c for c in res.checks if c.name == "joint reading units")
    assert res.verdict == "warn" and units.items == ("j4", "j5", "j6") and "weakly identifiable" in ident.summary
    # the tool's length is kept, pinned down; what the poses confound with it goes instead
    assert res.estimate("tool.z").std < 1e-3 and abs(res.estimate("tool.z").change - (
        true.markers[0].position[2] - m.markers[0].position[2])) < 3 * res.estimate("tool.z").std


# -- false alarms, outliers ----------------------------------------------------------------------------

def _clean(make, poses, compliance, seed):
    m = make(masses=compliance)
    params = ("geometric", "compliance") if compliance else ("geometric",)
    kw = {}
    if compliance:
        rng = np.random.default_rng(seed)
        ks = [n for n in rc.identifiability(m, parameters=params).identified
              if rc.kinematics.parameter_layout(m)[n].family == "compliance"]
        kw = dict(true_compliance={n: rng.uniform(2e-6, 1e-5) for n in ks})
    true, data = rc.simulate(m, poses, parameters=params, seed=1000 + seed, noise=NOISE, **kw)
    return rc.calibrate(m, data, parameters=params)


def test_clean_campaigns_raise_no_false_alarm():
    verdicts = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for make in (arm6r, cylindrical):
            for poses in (48, 500):
                for compliance in (False, True):
                    verdicts += [_clean(make, poses, compliance, seed).verdict for seed in range(13)]
    assert len(verdicts) >= 100
    assert verdicts.count("fail") == 0 and verdicts.count("warn") <= 0.05 * len(verdicts)


def _with_blunders(m, seed, n_bad):
    """A 48-pose campaign of a perturbed ``m`` with ``n_bad`` points moved 5 mm in random directions;
    (truth, data, the rows moved)."""
    true, data = rc.simulate(m, 48, seed=seed, noise=NOISE)
    rng = np.random.default_rng(seed)
    rows = rng.choice(48, size=n_bad, replace=False)
    direction = rng.normal(size=(n_bad, 3))
    pos = data.positions.copy()
    pos[rows, 0] += 5e-3 * direction / np.linalg.norm(direction, axis=1, keepdims=True)
    return true, replace(data, positions=pos), rows


def _count_campaigns(first_seed, n_bad, holds) -> int:
    """In how many of 100 blundered campaigns ``holds(result, truth, model, moved rows)`` is true."""
    m = arm6r()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        campaigns = (_with_blunders(m, first_seed + seed, n_bad) for seed in range(100))
        return sum(bool(holds(rc.calibrate(m, data), true, m, rows)) for true, data, rows in campaigns)


def test_one_blunder_is_named_in_nearly_every_campaign():
    def named(res, true, m, rows):
        check = next(c for c in res.checks if c.name == "outliers")
        return any(item.startswith(f"pose {rows[0]}, marker tool") for item in check.items)
    assert _count_campaigns(2000, 1, named) >= 95


def test_robust_refit_keeps_the_truth_within_three_sigma_with_gross_outliers():
    def recovered(res, true, m, rows):                  # 3 of 48 points: about 5 %
        return any("set aside" in n for n in res.notes) and np.abs(z_scores(res, true, m)).max() < 3.0
    assert _count_campaigns(3000, 3, recovered) >= 90


def test_fair_before_registers_base_and_tool():
    m, true, data = _campaign(seed=7)
    far = m.replace(base_position=tuple(np.add(m.base_position, (1.2, -0.8, 0.5))))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = rc.calibrate(far, data)
    # the nominal geometry with its base and tool fitted: millimetres, not the metres of the guess
    assert res.stats.fit_before.mean < 10e-3
    assert any("base and markers fitted" in n for n in res.notes)


def test_weak_parameters_are_judged_at_the_scatter_the_fit_shows():
    """Residuals of the robot's own size and no limit given: the shipped TH8 campaign holds back what
    the limit-aware calibration holds back (each choice by the cross-validated error); the fit says
    the scatter beyond the instrument is the robot's own; with the limit, reached in use, it passes."""
    th8 = Path(__file__).resolve().parents[1] / "examples" / "th8"
    nominal = rc.read_model(th8 / "model.yaml")
    fit, val = rc.split_sets(rc.read_measurements(th8 / "measurements.csv", nominal))
    kw = dict(validation=val, parameters=("geometric", "compliance"), known=("markers",))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        plain, aware = rc.calibrate(nominal, fit, **kw), rc.calibrate(nominal, fit, limit=0.483e-3, **kw)

    def weak(r):
        return {a.name for a in r.identifiability.eliminated if a.reason.startswith("is weakly identifiable")}
    assert weak(plain) and weak(plain) == weak(aware)
    # residuals 13 times the tracker's, as large on held-out poses, and better in use: the robot's own
    # scatter, said by the fit check as a pass
    fit_check = next(c for c in plain.checks if c.name == "fit against the instrument")
    assert fit_check.status == "pass" and "the robot's own scatter" in fit_check.summary
    assert plain.verdict == "pass" and any("model choice by cross-validated error" in n for n in plain.notes)
    assert aware.verdict == "pass" and aware.limit.reached


def test_outlier_bar_rises_with_the_campaign_so_clean_noise_names_no_point():
    """200,000 clean points: a fixed bar of 5 would name about three of them; the risen one names
    none, and still names a 10-sigma blunder among them."""
    from robocal.identification import Noise, outlier_bar, outlier_check
    n = 200_000
    residuals = np.random.default_rng(7).normal(scale=NOISE, size=(n, 3))
    labels = [f"pose {i}, marker tool" for i in range(n)]
    assert (np.linalg.norm(residuals, axis=1) / NOISE > 5.0).sum() >= 1      # what a fixed bar would name
    check, out = outlier_check(residuals, None, Noise.of(position=NOISE), labels)
    assert check.status == "pass" and not out.any() and outlier_bar(n) > 5.5
    residuals[123] = [10 * NOISE, 0, 0]
    check, out = outlier_check(residuals, None, Noise.of(position=NOISE), labels)
    assert check.status == "warn" and np.flatnonzero(out).tolist() == [123] and check.items[0].startswith("pose 123,")


def test_an_unconverged_fit_names_what_stopped_it():
    """The caller's budget, a model the data barely determine, or a far start: each its own cause,
    and a registered base offered only where the fit did not start from one."""
    from robocal._identification.checks import convergence_check

    stopped = dict(success=False, message="the maximum number of function evaluations is exceeded", nfev=5800)
    crawl = convergence_check(**stopped, n_free=48, n_rows=60, can_register=True)
    assert crawl.status == "fail"
    assert crawl.cause == "a model these data barely determine: 48 parameters on 60 equations"
    assert "--register-base" not in crawl.fix and "fewer parameters" in crawl.fix
    far = convergence_check(**stopped, n_free=30, n_rows=300, can_register=True)
    assert far.cause.startswith("a start far from the truth") and far.fix.endswith("(--register-base)")
    registered = convergence_check(**stopped, n_free=30, n_rows=300, can_register=False)
    assert "--register-base" not in registered.fix
    assert convergence_check(True, "", 4, n_free=48, n_rows=60, can_register=True).status == "pass"
    # through calibrate: the budget it was given is named, not the data
    root = Path(__file__).resolve().parent.parent / "examples" / "th8"
    model = rc.read_model(root / "model.yaml")
    data = rc.io.read_measurements(root / "measurements.csv", model)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rc.RobocalWarning)
        result = rc.calibrate(model, data, initial_base="register", max_nfev=2)
    check = next(c for c in result.checks if c.name == "solver convergence")
    assert check.status == "fail" and check.cause == "the 2 evaluations of the residuals max_nfev allows", check


def test_a_model_written_from_a_failed_calibration_is_named_where_it_is_used(tmp_path, cli):
    """--write-failed writes the model marked as failed; compensate and export used it without a word
    (a URDF made from it cannot carry the mark)."""
    m, _, data = _campaign()
    lines = _rename(_csv(data, m), "_mm", "_m", where=_markers_only)
    code, *_ = _calibrate(tmp_path, cli, m, lines, "--write-failed")
    written = tmp_path / "out" / "calibrated.yaml"
    assert code == 3 and written.exists()
    targets = tmp_path / "targets.csv"
    targets.write_text("pose," + ",".join(f"{j}_rad" for j in m.joint_names) + "\n"
                       + "".join(f"T{k}," + ",".join(f"{v:.9f}" for v in q) + "\n" for k, q in enumerate(data.q[:3])))
    for args in (("compensate", tmp_path / "model.yaml", written, targets, "--out", tmp_path / "c.csv"),
                 ("export", written, "--format", "urdf", "--out", tmp_path / "m.urdf")):
        code, _, err = cli(*args)
        assert code == 0 and f"{written}: a calibration that failed" in err, err
    code, _, err = cli("export", tmp_path / "model.yaml", "--format", "urdf", "--out", tmp_path / "n.urdf")
    assert code == 0 and "failed" not in err
