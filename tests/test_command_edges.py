"""Edges of the commands found by fuzzing from outside: each one a line on stderr and exit 2, or the
right output, never a traceback or numpy's own words."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import assert_one_line_error
from robots import arm6r

import robocal as rc
from robocal.io import read_program, read_program_joints, write_contacts
from robocal.sim import socket_campaign

ROOT = Path(__file__).resolve().parents[1]
TH8 = ROOT / "examples" / "th8"
ARM7 = ROOT / "examples" / "arm7" / "model.yaml"


def test_a_negative_zero_noise_simulates_without_noise(cli, tmp_path):
    code, out, err = cli("simulate", TH8 / "model.yaml", "--out", tmp_path / "s.csv", "--poses", "10",
                         "--noise-mm", "-0")
    assert code == 0 and "noise 0.0 mm" in out and err == "", err
    assert rc.read_measurements(tmp_path / "s.csv", rc.read_model(TH8 / "model.yaml")).n_poses == 10


def test_a_limit_file_name_longer_than_the_system_takes_is_one_line(cli, tmp_path):
    code, _, err = cli("calibrate", TH8 / "model.yaml", TH8 / "measurements.csv", "--out", tmp_path / "o",
                       "--limit-mm", "x" * 300)
    assert code == 2 and "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert "--limit-mm" in err and "no such file" in err and not (tmp_path / "o").exists()


@pytest.mark.parametrize("noise", ["1e-300", "1e-7", "0"])
def test_a_noise_no_instrument_has_is_refused(cli, tmp_path, noise):
    code, _, err = cli("calibrate", TH8 / "model.yaml", TH8 / "measurements.csv", "--out", tmp_path / "o",
                       "--noise-mm", noise)
    assert code == 2 and "--noise-mm" in err and "0.000001 to 1000" in err and "inf" not in err
    assert not (tmp_path / "o").exists()


def test_holding_out_every_placement_of_a_mixed_campaign_is_refused(cli, tmp_path):
    arm7 = rc.read_model(ARM7)
    write_contacts(socket_campaign(arm7, placements=2, poses_per_socket=6, rng=7), tmp_path / "sockets.csv", arm7)
    rc.write_measurements(rc.measure(arm7, rc.random_configurations(arm7, 15, 1), rng=1), tmp_path / "t.csv",
                          model=arm7)
    code, _, err = cli("calibrate", ARM7, tmp_path / "t.csv", "--contacts", tmp_path / "sockets.csv", "--out",
                       tmp_path / "o", "--holdout-placement", "P1,P2")
    assert_one_line_error(code, err, ["--holdout-placement", "every placement", "sockets.csv"], tmp_path / "o")


@pytest.mark.parametrize("share", ["1e-320", "0.001", "0.99"])
def test_a_holdout_that_holds_out_no_pose_or_every_pose_is_refused(cli, tmp_path, share):
    """A share of 30 poses that rounds to none of them (or to all) left an empty set, on which the
    check of copied rows raised numpy's reshape error."""
    arm7 = rc.read_model(ARM7)
    rc.write_measurements(rc.measure(arm7, rc.random_configurations(arm7, 30, 1), rng=1), tmp_path / "t.csv",
                          model=arm7)
    code, _, err = cli("calibrate", ARM7, tmp_path / "t.csv", "--out", tmp_path / "o", "--holdout", share)
    assert_one_line_error(code, err, ["t.csv", "--holdout", "of 30 poses holds out", "1/30 to 29/30"], tmp_path / "o")


def test_a_full_turn_joint_read_beyond_its_limits_at_every_pose_fails_its_check(cli, tmp_path):
    """The tool roll (limits +-180 deg, a full turn: its range of use is the campaign's) read 574.32
    deg at every pose: 0e1f3e7 drew the workspace between 574.32 and 180 deg and raised numpy's
    'high - low < 0' (the numbers fuzz family, seed 204). The readings' check fails the calibration."""
    lines = (TH8 / "measurements.csv").read_text().splitlines()
    rows = [row.split(",") for row in lines[1:]]
    for row in rows:
        row[6] = "574.32"
    (tmp_path / "roll.csv").write_text("\n".join([lines[0]] + [",".join(r) for r in rows]) + "\n")
    code, out, err = cli("calibrate", TH8 / "model.yaml", tmp_path / "roll.csv", "--out", tmp_path / "o",
                         "--parameters", "markers")
    assert code == 3 and "Traceback" not in err
    assert "FAIL joint readings within the limits" in out and "j6 = 574.32 deg" in out


