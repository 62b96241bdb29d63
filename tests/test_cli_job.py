"""The whole job from the command line: plan, compensate, export, import-dh, and the rough edges."""

from __future__ import annotations

import csv
import json
import re
import subprocess
import sys
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_one_line_error
from robots import arm6r

import robocal as rc

ROOT = Path(__file__).resolve().parent.parent
TH8 = str(ROOT / "examples/th8/model.yaml")
TRUE = str(ROOT / "examples/th8/true_model.yaml")


def _rows(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(line for line in fh if not line.startswith("#")))


def test_plan_writes_poses_ready_to_measure(tmp_path, cli):
    out = tmp_path / "poses.csv"
    code, printed, err = cli("plan", TH8, "--poses", 12, "--n-candidates", 300, "--out", out)
    assert code == 0, err
    rows = _rows(out)
    assert len(rows) == 12 and rows[0]["tool_x_mm"] == ""
    assert "parameters identified" in printed and "held-out poses" in printed and "j2.d" in printed
    # the written poses read back as targets, within the joint limits
    model = rc.read_model(TH8)
    q = rc.read_measurements(out, model, targets=True).q
    assert np.all((q >= model.lower_limits) & (q <= model.upper_limits))


def test_plan_predictions_agree_with_calibrations_on_the_same_poses():
    """Predicted standard deviations and held-out error against calibrations with simulated noise,
    averaged over seeds (a small arm, few poses: cheap). benchmarks/plan_prediction.py runs 20 seeds."""
    from robocal.sim import simulate

    model = arm6r()
    noise = 5e-5
    sel = rc.select_poses(model, 20, n_candidates=400, rng=0)
    pred = rc.predict_campaign(model, sel.q, noise=noise, n_workspace=400, rng=0)
    ratios, held = [], []
    for seed in range(6):
        true, data = simulate(model, q=sel.q, noise=noise, seed=seed)
        _, validation = simulate(model, 200, noise=noise, seed=100 + seed)
        validation = rc.sim.measure(true, validation.q, noise=noise, rng=seed)
        res = rc.calibrate(model, data, validation=validation, noise=rc.Noise.of(position=noise))
        got = {p.name: p.std for p in res.parameters}
        ratios.append([got[n] / s for n, s in zip(pred.parameters, pred.std) if n in got])
        held.append(res.stats.validation_after.rms)
    assert abs(np.mean(ratios) - 1) < 0.2
    assert abs(np.mean(held) / pred.held_out_rms - 1) < 0.2


def test_a_plan_holds_at_nominal_what_the_calibration_holds_and_predicts_the_rest():
    """The Panda of tests/data/real with its ball near the last axis: the plan listed panda_link7.alpha
    and .d (and panda_link6.theta and .r with them) with predicted standard deviations of degrees
    and centimetres, while the calibration of the same poses holds the first two at nominal and
    pins the rest down. Now the plan holds the same two, and predicts the others as reported."""
    from robocal.sim import simulate

    real = Path(__file__).parent / "data" / "real" / "mukca"
    model = rc.read_urdf(real / "panda.urdf", tip_link="ball_link", markers=[("ball", (0.0, 0.0, 0.0))])
    noise = 2e-5
    sel = rc.select_poses(model, 30, n_candidates=1000, rng=0)
    pred = rc.predict_campaign(model, sel.q, noise=noise, n_workspace=200, rng=0)
    assert [n for n, _ in pred.held] == ["panda_link7.alpha", "panda_link7.d"]
    for seed in range(2):
        _, data = simulate(model, q=sel.q, noise=noise, seed=seed)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", rc.RobocalWarning)
            res = rc.calibrate(model, data, noise=rc.Noise.of(position=noise))
        got = {p.name: p.std for p in res.parameters}
        assert set(got) == set(pred.parameters)
        ratios = np.array([got[n] / s for n, s in zip(pred.parameters, pred.std)])
        assert np.all(np.abs(ratios - 1) < 0.2), (ratios.min(), ratios.max())