def test_points_that_never_move_while_the_joints_do_are_refused(cli, tmp_path):
    """Every measured point the same (the instrument repeated one reading, or a pivot about the tool
    point): 5162251 fitted a geometry that puts the tool there at every pose (a 17-pose campaign with
    --compare and a robust loss took 107 s of CPU, its models 0.4 to 2.8 m off in use). Refused
    before any work; one marker still on one point among others that move is not."""
    lines = (TH8 / "measurements.csv").read_text().splitlines()
    first = lines[1].split(",")
    still = [lines[0]] + [",".join(row.split(",")[:7] + first[7:10] + row.split(",")[10:]) for row in lines[1:]]
    (tmp_path / "still.csv").write_text("\n".join(still) + "\n")
    code, _, err = cli("calibrate", TH8 / "model.yaml", tmp_path / "still.csv", "--out", tmp_path / "o")
    assert_one_line_error(code, err, ["still.csv", "every measured point of marker tool is the same", "joints move",
                                      "--contacts"], tmp_path / "o")
    m = arm6r(markers=(("tool", (0.05, 0.02, 0.12)), ("side", (-0.04, 0.06, 0.08))))
    _, data = rc.simulate(m, 30, seed=1)
    pos = data.positions.copy()
    pos[:, 1] = pos[0, 1]
    with pytest.raises(rc.DegenerateDataError, match="marker side is the same"):
        rc.calibrate(m, rc.Measurements(q=data.q, positions=pos, marker_names=data.marker_names))
    pos[1:, 1] = np.nan                        # measured once: nothing said of its moving
    assert rc.calibrate(m, rc.Measurements(q=data.q, positions=pos, marker_names=data.marker_names)).parameters


def test_a_set_of_no_pose_or_contact_is_refused_wherever_it_is_given():
    m = arm6r()
    _, data = rc.simulate(m, 30, seed=1)
    none = data.subset(np.zeros(30, dtype=bool))
    with pytest.raises(rc.InputError, match="validation: holds no pose: nothing to judge the calibration on"):
        rc.calibrate(m, data, validation=none)
    with pytest.raises(rc.InputError, match="data: holds no pose: nothing to fit"):
        rc.calibrate(m, none, validation=data)
    with pytest.raises(rc.InputError, match="data: holds no pose"):       # numpy's ptp of nothing before
        rc.diagnose(m, none, rc.calibrate(m, data))
    with pytest.raises(rc.InputError, match="data: holds no pose"):
        rc.register_base(m, none)
    unmeasured = data.without(np.ones(data.mask.shape, dtype=bool))     # numpy's concatenate before
    with pytest.raises(rc.InputError, match="data: holds no measured point: nothing to fit"):
        rc.calibrate(m, unmeasured)
    with pytest.raises(rc.InputError, match="data: holds no measured point"):
        rc.diagnose(m, unmeasured, rc.calibrate(m, data))
    arm7 = rc.read_model(ARM7)
    contacts = socket_campaign(arm7, placements=3, poses_per_socket=6, rng=1)
    no_contact = contacts.subset(np.zeros(contacts.n_rows, dtype=bool))
    with pytest.raises(rc.InputError, match="contacts: holds no contact: nothing to fit"):
        rc.calibrate(arm7, contacts=no_contact)
    with pytest.raises(rc.InputError, match="contacts: holds no contact"):      # numpy's concatenate before
        rc.diagnose_contacts(arm7, no_contact, rc.calibrate(arm7, contacts=contacts))


@pytest.mark.parametrize("component", ["1e308", "-1e308", "1e200"])
def test_a_huge_rapid_quaternion_component_is_refused_at_its_place(tmp_path, component):
    path = tmp_path / "p.mod"
    path.write_text("MODULE m\n  CONST robtarget p1 := [[1,2,3],[" + component + ",0,0,0],[0,0,0,0],"
                    "[9E9,9E9,9E9,9E9,9E9,9E9]];\n  MoveL p1, v10, fine, tool0;\nENDMODULE\n")
    with pytest.raises(rc.InputError, match="quaternion's norm") as e:
        read_program(path)
    assert "line 2" in str(e.value)


def test_urscript_joint_readings_are_labelled_by_their_declared_name(tmp_path):
    path = tmp_path / "log.script"
    path.write_text("def log():\n  home = [0, -1.57, 1.57, 0, 0, 0]\n  movej(home)\n"
                    "  q = [0.1, -1.2, 1.1, 0.2, 0.3, 0.4]\n  movej(q)\n  q = [0.2, -1.1, 1.0, 0.1, 0.2, 0.3]\n"
                    "  movej(q)\n  movej([0, 0, 0, 0, 0, 0])\nend\n")
    labels, q = read_program_joints(path, arm6r())
    # a name assigned once is the pose label; one assigned twice needs its line to tell them apart
    assert labels == ["home", "q (line 4)", "q (line 6)", "line 8"]
    assert np.allclose(q[0], [0, -1.57, 1.57, 0, 0, 0])


def test_numpy_runtime_warnings_never_reach_the_user(cli, tmp_path, monkeypatch):
    import robocal.cli.simulate as command

    def overflowing(args):
        np.float64(1e308) * np.float64(10.0)        # what numpy says of its internals
        print("done")
        return 0

    monkeypatch.setattr(command, "run", overflowing)
    code, out, err = cli("simulate", TH8 / "model.yaml", "--out", tmp_path / "s.csv", "--poses", "10")
    assert code == 0 and out == "done\n" and err == ""


def test_a_format_version_written_as_text_is_named_so(cli, tmp_path):
    text = (TH8 / "model.yaml").read_text()
    assert "robocal_model: 1\n" in text
    (tmp_path / "m.yaml").write_text(text.replace("robocal_model: 1\n", "robocal_model: '1'\n"))
    code, _, err = cli("calibrate", tmp_path / "m.yaml", TH8 / "measurements.csv", "--out", tmp_path / "o")
    assert_one_line_error(code, err, ["robocal_model", "the number 1", "without quotes"], tmp_path / "o")
    assert "reads version 1" not in err


def test_argument_messages_say_what_the_argument_holds():
    from robocal.identification import analyse
    from robocal.kinematics import forward_kinematics

    arm7 = rc.read_model(ARM7)
    with pytest.raises(rc.InputError, match=r"joint readings: a row per pose, a column for each of the model's 7 "
                                            r"joints.*got 6 column\(s\)"):
        forward_kinematics(arm7, np.zeros((3, 6)))
    with pytest.raises(rc.InputError, match="the Jacobian .* must hold finite numbers"):
        analyse(np.array([[1.0, np.nan]]), ["a", "b"])


def test_a_commands_files_may_come_before_or_after_its_options(cli, tmp_path):
    # the CSV, which --contacts lets be left out, after an option: taken, not refused as unrecognized
    code, out, err = cli("calibrate", TH8 / "model.yaml", "--out", tmp_path / "o", "--known", "markers",
                         TH8 / "measurements.csv")
    assert code == 0 and (tmp_path / "o" / "result.json").exists(), err
    code, _, err = cli("calibrate", TH8 / "model.yaml", TH8 / "measurements.csv", "--out", tmp_path / "p",
                       TH8 / "verification.csv")
    assert_one_line_error(code, err, ("unrecognized arguments:", "verification.csv"), tmp_path / "p")


@pytest.mark.parametrize("path, form, command, function", [
    (ROOT / "examples" / "urdf" / "gen3_like.urdf", "a URDF", "import-urdf", "read_urdf"),
    (ROOT / "examples" / "dh" / "ur5-dh.csv", "a DH table", "import-dh", "read_dh_table")])
def test_a_model_in_a_form_robocal_imports_names_the_import(cli, tmp_path, path, form, command, function):
    """A URDF or a DH table given where a model file goes was refused as YAML that is not a mapping;
    it now says what the file is and which command makes a model file of it."""
    code, _, err = cli("calibrate", path, TH8 / "measurements.csv", "--out", tmp_path / "o")
    assert_one_line_error(code, err, [str(path), form, f"robocal {command} {path} --out model.yaml"], tmp_path / "o")
    with pytest.raises(rc.InputError, match=f"rc.{function}"):
        rc.read_model(path)
    imported = rc.read_urdf(path) if command == "import-urdf" else rc.read_dh_table(path)
    rc.write_model(imported, tmp_path / "model.yaml")
    assert rc.read_model(tmp_path / "model.yaml").joint_names == imported.joint_names