def test_compensate_reaches_every_reachable_target_and_flags_the_rest(tmp_path, cli):
    nominal, true = rc.read_model(TH8), rc.read_model(TRUE)
    q = rc.random_configurations(nominal, 8, 3)
    q = 0.8 * q + 0.2 * (nominal.lower_limits + nominal.upper_limits) / 2     # away from the limits
    targets = tmp_path / "targets.csv"
    header = ["pose"] + [f"{j}_{'mm' if k == 'length' else 'deg'}" for j, k in
                         zip(nominal.joint_names, nominal.reading_quantities)] + ["tool_x_mm", "tool_y_mm", "tool_z_mm"]
    scale = [1e3 if k == "length" else 180 / np.pi for k in nominal.reading_quantities]
    far = rc.forward_kinematics(nominal, q[:1]).positions[0, 0] * 1e3 + [5000.0, 0, 0]
    # reachable within the limits, from a starting guess whose base axis is 2.4 rad off: the solver
    # stops short of it, which is not the same as out of reach
    goal = np.array([120 * np.pi / 180, 0.4, 0.3, 0, 0, 0])
    there = rc.forward_kinematics(true, goal).positions[0, 0] * 1e3
    with open(targets, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        for i, qi in enumerate(q):
            w.writerow([f"T{i}"] + [v * s for v, s in zip(qi, scale)] + ["", "", ""])
        w.writerow(["far"] + [v * s for v, s in zip(q[0], scale)] + list(far))   # Cartesian, out of reach
        w.writerow(["short"] + [v * s for v, s in zip(goal - [2.4, 0, 0, 0, 0, 0], scale)] + list(there))
    out = tmp_path / "commands.csv"
    code, printed, err = cli("compensate", TH8, TRUE, targets, "--out", out)
    assert code == 0, err
    rows = _rows(out)
    assert [r["pose"] for r in rows] == [f"T{i}" for i in range(8)] + ["far", "short"]       # none dropped
    assert [r["status"] for r in rows] == ["ok"] * 8 + ["out of reach", "not converged"]
    assert "far: out of reach" in err and "short: not converged" in err
    # their solver's last readings command no pose asked for: left empty, not sent to the robot
    assert all(r[c] == "" for r in rows[8:] for c in header[1:7]) and all(r["residual_mm"] for r in rows[8:])
    got = np.array([[float(r[c]) / s for c, s in zip(header[1:7], scale)] for r in rows[:8]])
    # the nominal pose on the calibrated robot's base: the nominal base (a guess of where the
    # instrument stood) moves no target
    on_true_base = nominal.replace(base_position=true.base_position, base_rotation=true.base_rotation)
    want = rc.forward_kinematics(on_true_base, q)
    reached = rc.forward_kinematics(true, got)
    assert np.abs(reached.positions - want.positions).max() < 1e-6
    assert np.abs(reached.rotations - want.rotations).max() < 1e-6


def test_compensate_cartesian_targets_and_joint_limits():
    model = arm6r()
    true, _ = rc.simulate(model, 3, seed=2)
    q = rc.random_configurations(model, 5, 1) * 0.7
    goal = rc.forward_kinematics(model, q + 0.05).positions[:, 0]
    comp = rc.compensate(true, q, nominal=model, positions=goal)
    assert comp.reached(1e-6).all() and not comp.oriented.any()
    assert np.abs(rc.forward_kinematics(true, comp.q).positions[:, 0] - goal).max() < 1e-6
    narrow = model.replace(joint_limits=tuple((lo * 1e-3, hi * 1e-3) for lo, hi in model.joint_limits))
    assert not rc.compensate(narrow, q, nominal=model).within_limits.all()


def test_a_target_beyond_the_arms_reach_is_out_of_reach_and_one_stopped_short_of_is_not():
    """Targets twice as far from the base as the arm reaches: once the solver no longer approaches
    them it says they are out of reach; stopped while still approaching, it does not."""
    model = arm6r()
    true, _ = rc.simulate(model, 3, seed=2)
    q = rc.random_configurations(model, 5, 1) * 0.7
    goal = 2.0 * rc.forward_kinematics(model, q).positions[:, 0]
    comp = rc.compensate(true, q, nominal=model, positions=goal, iterations=300)
    assert comp.stuck.all() and comp.out_of_reach().all() and (comp.residual > 0.3).all()
    early = rc.compensate(true, q, nominal=model, positions=goal, iterations=3)
    assert not early.stuck.any() and not early.reached().any()
    assert np.array_equal(early.out_of_reach(), ~early.within_limits)


def test_export_takes_urdf_from_the_file_name_and_asks_for_a_tables_form(tmp_path, cli):
    code, out, err = cli("export", TRUE, "--out", tmp_path / "m.urdf")
    assert code == 0 and ": urdf of 6 joints" in out, err
    code, _, err = cli("export", TRUE, "--out", tmp_path / "m.csv")
    assert code == 2 and "--format" in err and "mdh-csv" in err and "dh-csv" in err
    assert not (tmp_path / "m.csv").exists()


@pytest.mark.parametrize("fmt, name, words", [
    # a classic DH table written into x.urdf, exit 0
    ("dh-csv", "x.urdf", "names a URDF file (.urdf), but --format dh-csv writes a CSV file: give it a .csv name, "
                         "or --format urdf"),
    ("mdh-csv", "x.URDF", "names a URDF file (.urdf)"),
    ("urdf", "x.csv", "names a CSV file (.csv), but --format urdf writes a URDF file: give it a .urdf name, or "
                      "--format mdh-csv or dh-csv"),
    # a URDF written under a model file's or a robot program's name, exit 0
    ("urdf", "x.yaml", "names a model file (.yaml)"),
    ("mdh-csv", "x.mod", "names a rapid program file (.mod)"),
])
def test_export_refuses_an_out_named_as_another_format(fmt, name, words, tmp_path, cli):
    (tmp_path / name).write_text("kept\n")
    code, _, err = cli("export", TRUE, "--format", fmt, "--out", tmp_path / name, "--force")
    assert_one_line_error(code, err, ["--out", words], command="export")
    assert (tmp_path / name).read_text() == "kept\n"


@pytest.mark.parametrize("fmt", ["urdf", "mdh-csv", "dh-csv"])
def test_export_round_trips(fmt, tmp_path, cli):
    source = TRUE if fmt != "dh-csv" else TH8
    out = tmp_path / f"out.{fmt}"
    code, _, err = cli("export", source, "--format", fmt, "--out", out)
    assert code == 0, err
    model = rc.read_model(source)
    if fmt == "urdf":
        back = rc.read_urdf(out)
    else:
        code, _, err = cli("import-dh", out, "--out", tmp_path / "back.yaml")
        assert code == 0, err
        back = rc.read_model(tmp_path / "back.yaml")
    # the forms hold geometry: compare the geometric forward kinematics (compliance is not exported)
    model = model.replace(frames=tuple(replace(f, k_theta=0.0, k_alpha=0.0, k_beta=0.0) for f in model.frames))
    q = rc.random_configurations(model, 100, 0)
    a, b = rc.forward_kinematics(model, q), rc.forward_kinematics(back, q)
    assert np.abs(a.positions - b.positions).max() < 1e-9
    assert np.allclose(back.joint_limits, model.joint_limits, atol=1e-12)


@pytest.mark.parametrize("fmt", ["urdf", "mdh-csv", "dh-csv"])
def test_export_says_what_it_leaves_out_and_how_far_that_moves_the_tool(fmt, tmp_path, cli):
    """A model with backlash was exported without a word; now each term an export cannot carry is
    named, with how far the geometry alone puts the tool. The TH8's vertical slide always rests on
    the side gravity pushes it to (its load, some 770 N, beats its 10 N friction): its half lost
    motion of 0.5 mm moves the whole arm by 0.5 mm at every configuration."""
    nominal = rc.read_model(TH8)
    frames = list(nominal.frames)
    frames[1] = replace(frames[1], backlash_r=0.5e-3)
    rc.write_model(nominal.replace(frames=tuple(frames)), tmp_path / "backlash.yaml")
    out = tmp_path / ("m.urdf" if fmt == "urdf" else "m.csv")
    code, _, err = cli("export", tmp_path / "backlash.yaml", "--format", fmt, "--out", out)
    assert code == 0, err
    assert err.splitlines() == [f"robocal: warning: {tmp_path / 'backlash.yaml'}: backlash is not exported: {fmt} "
                                "holds the geometry only, which puts the markers (tool) up to 0.5 mm from the model's "
                                "(1000 readings within the joint limits)"]
    code, _, err = cli("export", TRUE, "--format", fmt, "--out", tmp_path / "true" / out.name)
    assert code == 0 and err.count("warning") == 1 and ": compliance is not exported: " in err, err


def test_a_classic_dh_table_is_the_robots_own_wherever_the_instrument_stood(tmp_path, cli):
    """The classic table put its frame 0 on axis 1 at the point nearest the instrument's origin: the
    TH8, whose vertical slide sits 600 mm above its base, was written with d = -200 mm because the
    theodolites stood 800 mm below it; its rows now hold the robot alone, the base row where it stood."""
    code, _, err = cli("export", TH8, "--format", "dh-csv", "--out", tmp_path / "dh.csv")
    assert code == 0, err
    lines = (tmp_path / "dh.csv").read_text().splitlines()
    rows = {r["name"]: r for r in csv.DictReader(line for line in lines if line[0] != "#")}
    assert [float(rows[n]["d_mm"]) for n in ("j1", "j2")] == pytest.approx([0.0, 600.0], abs=1e-9)
    assert [float(rows["base"][k]) for k in ("x_mm", "y_mm", "z_mm", "yaw_deg")] == pytest.approx(
        [2000.0, 1200.0, -800.0, 30.0], abs=1e-9)
    model = rc.read_model(TRUE)
    here = rc.to_standard_dh(model.replace(base_position=(0.0, 0.0, 0.0),
                                           base_rotation=((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))))
    there = rc.to_standard_dh(model)
    assert there.rows == here.rows
    assert np.abs(there.X_W0 - model.X_WB @ here.X_W0).max() < 1e-12


def test_the_calibrated_th8_exports_to_classic_dh_and_reproduces_its_kinematics(tmp_path, cli):
    # what the README says of its own example: the calibrated TH8's classic-DH table is written and usable
    code, _, err = cli("calibrate", TH8, str(ROOT / "examples/th8/measurements.csv"), "--out", tmp_path / "run",
                       "--known", "markers")
    assert code == 0, err
    code, _, err = cli("export", tmp_path / "run" / "calibrated.yaml", "--format", "dh-csv",
                       "--out", tmp_path / "dh.csv")
    assert code == 0 and "warning" not in err, err
    code, _, err = cli("import-dh", tmp_path / "dh.csv", "--out", tmp_path / "back.yaml")
    assert code == 0, err
    cal = rc.read_model(tmp_path / "run" / "calibrated.yaml")
    cal = cal.replace(frames=tuple(replace(f, k_theta=0.0, k_alpha=0.0, k_beta=0.0) for f in cal.frames))
    back = rc.read_model(tmp_path / "back.yaml")
    q = rc.random_configurations(cal, 200, 3)
    assert np.abs(rc.forward_kinematics(cal, q).positions - rc.forward_kinematics(back, q).positions).max() < 1e-9


def test_classic_dh_export_refuses_ill_conditioned_parallel_axes(tmp_path, cli):
    model = arm6r()
    true, _ = rc.simulate(model, 3, seed=1)       # a tilt between the parallel axes j2 and j3
    rc.write_model(true, tmp_path / "cal.yaml")
    code, _, err = cli("export", tmp_path / "cal.yaml", "--format", "dh-csv", "--out", tmp_path / "dh.csv")
    assert code == 2 and "ill-conditioned" in err and "j2" in err and not (tmp_path / "dh.csv").exists()
    # one line as every refusal: the model file, where, what, and the option that writes it anyway
    assert_one_line_error(code, err, [f"{tmp_path / 'cal.yaml'}: frames: classic DH is ill-conditioned",
                                      "--allow-ill-conditioned"], command="export")
    code, _, err = cli("export", tmp_path / "cal.yaml", "--format", "dh-csv", "--out", tmp_path / "dh.csv",
                       "--allow-ill-conditioned")
    assert code == 0 and "warning" in err and "ill-conditioned" in err


def test_compare_writes_the_chosen_result_json(tmp_path, cli):
    out = tmp_path / "run"
    code, _, err = cli("calibrate", TH8, str(ROOT / "examples/th8/measurements.csv"), "--out", out, "--compare",
                       "--known", "markers")
    assert code in (0, 3), err
    def summary(name):  # the per-pose arrays, the same bytes, are in a sidecar of each file's name
        d = json.loads((out / name).read_text())
        assert (out / d["errors"]["file"].pop("name")).exists()
        return d

    chosen = summary("result.json")
    assert chosen in (summary("result-geometric.json"), summary("result-compliance.json"))


def test_rough_edges(tmp_path, cli):
    code, _, err = cli("simulate", TH8, "--out", tmp_path / "s.csv", "--poses", 5, "--noise-mm", -1)
    assert code == 2 and "Traceback" not in err and "--noise-mm" in err.strip().splitlines()[-1]
    limit = tmp_path / "limit.json"
    limit.write_text(json.dumps({"schema": "robocal.limit/1", "unit": "m", "limit": 0.0005}))
    from robocal.cli.common import limit_mm
    assert limit_mm(str(limit)) == pytest.approx(0.5) and limit_mm("0.4") == 0.4
    code, _, err = cli("-v", "plan", TH8, "--poses", 10, "--n-candidates", 100, "--out", tmp_path / "p.csv")
    assert code == 0 and "robocal: " in err and "chose 10 of 100" in err
    # after the command too, as users type it
    code, _, err = cli("plan", TH8, "--poses", 10, "--n-candidates", 100, "--out", tmp_path / "p2.csv", "-v")
    assert code == 0 and "chose 10 of 100" in err
    code, _, err = cli("plan", TH8, "--poses", 10, "--n-candidates", 100, "--out", tmp_path / "p3.csv")
    assert code == 0 and "chose 10 of 100" not in err


def test_the_masses_advice_is_a_command_line_that_works(tmp_path, cli):
    from robocal.cli import build_parser

    with pytest.raises(rc.InputError) as e:
        rc.calibrate(arm6r(), rc.simulate(arm6r(), 30, seed=1)[1], parameters=("geometric", "compliance"))
    advice = re.search(r"\((--assume-masses[^)]*) on the command line\)", str(e.value)).group(1)
    options = re.findall(r"--[\w-]+(?: [A-Z]+)?", advice)
    assert options == ["--assume-masses", "--total-mass KG"]
    argv = ["calibrate", TH8, "data.csv", "--out", str(tmp_path)] + [w for o in options for w in o.split()]
    argv[-1] = "12.5"
    args = build_parser().parse_args(argv)
    assert args.assume_masses and args.total_mass == 12.5


@pytest.mark.parametrize("command", ["plan", "simulate", "calibrate", "compensate", "export", "identifiability",
                                     "report", "limit", "import-urdf", "import-dh"])
def test_every_help_has_a_description_and_an_example(command, cli):
    code, out, _ = cli(command, "--help")
    usage, description = out.split("\n\n")[:2]
    assert code == 0 and usage.startswith(f"usage: robocal {command}") and not description.startswith(("positional",
                                                                                                      "options"))
    assert "\nexample" in out and f"  robocal {command} " in out


def test_broken_pipe_is_quiet():
    code = ("import sys; sys.argv = ['robocal', 'identifiability', '" + TH8 + "', '--poses', '30'];"
            "from robocal.cli import main; sys.exit(main())")
    p = subprocess.run(f"{sys.executable} -c \"{code}\" | head -1", shell=True, capture_output=True, text=True,
                       cwd=ROOT)
    assert p.stderr == "" and p.stdout.startswith("identifiability")


@pytest.mark.parametrize("edit, words", [
    (("89.159", "8x9"), ["line 5", "'d_mm'", "expected a number"]),
    ((",revolute,0,0,-425", ",rotary,0,0,-425"), ["line 6", "'joint'", "rotary"]),
], ids=["number", "joint-kind"])
def test_import_dh_bad_table(edit, words, tmp_path, cli):

    text = ((ROOT / "examples/dh/ur5-dh.csv").read_text()).replace(*edit)
    (tmp_path / "t.csv").write_text(text)
    code, _, err = cli("import-dh", tmp_path / "t.csv", "--out", tmp_path / "out" / "m.yaml")
    assert_one_line_error(code, err, ["t.csv"] + words, tmp_path / "out", command="import-dh")


def test_compensate_unknown_marker(tmp_path, cli):
    from conftest import assert_one_line_error

    code, _, err = cli("compensate", TH8, TRUE, str(ROOT / "examples/th8/targets.csv"), "--out",
                       tmp_path / "o" / "c.csv",
                       "--marker", "nose")
    assert_one_line_error(code, err, ["--marker", "nose", "tool"], tmp_path / "o", command="compensate")


def test_a_closed_pipe_ends_quietly(monkeypatch, capsys):
    """What ``robocal ... | head`` meets: stdout raising BrokenPipeError once the reader left."""
    from robocal.cli import main

    class Closed:
        def write(self, text):
            raise BrokenPipeError(32, "Broken pipe")

        def flush(self):
            pass

    monkeypatch.setattr(sys, "stdout", Closed())
    assert main(["identifiability", TH8, "--poses", "20"]) == 0
    assert capsys.readouterr().err == ""


def test_a_closed_pipe_keeps_the_exit_code_and_the_files(monkeypatch, capsys, tmp_path):
    """``robocal calibrate ... | head``: once the reader left, a failed calibration ended with 0 (the
    broken pipe caught as a quiet end) though it had failed its checks. It now ends with 3, its files
    written."""
    from robocal.cli import main

    class Closed:
        def write(self, text):
            raise BrokenPipeError(32, "Broken pipe")

        def flush(self):
            pass

    real = ROOT / "tests" / "data" / "real"
    grid = real / "serial_robots_datasets" / "UR5" / "3D_UR5_uncalibrated_grid_cleaned.csv"
    columns = ("x_t+x_dif=tool_x_mm,y_t+y_dif=tool_y_mm,z_t+z_dif=tool_z_mm,step_order=pose,joint_1=shoulder_pan,"
               "joint_2=shoulder_lift,joint_3=elbow,joint_4=wrist_1,joint_5=wrist_2,joint_6=wrist_3")
    assert main(["import-dh", str(real / "ur5-dh.csv"), "--out", str(tmp_path / "ur5.yaml")]) == 0
    monkeypatch.setattr(sys, "stdout", Closed())
    # degrees declared as radians: the calibration fails, naming them
    code = main(["calibrate", str(tmp_path / "ur5.yaml"), str(grid), "--map", columns, "--units", "mm-rad",
                 "--out", str(tmp_path / "run")])
    assert code == 3 and (tmp_path / "run" / "result.json").is_file()
    assert "Traceback" not in capsys.readouterr().err


def test_plan_from_candidate_poses(tmp_path, cli):
    out = tmp_path / "poses.csv"
    code, printed, err = cli("plan", TH8, "--poses", 10, "--candidates", ROOT / "examples/th8/measurements.csv",
                             "--out", out)
    assert code == 0, err
    model = rc.read_model(TH8)
    given = rc.read_measurements(ROOT / "examples/th8/measurements.csv", model).q
    assert f"10 poses chosen from {len(given)} poses of" in printed
    chosen = rc.read_measurements(out, model, targets=True)
    assert all(np.isclose(given, row).all(axis=1).any() for row in chosen.q)
    # each chosen pose keeps its name in the candidates' file (they were renamed P01, P02, ...)
    named = rc.read_measurements(ROOT / "examples/th8/measurements.csv", model)
    for label, row in zip(chosen.labels, chosen.q):
        assert np.allclose(named.q[named.labels.index(label)], row), label