@pytest.mark.parametrize("command, path, words", [
    ("import-urdf", ROOT / "examples" / "dh" / "ur5-dh.csv", ["a DH table, not a URDF", "robocal import-dh"]),
    ("import-dh", ROOT / "examples" / "urdf" / "gen3_like.urdf", ["a URDF, not a DH table", "robocal import-urdf"]),
    ("import-urdf", TH8 / "model.yaml", ["a robocal model file, not a URDF", "a model file already"])])
def test_an_importer_given_another_form_names_the_one_that_reads_it(cli, tmp_path, command, path, words):
    """import-urdf read a DH table or a model file as malformed XML, import-dh a URDF as a table of
    neither convention."""
    code, _, err = cli(command, path, "--out", tmp_path / "m.yaml")
    assert_one_line_error(code, err, [str(path), *words], tmp_path / "m.yaml", command=command)


def test_an_output_that_is_one_of_the_commands_inputs_is_refused_even_with_force(cli, tmp_path):
    """`compensate ... targets.csv --out targets.csv --force` replaced the targets with the commands
    made from them, and `export model.yaml --out model.yaml --force` the model with its URDF; an
    output that is (or links to) a file the command reads is now refused, the file left as it was."""
    model, targets = tmp_path / "model.yaml", tmp_path / "targets.csv"
    model.write_bytes((TH8 / "model.yaml").read_bytes())
    targets.write_bytes((TH8 / "targets.csv").read_bytes())
    (tmp_path / "link.csv").symlink_to(targets)
    (tmp_path / "link.urdf").symlink_to(model)      # model.yaml itself is refused by its name first
    before = {p: p.read_bytes() for p in (model, targets)}
    for args, out in ((("compensate", model, model, targets), targets),
                      (("compensate", model, model, targets), tmp_path / "link.csv"),
                      (("export", model, "--format", "urdf"), tmp_path / "link.urdf")):
        code, _, err = cli(*args, "--out", out, "--force")
        assert code == 2 and "a file this command reads" in err and str(out) in err, err
        assert len(err.strip().splitlines()) == 1
    assert {p: p.read_bytes() for p in before} == before
    code, _, err = cli("compensate", model, model, targets, "--out", tmp_path / "commands.csv")
    assert code == 0, err


def test_plan_with_too_few_poses_says_how_many_it_needs(cli, tmp_path):
    code, _, err = cli("plan", TH8 / "model.yaml", "--poses", "5", "--out", tmp_path / "plan.csv")
    k = len(rc.identifiability(rc.read_model(TH8 / "model.yaml")).identified)
    assert_one_line_error(code, err, ["5 poses give 15 equations", f"at least {k // 3 + 1} poses"],
                          tmp_path / "plan.csv", command="plan")


def test_plan_counts_a_candidate_given_twice_once_and_names_what_its_poses_cannot_separate(cli, tmp_path):
    """Twenty copies of one pose were a plan predicting 0.008 mm in use (condition number 1e110); a
    joint that never moves among the candidates left its neighbours' parameters out without a word."""
    model = rc.read_model(TH8 / "model.yaml")
    lines = (TH8 / "measurements.csv").read_text().splitlines()
    header, first = lines[0], lines[1]
    label = first.split(",")[0]
    (tmp_path / "copies.csv").write_text("\n".join([header] + [first.replace(label, f"C{i}", 1) for i in range(20)]))
    code, _, err = cli("plan", TH8 / "model.yaml", "--poses", "20", "--candidates", tmp_path / "copies.csv",
                       "--out", tmp_path / "plan.csv")
    assert code == 2 and "19 candidate poses repeat others" in err
    assert "cannot choose 20 poses from 1 distinct candidates" in err and not (tmp_path / "plan.csv").exists()
    q = rc.random_configurations(model, 200, rng=1)
    q[:, 3] = 0.3
    rc.write_measurements(rc.measure(model, q, rng=1), tmp_path / "still.csv", model=model)
    code, out, err = cli("plan", TH8 / "model.yaml", "--poses", "20", "--candidates", tmp_path / "still.csv",
                         "--out", tmp_path / "plan.csv")
    assert code == 0, err
    assert "warning: these poses cannot separate j5.alpha, j5.d, j5.theta, j5.r" in out
    code, out, _ = cli("plan", TH8 / "model.yaml", "--poses", "20", "--out", tmp_path / "random.csv")
    assert code == 0 and "cannot separate" not in out
