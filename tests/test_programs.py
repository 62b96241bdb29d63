"""Robot programs in, compensated programs out (docs/formats.md, "Robot programs"): each dialect read
and written back byte for byte, compensated joint and Cartesian targets checked through the models
(the Cartesian ones through the nominal inverse kinematics in the written configuration), targets
out of reach flagged, malformed programs refused at their line and column."""

import codecs
import dataclasses
import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_one_line_error
from robots import arm6r
from scipy.spatial.transform import Rotation

import robocal as rc
from robocal._files.programs import DIALECTS
from robocal.io import compensate_program, program_joints, read_program, read_program_joints
from robocal.kinematics import inverse_kinematics, posture
from robocal.sim import perturb_model

HERE = Path(__file__).resolve().parent / "programs"
EXAMPLES = ["example.mod", "example.dat", "example.src", "example.script"]
TOL_MM, TOL_DEG = 1e-6, 1e-6


@pytest.fixture(scope="module")
def models():
    nominal = arm6r()
    names = rc.candidate_parameters(nominal, ("geometric",))
    return nominal, perturb_model(nominal, names, rng=3)


def _compensate(program, *args, **kw):
    """``compensate_program`` with the files a test program is read with (``_with``)."""
    return compensate_program(program, *args, companions=_with(program), **kw)


def _with(program):
    """The files read with a test program: a KRL program's other half (its .dat or .src, of
    tests/programs) and the controller's $config.dat that declares its tool."""
    if program.dialect != "krl":
        return ()
    other = "example.dat" if program.source.endswith(".src") else "example.src"
    return (read_program(HERE / other), read_program(HERE / "$config.dat"))


def _reread(tmp_path, text, name):
    path = tmp_path / name
    path.write_bytes(text.encode("utf-8"))
    return read_program(path)


@pytest.mark.parametrize("name", EXAMPLES)
def test_nominal_as_calibrated_writes_the_program_back_byte_for_byte(name, models):
    nominal, _ = models
    program = read_program(HERE / name)
    assert len([t for t in program.targets if not t.skip]) >= 5
    result = _compensate(program, nominal, nominal)
    assert result.text.encode("utf-8") == (HERE / name).read_bytes()
    assert not result.flagged and {r.status.split(":")[0] for r in result.targets} <= {"ok", "read only",
                                                                                        "not compensated"}


@pytest.mark.parametrize("name", EXAMPLES)
def test_byte_order_mark_and_crlf_lines_survive(name, tmp_path, models):
    nominal, calibrated = models
    raw = codecs.BOM_UTF8 + (HERE / name).read_bytes().replace(b"\n", b"\r\n")
    (tmp_path / f"crlf{Path(name).suffix}").write_bytes(raw)
    program = read_program(tmp_path / f"crlf{Path(name).suffix}")
    assert _compensate(program, nominal, nominal).text.encode("utf-8") == raw
    changed = _compensate(program, nominal, calibrated).text.encode("utf-8")
    assert changed.startswith(codecs.BOM_UTF8) and b"\n" not in changed.replace(b"\r\n", b"")
    # only the targets' numbers changed: every line without a target's number is the same
    text = program.text
    held = {text.count("\n", 0, n.start) for t in program.targets
            for n in (*t.joints, *t.position, *t.orientation, *t.configuration)}
    new_lines = [ln for ln in changed.split(b"\r\n") if b"robocal: " not in ln]
    old_lines = raw.split(b"\r\n")
    assert len(new_lines) == len(old_lines) and len(held) >= 3
    assert all(a == b for k, (a, b) in enumerate(zip(old_lines, new_lines)) if k not in held)
    assert any(a != b for a, b in zip(old_lines, new_lines))


def test_numbers_keep_their_style():
    from robocal._files.programs.syntax import Number, format_number

    def fmt(value, old, digits=7):
        return format_number(value, Number(float(old), old, 0, 0), digits=digits, keep=1e-12)

    assert fmt(12.0, "12") == "12" and fmt(12.5, "12") == "12.5" and fmt(12.25, "12.0000") == "12.2500"
    assert fmt(-1e-11, "0.0") == "0.0" and fmt(-0.00000001, "0.000") == "0.000"   # no "-0"
    assert fmt(2.5, "+1.0") == "+2.5" and fmt(-2.5, "+1.0") == "-2.5"
    assert fmt(1.234567891234, "1.5", digits=9) == "1.234567891"


def _tool_pose(model, q):
    ev = rc.evaluate(model, q, orientations=True)
    return ev.positions[:, 0], ev.rotations[:, 0]


def _on_base(model, tool_of=None):
    """``model`` in the robot's base frame (its base at the identity), with the markers of
    ``tool_of``: a program's targets are in the robot's base frame, its tool exact in both models."""
    eye = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    return model.replace(base_position=(0.0, 0.0, 0.0), base_rotation=eye,
                         markers=(tool_of or model).markers)


def _assert_same_pose(P, R, P_goal, R_goal):
    assert np.abs(P - P_goal).max() * 1e3 < TOL_MM
    angle = Rotation.from_matrix(R @ np.swapaxes(R_goal, 1, 2)).magnitude()
    assert np.degrees(angle).max() < TOL_DEG


@pytest.mark.parametrize("name", EXAMPLES)
def test_compensated_joint_targets_land_where_the_nominal_ones_did(name, models, tmp_path):
    nominal, calibrated = models
    program = read_program(HERE / name)
    labels, q_old = program_joints(program, nominal)
    result = _compensate(program, nominal, calibrated)
    new = _reread(tmp_path, result.text, name)
    labels_new, q_new = program_joints(new, nominal)
    assert labels_new == labels and np.abs(q_new - q_old).max() > 1e-4   # they did change
    _assert_same_pose(*_tool_pose(_on_base(calibrated, nominal), q_new), *_tool_pose(_on_base(nominal), q_old))


@pytest.mark.parametrize("name", EXAMPLES)
def test_compensated_cartesian_targets_through_the_nominal_ik_land_on_the_intended_pose(name, models, tmp_path):
    nominal, calibrated = models
    module = DIALECTS[read_program(HERE / name).dialect]
    program = read_program(HERE / name)
    result = _compensate(program, nominal, calibrated)
    new = _reread(tmp_path, result.text, name)
    ok = {r.name for r in result.targets if r.status == "ok"}
    pairs = [(a, b) for a, b in zip(program.targets, new.targets) if a.kind == "pose" and a.name in ok]
    assert len(pairs) >= 3
    goal = module.poses([a for a, _ in pairs])                            # in the robot's base frame
    given = module.poses([b for _, b in pairs])
    assert np.abs(given[:, :3, 3] - goal[:, :3, 3]).max() > 1e-4          # the targets moved
    want, turn = zip(*[module.wanted(b, 6) if b.configuration else (np.full(3, -1), np.full(6, np.nan))
                       for _, b in pairs])
    hints = [None if b.configuration else q for (_, b), q in zip(pairs, _hint_rows(new, nominal, pairs))]
    ik = inverse_kinematics(_on_base(nominal), given[:, :3, 3], given[:, :3, :3], want=np.array(want),
                            turn_from=np.array(turn), hints=np.array([np.full(6, np.nan) if h is None else h
                                                                      for h in hints]))
    assert ik.solved.all()
    _assert_same_pose(*_tool_pose(_on_base(calibrated, nominal), ik.q), goal[:, :3, 3], goal[:, :3, :3])
    has_conf = np.array([bool(b.configuration) for _, b in pairs])
    assert np.all((np.array(want) < 0) | (posture(nominal, ik.q) == (np.array(want) > 0))) and (
        has_conf.any() or module.NAME == "urscript")


def _hint_rows(program, model, pairs):
    """The joint target before each pose target (what the compensation seeds a target without
    configuration data from)."""
    out, last = [], None
    targets = sorted(program.targets, key=lambda t: (t.line, t.column))
    wanted = {(b.line, b.column) for _, b in pairs}
    for t in targets:
        if t.kind == "joint" and not t.skip:
            last = program_joints(type(program)(program.source, program.dialect, program.text, (t,)), model)[1][0]
        elif (t.line, t.column) in wanted:
            out.append(last)
    return out


def test_configuration_data_are_kept_as_written_where_they_reach_the_compensated_joints(models, tmp_path):
    """RAPID's quadrants are windows the controller solves in: axes 1 and 4 sat on 0 deg and move
    below it, and the written [0,0,0,0] still reaches them, so it stays as written."""
    nominal, calibrated = models
    program = read_program(HERE / "example.mod")
    result = _compensate(program, nominal, calibrated)
    assert next(r for r in result.targets if r.name == "line 30").status == "ok"
    old = next(t for t in program.targets if t.name == "line 30")
    new = next(t for t in _reread(tmp_path, result.text, "x.mod").targets if t.name == "line 30")
    assert [n.text for n in new.configuration] == [n.text for n in old.configuration] == ["0"] * 4
    assert [n.text for n in new.position] != [n.text for n in old.position]


def test_a_target_its_configuration_data_no_longer_reach_is_flagged_and_left_unchanged(models, tmp_path):
    """KRL's Turn bit 0 says an axis is at or above 0 deg: a home pose taught with axes 1 and 4 at
    0 deg whose compensated axes go below would make the controller turn them by a whole turn."""
    nominal, calibrated = models
    text = (HERE / "example.src").read_text().replace("T 'B001011'", "T 'B000010'")
    (tmp_path / "home.src").write_text(text)
    result = _compensate(read_program(tmp_path / "home.src"), nominal, calibrated)
    row = next(r for r in result.targets if r.line == 12)
    assert row.status == "its configuration data no longer fit: the compensated joints need 0,11, not 0,2"
    assert row in result.flagged
    assert "; robocal: line 12: its configuration data no longer fit" in result.text
    line = next(ln for ln in result.text.splitlines() if ln.startswith("LIN {X 103.185"))
    assert line in text                                          # left as written


def _th8_glue(tmp_path, cfx):
    """A TH8 program of taught robtargets with the given cfx (the TH8 has one shoulder and one
    elbow configuration: only the wrist bit of cfx means something)."""
    model = rc.read_model(HERE.parent.parent / "examples" / "th8" / "model.yaml")
    q = rc.random_configurations(model, 12, rng=4) * 0.8
    q[:, 4] = np.where(cfx & 1, -1.0, 1.0) * np.abs(q[:, 4])
    P, R = _tool_pose(_on_base(model), q)
    quat = Rotation.from_matrix(R).as_quat()[:, [3, 0, 1, 2]]
    lines = ["MODULE Glue", "  PERS tooldata tSphere := [TRUE, [[30, 0, 120], [1, 0, 0, 0]], [1, [0, 0, 50], "
             "[1, 0, 0, 0], 0, 0, 0]];"]
    for i in range(len(q)):
        cf = [int(np.floor(q[i, j] / (np.pi / 2))) for j in (0, 3, 5)]
        lines.append(f"  CONST robtarget p{i} := [[{', '.join(f'{v:.6f}' for v in P[i] * 1e3)}], "
                     f"[{', '.join(f'{v:.8f}' for v in quat[i])}], [{cf[0]}, {cf[1]}, {cf[2]}, {cfx}], "
                     "[9E9, 9E9, 9E9, 9E9, 9E9, 9E9]];")
    lines += ["  PROC main()"] + [f"    MoveL p{i}, v100, fine, tSphere;" for i in range(len(q))]
    text = "\n".join(lines + ["  ENDPROC", "ENDMODULE", ""])
    (tmp_path / "glue.mod").write_text(text)
    return model, read_program(tmp_path / "glue.mod"), text


@pytest.mark.parametrize("cfx", [0, 3, 4, 7])
def test_posture_bits_a_robot_does_not_have_ask_nothing(cfx, tmp_path):
    """The TH8's shoulder and elbow tests are round-off (1e-16): whatever bits 4 and 2 of cfx say,
    taught targets are solved, 1e-12 rad changes leave their configuration data as written, and
    the nominal model as calibrated gives the program back as it was."""
    model, program, text = _th8_glue(tmp_path, cfx)
    same = _compensate(program, model, model)
    assert same.text == text and {r.status for r in same.targets} == {"ok"}
    assert same.notes == ("th8-like has no distinct shoulder or elbow configurations (the posture tests are zero "
                          "over its joint ranges): the configuration data's shoulder, elbow bits are kept as "
                          "written and ask nothing",)
    for k, name in enumerate(("j1", "j4", "j5")):
        frames = list(model.frames)
        i = model.frame_names.index(name)
        frames[i] = dataclasses.replace(frames[i], theta=frames[i].theta + (-1) ** k * 1e-12)
        nudged = _compensate(program, model, model.replace(frames=tuple(frames)))
        assert {r.status for r in nudged.targets} == {"ok"}
        assert nudged.text.count(f"{cfx}], [9E9") == len(nudged.targets)


@pytest.mark.parametrize("name, far, comment", [
    ("example.mod", "    CONST robtarget pFar := [[5000,0,0],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
                    "    MoveL pFar, v100, fine, tGripper;\n", "!"),
    ("example.src", "LIN {X 5000.0,Y 0.0,Z 0.0,A 0.0,B 0.0,C 0.0,S 0,T 0}\n", ";"),
    ("example.script", "  far = p[5.0, 0.0, 0.0, 0.0, 0.0, 0.0]\n  movel(far)\n", "#"),
])
def test_out_of_reach_targets_are_flagged_and_left_unchanged(name, far, comment, models, tmp_path):
    nominal, calibrated = models
    lines = (HERE / name).read_text().splitlines(keepends=True)
    lines.insert(len(lines) - 2, far)
    path = tmp_path / name
    path.write_text("".join(lines))
    result = _compensate(read_program(path), nominal, calibrated)
    assert [r.status for r in result.flagged] == ["no nominal solution in its configuration"]
    out = result.text.splitlines(keepends=True)
    i = out.index(far.splitlines(keepends=True)[0])
    assert out[i - 1].strip().startswith(f"{comment} robocal: ") and "left unchanged" in out[i - 1]
    # the flagged program reads back with the same targets
    assert len(_reread(tmp_path, result.text, "again" + path.suffix).targets) == len(read_program(path).targets)


def test_a_target_at_the_largest_float_is_flagged_without_overflow(models, tmp_path):
    """A KRL target at Z -1e308 mm once sent the seed lookup past its table (IndexError) and the
    inverse kinematics into overflowing steps: it is out of reach, flagged, nothing else."""
    nominal, calibrated = models
    path = tmp_path / "example.src"
    path.write_text((HERE / "example.src").read_text().replace("Z -229.637", "Z -1e308"))
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        result = _compensate(read_program(path), nominal, calibrated)
    assert [r.line for r in result.flagged] == [12]
    assert result.flagged[0].status.startswith("no nominal solution")


def test_a_compensation_beyond_a_joint_limit_is_flagged(models):
    nominal, calibrated = models
    lo, hi = nominal.lower_limits.copy(), nominal.upper_limits.copy()
    lo[0] = np.radians(9.999)                               # jHome's axis 1 is 10 deg and moves below it
    narrow = nominal.replace(joint_limits=tuple(zip(lo, hi)))
    result = _compensate(read_program(HERE / "example.mod"), narrow, calibrated.replace(
        joint_limits=tuple(zip(lo, hi))))
    row = next(r for r in result.targets if r.name == "jHome")
    assert row.status == "beyond a joint limit"
    flag = "! robocal: jHome: beyond a joint limit; left unchanged\n"
    assert flag + "  CONST jointtarget jHome := [[10, -30" in result.text


def test_a_work_object_is_the_frame_of_the_targets(models, tmp_path):
    nominal, calibrated = models
    frames = "[[0, 0, 0], [1, 0, 0, 0]], [[0, 0, 0], [1, 0, 0, 0]]];"
    text = (HERE / "example.mod").read_text().replace(frames, frames.replace("[[0, 0, 0]", "[[100, 0, 0]", 1))
    shifted = text.replace("[[231.980,68.259,", "[[131.980,68.259,")
    (tmp_path / "w.mod").write_text(shifted)
    base = _compensate(read_program(HERE / "example.mod"), nominal, calibrated)
    inwobj = _compensate(read_program(tmp_path / "w.mod"), nominal, calibrated, wobj="wTable")
    a = next(r for r in base.targets if r.name == "pApproach")
    b = next(r for r in inwobj.targets if r.name == "pApproach")
    assert a.status == b.status == "ok" and abs(a.moved - b.moved) < 1e-9 and abs(a.turned - b.turned) < 1e-9


def test_program_joints_read_a_campaign_written_as_controller_code(tmp_path):
    model = arm6r()
    ext = "[9E9,9E9,9E9,9E9,9E9,9E9]"
    (tmp_path / "log.mod").write_text(f"MODULE log\n  ! readings\n"
                                      f"  MoveAbsJ [[1,2,3,4,5,6],{ext}]\\NoEOffs, v10, fine, tool0;\n"
                                      f"  MoveAbsJ [[-1.5,0,0.25,0,90,-180],{ext}], v10, fine, tool0;\n"
                                      "ENDMODULE\n")
    labels, q = read_program_joints(tmp_path / "log.mod", model)
    assert labels == ["line 3", "line 4"]
    assert np.allclose(q, np.radians([[1, 2, 3, 4, 5, 6], [-1.5, 0, 0.25, 0, 90, -180]]))


@pytest.mark.parametrize("suffix, text, line, at", [
    (".mod", "MODULE m\n  CONST robtarget p1 := [[1,2,3],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9];\nENDMODULE\n",
     2, ":= [" ),
    (".mod", "MODULE m\n  CONST robtarget p1 := [[1,2],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\nENDMODULE\n",
     2, ":= ["),
    (".mod", "MODULE m\n  CONST robtarget p1 := [[1,2,3],[1,0,0,0],[0,0,0,9],[9E9,9E9,9E9,9E9,9E9,9E9]];\n", 2, "9]"),
    (".mod", 'MODULE m\n  CONST string s := "open;\n', 2, '"'),
    (".dat", "DEFDAT d\nDECL E6POS XP1={X 1,Y 2,Z 3,A 0,B 0,C 0,S 0,T 0\nENDDAT\n", 2, "={"),
    (".dat", "DEFDAT d\nDECL E6POS XP1={X 1,Y 2,Z 3,A 0,B 0,C 0,S 'B012',T 0}\nENDDAT\n", 2, "'B012'"),
    (".src", "DEF a()\n  LIN {X 1, Y 2, Z 3, A 0, B 0, C 0, S 1e999, T 0}\nEND\n", 2, "1e999"),
    (".src", "DEF a()\n  PTP {A1 0, A2 0, A3 0, A4 0, A5 0, A6 0}}\nEND\n", 2, "}}"),
    (".script", "def a():\n  movej([0, 0, 0, 0, 0, 0], a=1.4))\nend\n", 2, "))"),
    (".script", "def a():\n  movej([0, 0, 0,\n    0, 0, 0,], a=1.4)\nend\n", 3, ",]"),
])
def test_a_malformed_program_is_one_line_naming_file_line_and_column(suffix, text, line, at, tmp_path, cli):
    nominal = arm6r()
    rc.write_model(nominal, tmp_path / "m.yaml")
    (tmp_path / f"p{suffix}").write_text(text)
    row = text.splitlines()[line - 1]
    column = row.index(at) + 1 + {":= [": 3, "={": 1, "}}": 1, "))": 1}.get(at, 0)
    code, _, err = cli("compensate", tmp_path / "m.yaml", tmp_path / "m.yaml", tmp_path / f"p{suffix}",
                       "--out", tmp_path / "o" / f"out{suffix}")
    assert_one_line_error(code, err, [f"p{suffix}", f"line {line}, column {column}:"], tmp_path / "o",
                          command="compensate")


EXT = "[9E9, 9E9, 9E9, 9E9, 9E9, 9E9]"


@pytest.mark.parametrize("suffix, text, value, named", [
    (".mod", f"MODULE m\n  CONST robtarget p1 := [[628.819, 962.752x, 1135.675], [1, 0, 0, 0], [0, 0, 0, 0], {EXT}];\n"
             "ENDMODULE\n", "962.752x", "p1: "),
    (".mod", f"MODULE m\n  CONST jointtarget j1 := [[10, -30, 4.0.5, 20, 50, -30], {EXT}];\nENDMODULE\n", "4.0.5",
     "j1: "),
    (".mod", f"MODULE m\n  PROC main()\n    MoveL [[1, 2, 3], [1, 0, 0, 0], [0, 0, 0, 0e], {EXT}], v10, fine, tool0;\n"
             "  ENDPROC\nENDMODULE\n", "0e", ""),
    (".script", "def a():\n  movel(p[0.1, 0.2x, 0.3, 0, 0, 0], a=1.2, v=0.25)\nend\n", "0.2x", ""),
    (".script", "def a():\n  home = [0.1, 0.2, 0.3, 0.4, 0.5, -0.6rad]\n  movej(home)\nend\n", "0.6rad", "home: "),
    (".src", "DEF a()\n  LIN {X 962.752x, Y 2, Z 3, A 0, B 0, C 0, S 0, T 0}\nEND\n", "962.752x", ""),
    (".dat", "DEFDAT a\n  DECL E6POS XP1={X 962.752x, Y 2, Z 3, A 0, B 0, C 0, S 0, T 0}\nENDDAT\n", "962.752x",
     "XP1: "),
    (".dat", "DEFDAT a\n  TOOL_DATA[1]={X 1.2.3, Y 2, Z 3, A 0, B 0, C 0}\nENDDAT\n", "1.2.3", "TOOL_DATA[1]: "),
])
def test_a_malformed_number_in_a_target_is_refused_naming_file_line_and_value(suffix, text, value, named, tmp_path,
                                                                             cli):
    """A number run into letters or into another number is a slip, not a value computed in the
    program: listing the target as read only would leave it uncompensated without saying why. A
    declared target or frame is named (an inline one has only its line)."""
    rc.write_model(arm6r(), tmp_path / "m.yaml")
    (tmp_path / f"p{suffix}").write_text(text)
    line = next(k for k, row in enumerate(text.splitlines(), 1) if value in row)
    column = text.splitlines()[line - 1].index(value.lstrip("-")) + 1
    code, _, err = cli("compensate", tmp_path / "m.yaml", tmp_path / "m.yaml", tmp_path / f"p{suffix}",
                       "--out", tmp_path / "o" / f"out{suffix}")
    assert_one_line_error(code, err, [f"p{suffix}: line {line}, column {column}: {named}'{value}' is not a number"],
                          tmp_path / "o", command="compensate")


def test_targets_computed_in_the_program_stay_read_only(tmp_path, cli):
    """Expressions, variables, calls and RAPID's whole numbers in base 16 are no malformed numbers."""
    rapid = (f"MODULE m\n  VAR num x0 := 10;\n"
             f"  CONST robtarget p1 := [[x0 + 10, 962.752, 1135.675], [1, 0, 0, 0], [0, 0, 0, 0], {EXT}];\n"
             f"  CONST robtarget p2 := [[10*2, 962.752, 1135.675], [1, 0, 0, 0], [0, 0, 0, 0], {EXT}];\n"
             f"  CONST jointtarget j1 := [[0x1F, 0, 0, 0, 0, 0], {EXT}];\n"
             f"  CONST jointtarget j2 := [[10 DIV 2, Abs(x0), 0, 0, 0, 0], {EXT}];\n"
             f"  CONST jointtarget j3 := [[10, -30, 40, 20, 50, -30], {EXT}];\n"
             "  PROC main()\n    MoveL Offs(p2, 0, 0, 10), v100, fine, tool0;\n  ENDPROC\nENDMODULE\n")
    script = ("def a():\n  x0 = 0.1\n  movel(p[x0 + 0.1, 0.2, 0.3, 0, 0, 0], a=1.2, v=0.25)\n"
              "  movej([2*x0, 0, 0, 0, 0, 0], a=1.4, v=1.05)\n  movej([0.1, 0.2, 0.3, 0.4, 0.5, 0.6])\nend\n")
    for name, text, skip in (("p.mod", rapid, "not a literal value"), ("p.script", script, "not six literal numbers")):
        (tmp_path / name).write_text(text)
        targets = read_program(tmp_path / name).targets
        assert [t.skip for t in targets] == [skip] * (len(targets) - 1) + [""], targets
        assert len(targets) == (5 if name == "p.mod" else 3)
    rc.write_model(arm6r(), tmp_path / "m.yaml")
    code, out, err = cli("compensate", tmp_path / "m.yaml", tmp_path / "m.yaml", tmp_path / "p.mod",
                         "--out", tmp_path / "out.mod")
    assert code == 0, err
    assert "p1 (line 3, pose): read only: not a literal value" in out and "compensated 1 of 5 targets" in out


def test_a_target_computed_inline_is_listed_read_only_not_dropped(tmp_path, cli):
    """A RAPID target written inline in a motion with an expression inside is listed as read only,
    as a declared one is; a motion's other bracketed arguments (speed data) are no targets."""
    rapid = ("MODULE m\n  VAR num x0 := 10;\n  PROC main()\n"
             f"    MoveL [[Abs(x0), 10, 20], [1, 0, 0, 0], [0, 0, 0, 0], {EXT}], v100, z10, tool0;\n"
             f"    MoveAbsJ [[10, -30, x0 + 40, 20, 50, -30], {EXT}], v100, fine, tool0;\n"
             f"    MoveL [p0.trans, [1, 0, 0, 0], [0, 0, 0, 0], {EXT}], [100, 500, 5000, 1000], fine, tool0;\n"
             f"    MoveAbsJ [[10, -30, 40, 20, 50, -30], {EXT}], [vtcp, vori, vleax, vreax], fine, tool0;\n"
             "  ENDPROC\nENDMODULE\n")
    (tmp_path / "p.mod").write_text(rapid)
    targets = read_program(tmp_path / "p.mod").targets
    assert [(t.name, t.kind, t.skip) for t in targets] == [
        ("line 4", "pose", "not a literal value"), ("line 5", "joint", "not a literal value"),
        ("line 6", "pose", "not a literal value"), ("line 7", "joint", "")]
    rc.write_model(arm6r(), tmp_path / "m.yaml")
    code, out, err = cli("compensate", tmp_path / "m.yaml", tmp_path / "m.yaml", tmp_path / "p.mod",
                         "--out", tmp_path / "out.mod")
    assert code == 0, err
    assert "line 4 (pose): read only: not a literal value" in out
    assert "line 5 (joint): read only: not a literal value" in out and "compensated 1 of 4 targets" in out


def test_cli_compensates_a_program_and_prints_each_target(models, tmp_path, cli):
    nominal, calibrated = models
    rc.write_model(nominal, tmp_path / "nominal.yaml")
    rc.write_model(calibrated, tmp_path / "calibrated.yaml")
    far = "LIN {X 5000.0, Y 0.0, Z 0.0, A 0.0, B 0.0, C 0.0, S 0, T 0}\n"
    (tmp_path / "prog.txt").write_text((HERE / "example.src").read_text().replace("FDAT_ACT", far + "FDAT_ACT"))
    code, out, err = cli("compensate", tmp_path / "nominal.yaml", tmp_path / "calibrated.yaml", tmp_path / "prog.txt",
                         "--dialect", "krl", "--include", HERE / "$config.dat",
                         "--out", tmp_path / "prog-compensated.src")
    assert code == 0, err
    assert "line 10 (joint): moved " in out and " mm, turned " in out
    assert "line 12 (pose; tool TOOL_DATA[1], work object $NULLFRAME): moved " in out
    assert "line 18 (pose; tool TOOL_DATA[1], work object $NULLFRAME): no nominal solution" in out
    assert ": line 18: no nominal solution" in err and "(line 18)" not in err
    assert "compensated 5 of 6 targets" in out and "1 flagged" in out
    assert (tmp_path / "prog-compensated.src").read_text() != (HERE / "example.src").read_text()
    code, _, err = cli("compensate", tmp_path / "nominal.yaml", tmp_path / "calibrated.yaml", HERE / "example.mod",
                       "--tool", "tGriper", "--out", tmp_path / "t.mod")
    assert_one_line_error(code, err, ["--tool", "tGriper", "tGripper"], command="compensate")
    assert not (tmp_path / "t.mod").exists()
    # a program without a target compensated nothing and wrote a copy, exit 0
    (tmp_path / "empty.mod").write_text("MODULE Empty\nENDMODULE\n")
    code, _, err = cli("compensate", tmp_path / "nominal.yaml", tmp_path / "calibrated.yaml", tmp_path / "empty.mod",
                       "--out", tmp_path / "e.mod")
    assert_one_line_error(code, err, ["empty.mod", "no target in this rapid program"], command="compensate")
    assert not (tmp_path / "e.mod").exists()


def test_a_relative_motion_is_left_as_written_and_said(models, tmp_path):
    """KRL's relative motions (PTP_REL, LIN_REL...) move by an offset from wherever the robot is: no
    target of their own to compensate, and the summary said nothing of them."""
    nominal, calibrated = models
    text = (HERE / "example.src").read_text().replace("FDAT_ACT", "lin_rel {X 10.0, Z -5.0} C_DIS\nFDAT_ACT")
    program = _reread(tmp_path, text, "example.src")
    assert program.relative == (("PTP_REL", 17), ("LIN_REL", 18))
    result = compensate_program(program, nominal, calibrated, companions=_with(program))
    assert "PTP_REL (line 17), LIN_REL (line 18) left as written: a relative motion" in " ".join(result.notes)
    lines = result.text.splitlines()
    assert lines[16:18] == ["PTP_REL {A1 10.0}", "lin_rel {X 10.0, Z -5.0} C_DIS"]
    assert not any("REL" in n for n in _compensate(read_program(HERE / "example.mod"), nominal, calibrated).notes)


@pytest.mark.parametrize("example, dialect", [("example.mod", "rapid"), ("example.dat", "krl"),
                                              ("example.src", "krl"), ("example.script", "urscript")])
def test_a_program_under_a_name_no_dialect_claims_is_refused_naming_its_dialect(example, dialect, tmp_path, cli):
    """A program saved as .txt was read as a CSV of targets: "unknown column 'MODULE'" said nothing
    of the --dialect it needed."""
    rc.write_model(arm6r(), tmp_path / "m.yaml")
    (tmp_path / "prog.txt").write_text("\n" + (HERE / example).read_text())
    code, _, err = cli("compensate", tmp_path / "m.yaml", tmp_path / "m.yaml", tmp_path / "prog.txt",
                       "--out", tmp_path / "o" / "out.csv")
    assert_one_line_error(code, err, ["prog.txt", f"reads as a {dialect} program", f"give --dialect {dialect}"],
                          tmp_path / "o", command="compensate")
    # a CSV of targets with an unknown column keeps its own message
    (tmp_path / "t.csv").write_text("MODULE,j1\n1,2\n")
    code, _, err = cli("compensate", tmp_path / "m.yaml", tmp_path / "m.yaml", tmp_path / "t.csv",
                       "--out", tmp_path / "o" / "out.csv")
    assert_one_line_error(code, err, ["t.csv", "unknown column 'MODULE'"], tmp_path / "o", command="compensate")


def test_a_campaign_whose_joint_readings_are_controller_code_is_read(tmp_path, cli):
    """The tracker's file holds the points; the joint readings are the MoveAbsJ lines of a RAPID log."""
    model = arm6r()
    true, data = rc.simulate(model, 30, seed=5)
    rc.write_model(model, tmp_path / "model.yaml")
    rc.write_measurements(data, tmp_path / "all.csv", model=model)
    rows = (tmp_path / "all.csv").read_text().splitlines()
    header = rows[0].split(",")
    keep = [i for i, h in enumerate(header) if not h.startswith("j")]
    points = "\n".join(",".join(r.split(",")[i] for i in keep) for r in rows) + "\n"
    (tmp_path / "points.csv").write_text(points.replace("pose ", "p"))
    labels_rapid = [label.replace("pose ", "p") for label in data.labels]
    deg = np.degrees(data.q)
    moves = "".join(f"  CONST jointtarget {label} := [[{', '.join(repr(float(v)) for v in row)}], "
                    f"[9E9,9E9,9E9,9E9,9E9,9E9]];  ! pose {k}\n"
                    for k, (label, row) in enumerate(zip(labels_rapid, deg)))
    (tmp_path / "joints.mod").write_text(f"MODULE campaign\n{moves}ENDMODULE\n")
    labels, q = read_program_joints(tmp_path / "joints.mod", model)
    assert labels == labels_rapid and np.allclose(q, data.q, rtol=0, atol=1e-12)
    joined = rc.read_measurements(tmp_path / "points.csv", model, joints=tmp_path / "joints.mod")
    assert np.allclose(joined.q, data.q, rtol=0, atol=1e-12) and np.allclose(joined.positions, data.positions)
    code, out, err = cli("identifiability", tmp_path / "model.yaml", tmp_path / "points.csv", "--joints",
                         tmp_path / "joints.mod")
    assert code == 0, err
    assert out.splitlines()[0].startswith("identifiability of arm6r at the 30 poses of ")


def test_inverse_kinematics_keeps_the_posture_and_turns_asked_for():
    """The same tool pose in two postures (wrist flipped: axes 4 and 6 turned by half a turn, axis 5
    negated): each request gets its own solution back, and the turn window picks the axis-6 turn."""
    model = arm6r()
    q = np.radians([[20.0, -40.0, 60.0, 30.0, 50.0, 40.0]])
    flipped = q + np.radians([[0, 0, 0, 180.0, 0, 180.0]])
    flipped[0, 4] = -q[0, 4]
    P, R = _tool_pose(model, q)
    P2, R2 = _tool_pose(model, flipped)
    _assert_same_pose(P2, R2, P, R)                                   # one pose, two postures
    bits, bits2 = posture(model, q)[0], posture(model, flipped)[0]
    assert bits[2] != bits2[2] and (bits[:2] == bits2[:2]).all()
    for want, expected in ((bits, q), (bits2, flipped)):
        ik = inverse_kinematics(model, P, R, want=want[None].astype(int))
        assert ik.solved.all()
        assert np.allclose(np.angle(np.exp(1j * (ik.q - expected))), 0, atol=1e-7)
    turn = np.full((1, 6), np.nan)
    turn[0, 5] = np.radians(300.0) - np.pi                            # axis 6 in [120, 480) deg
    ik = inverse_kinematics(model, P, R, want=bits[None].astype(int), turn_from=turn)
    assert np.isclose(ik.q[0, 5], q[0, 5] + 2 * np.pi) and not ik.within_limits[0]


def test_elbow_bit_separates_the_two_arm_solutions(models):
    nominal, _ = models
    rng = np.random.default_rng(2)
    q = rng.uniform(nominal.lower_limits * 0.8, nominal.upper_limits * 0.8, (200, 6))
    P, R = _tool_pose(nominal, q)
    want = posture(nominal, q).astype(int)
    want[:, 1] = 1 - want[:, 1]                                     # the other elbow
    ik = inverse_kinematics(nominal, P, R, want=want)
    found = ik.solved
    assert found.mean() > 0.5
    _assert_same_pose(*_tool_pose(nominal, ik.q[found]), P[found], R[found])
    assert np.all(posture(nominal, ik.q[found]) == want[found].astype(bool))
    assert np.all(np.abs(ik.q[found] - q[found]).max(axis=1) > 1e-3)   # other joints than the sampled ones


def test_a_named_tool_is_the_model_with_that_tool_point(models, tmp_path):
    """example.mod moves with tGripper, arm6r's own tool point: the same as the flange (tool0) with
    --tool tGripper, and another tool moves the targets otherwise."""
    nominal, calibrated = models
    program = read_program(HERE / "example.mod")
    (tmp_path / "flange.mod").write_text((HERE / "example.mod").read_text().replace(", tGripper", ", tool0"))
    flange = read_program(tmp_path / "flange.mod")
    default = _compensate(program, nominal, calibrated)
    given = _compensate(flange, nominal, calibrated, tool="tGripper")
    assert [r.status for r in given.targets] == [r.status for r in default.targets]
    assert {r.tool for r in default.targets if r.kind == "pose"} == {"tGripper"}
    assert all(abs(a.moved - b.moved) < 1e-10 for a, b in zip(given.targets, default.targets))
    on_flange = _compensate(flange, nominal, calibrated)
    assert {r.tool for r in on_flange.targets if r.kind == "pose" and r.status == "ok"} == {"tool0"}
    assert any(abs(a.moved - b.moved) > 1e-6 for a, b in zip(on_flange.targets, default.targets) if a.status == "ok")


def test_krl_tool_and_base_data_are_named_frames_not_targets(models, tmp_path):
    """KRL ``TOOL_DATA[n]`` is a tool, ``BASE_DATA[n]`` a work object and another array's element a
    frame, each by its whole name; one without six literal numbers is no frame."""
    nominal, calibrated = models
    calibrated = calibrated.replace(markers=nominal.markers)        # a named tool is exact in both models
    data = ("TOOL_DATA[1]={X 50.0,Y 20.0,Z 120.0,A 0.0,B 0.0,C 0.0}\n"
            "BASE_DATA[2]={X 100.0,Y 0.0,Z 0.0,A 0.0,B 0.0,C 0.0}\n"
            "MY_FRAMES[3]={X 1.0,Y 2.0,Z 3.0,A 90.0,B 0.0,C 0.0}\nTOOL_DATA[4]={X 1.0,Y 0.0}\n")
    (tmp_path / "frames.src").write_text((HERE / "example.src").read_text().replace("$TOOL =", data + "$TOOL =", 1))
    program = read_program(tmp_path / "frames.src")
    frames = {f.name: f for f in program.frames}
    assert {name: f.kind for name, f in frames.items()} == {"TOOL_DATA[1]": "tool", "BASE_DATA[2]": "wobj",
                                                             "MY_FRAMES[3]": "frame"}
    assert np.allclose(frames["MY_FRAMES[3]"].X[:3, 3], [0.001, 0.002, 0.003])
    assert np.allclose(frames["MY_FRAMES[3]"].X[:3, :3], Rotation.from_euler("z", 90, degrees=True).as_matrix())
    own = read_program(HERE / "example.src").targets                 # the same targets, four lines down
    assert [(t.kind, t.line) for t in program.targets] == [(t.kind, t.line + 4) for t in own]
    # arm6r's own tool point is (50, 20, 120) mm on the last frame, with the frame's axes
    with_tool = _compensate(program, nominal, calibrated, tool="TOOL_DATA[1]")
    default = _compensate(program, nominal, calibrated)
    assert [r.status for r in with_tool.targets] == [r.status for r in default.targets]
    assert all(abs(a.moved - b.moved) < 1e-10 for a, b in zip(with_tool.targets, default.targets))
    with pytest.raises(rc.errors.InputError, match=r"'BASE_DATA\[2\]' is a wobj"):
        _compensate(program, nominal, calibrated, tool="BASE_DATA[2]")


@pytest.mark.parametrize("dialect", ["rapid", "krl", "urscript"])
def test_orientations_are_written_in_the_dialects_convention(dialect):
    """A rotation through the dialect's writer and back through its reader is the same rotation,
    and the form written is the one nearest the old (quaternion sign, ZYX triple, rotation vector)."""
    module = DIALECTS[dialect]
    rng = np.random.default_rng(1)
    R = Rotation.random(50, random_state=rng).as_matrix()
    size = {"rapid": 4, "krl": 3, "urscript": 3}[dialect]
    olds = rng.normal(size=(50, size)) * (1 if dialect != "krl" else 100)
    targets = [module.Target("t", "pose", 1, 1, position=_numbers([0, 0, 0]), orientation=_numbers(o)) for o in olds]
    values = module.orientation_values(R, targets)
    back = [module.Target("t", "pose", 1, 1, position=_numbers([0, 0, 0]), orientation=_numbers(v)) for v in values]
    X = module.poses(back)
    assert np.abs(X[:, :3, :3] - R).max() < 1e-12
    if dialect == "rapid":
        assert np.all(np.einsum("ni,ni->n", values, olds) >= 0)
    if dialect == "krl":
        assert np.all(np.abs(values - olds) <= 180.0 + 1e-9)


def _numbers(values):
    from robocal._files.programs.syntax import Number

    return tuple(Number(float(v), repr(float(v)), 0, 0) for v in values)


def test_cartesian_targets_need_a_six_axis_arm(tmp_path, cli):
    four = rc.serial_model("four", [dict(joint="revolute"), dict(joint="revolute", alpha=np.pi / 2),
                                    dict(joint="revolute", d=0.4), dict(joint="revolute", d=0.3)],
                           markers=[("tool", (0.1, 0, 0))])
    rc.write_model(four, tmp_path / "four.yaml")
    (tmp_path / "p.script").write_text("def a():\n  set_tcp(p[0.1, 0, 0, 0, 0, 0])\n"
                                       "  movel(p[0.3, 0.1, 0.2, 0, 3.14, 0], a=1)\nend\n")
    code, _, err = cli("compensate", tmp_path / "four.yaml", tmp_path / "four.yaml", tmp_path / "p.script",
                       "--out", tmp_path / "o.script")
    assert_one_line_error(code, err, ["p.script", "six-axis arm", "4 joints", "line 3"], command="compensate")


def test_rapid_targets_take_the_tool_and_work_object_their_motions_use(models, tmp_path):
    """tests/programs/tools.mod: p1 is moved to with tool tA and work object wB, p2 with tA (named
    in two cases), the elements of p3 by index in a loop through Offs with wB and tool0 (the
    flange), the inline target with tA: the same figures as when the tool and work object are
    given on the command line. A target moved to with two tools is flagged, one never moved to too."""
    nominal, calibrated = models
    program = read_program(HERE / "tools.mod")
    rows = {r.name: r for r in _compensate(program, nominal, calibrated).targets}
    assert {n: (r.tool, r.wobj, r.through) for n, r in rows.items()} == {
        "p1": ("tA", "wB", ""), "p2": ("tA", "wobj0", ""), "p3{1}": ("tool0", "wB", "Offs (line 12)"),
        "p3{2}": ("tool0", "wB", "Offs (line 12)"), "line 13": ("tA", "wobj0", "")}
    for name, tool, wobj in (("p1", "tA", "wB"), ("p3{1}", "tool0", "wB"), ("line 13", "tA", None),
                             ("p2", "tA", "wobj0")):
        alone = {r.name: r for r in _compensate(program, nominal, calibrated, tool=tool, wobj=wobj).targets}
        assert rows[name].status == "ok" and abs(rows[name].moved - alone[name].moved) < 1e-12
    assert len({round(rows[n].moved, 9) for n in ("p1", "p2", "p3{1}")}) == 3   # three frames
    text = (HERE / "tools.mod").read_text().replace("MoveL p2, v100, fine, TA;", "MoveL p2, v100, fine, tool0;")
    (tmp_path / "two.mod").write_text(text.replace("FOR i FROM 1 TO 2", "FOR i FROM 1 TO 1").replace("p3{i}", "p3{1}"))
    rows = {r.name: r for r in _compensate(read_program(tmp_path / "two.mod"), nominal, calibrated).targets}
    assert rows["p2"].status == ("moved to with several tools or work objects (tool tA, work object wobj0 at line "
                                 "10; tool tool0, work object wobj0 at line 11)")
    assert rows["p3{2}"].status == "not moved to by a motion of the program: its tool and work object are not known"
    assert {n for n, r in rows.items() if r.status != "ok"} == {"p2", "p3{2}"}


def _base_moved(model, seed):
    """``model`` with its base moved by a random rigid transform (metres, any rotation)."""
    rng = np.random.default_rng(seed)
    R = Rotation.random(random_state=rng).as_matrix()
    return model.replace(base_position=tuple(rng.uniform(-3.0, 3.0, 3)), base_rotation=tuple(map(tuple, R)))


@pytest.mark.parametrize("name", EXAMPLES)
def test_where_the_instrument_stood_never_moves_a_target(name, models):
    """A model's base is where the tracker saw the robot: moving only the nominal base by any rigid
    transform changes no target, and a calibrated robot that differs from the nominal only in its
    base (its tracker stood 50 mm elsewhere) leaves the program as it was."""
    nominal, calibrated = models
    program = read_program(HERE / name)
    ref = _compensate(program, nominal, calibrated)
    assert sum(r.status == "ok" for r in ref.targets) >= 3
    for seed in range(3):
        moved = _compensate(program, _base_moved(nominal, seed), calibrated)
        assert moved.text == ref.text
        assert all(abs(a.moved - b.moved) < 1e-12 for a, b in zip(moved.targets, ref.targets))
    elsewhere = nominal.replace(base_position=tuple(np.add(nominal.base_position, (0.05, 0.0, 0.0))))
    assert _compensate(program, nominal, elsewhere).text == program.text


def test_the_csv_path_is_blind_to_the_nominal_base(models, tmp_path, cli):
    """Joint targets in a CSV: the same commands whatever the nominal model's base."""
    nominal, calibrated = models
    q = np.radians([[10, -30, 40, 20, 50, -30], [-45, -50, 70, -100, -60, 120], [0, -40, 60, 0, 45, 0]])
    rows = ["pose,j1_rad,j2_rad,j3_rad,j4_rad,j5_rad,j6_rad"] + [f"P{i}," + ",".join(repr(float(v)) for v in r)
                                                                 for i, r in enumerate(q)]
    (tmp_path / "targets.csv").write_text("\n".join(rows) + "\n")
    rc.write_model(calibrated, tmp_path / "calibrated.yaml")
    written = []
    for k, model in enumerate([nominal, _base_moved(nominal, 1), _base_moved(nominal, 2)]):
        rc.write_model(model, tmp_path / f"nominal{k}.yaml")
        code, _, err = cli("compensate", tmp_path / f"nominal{k}.yaml", tmp_path / "calibrated.yaml",
                           tmp_path / "targets.csv", "--out", tmp_path / f"commands{k}.csv")
        assert code == 0, err
        written.append(np.genfromtxt(tmp_path / f"commands{k}.csv", delimiter=",", names=True))
    moved = [np.array([w[n] for n in written[0].dtype.names if n.startswith("j")]).T for w in written]
    assert np.abs(moved[0] - np.degrees(q)).max() > 1e-3                    # they were compensated
    assert all(np.abs(m - moved[0]).max() < 1e-9 for m in moved[1:])        # deg
    # in the robot's base frame the calibrated robot lands where the nominal one would have
    _assert_same_pose(*_tool_pose(_on_base(calibrated), np.radians(moved[0])), *_tool_pose(_on_base(nominal), q))


# -- cells as real ones are written: tests/programs/cells ----------------------------------------------

CELLS = HERE / "cells"
TH8 = HERE.parent.parent / "examples" / "th8"
IDENTITY = ("tool0", "wobj0", "$nullframe", "robot base")


def _cell(name):
    """A cell's program, the files read with it and its models: the glue cell runs on the simulated
    TH8 of examples/th8 (its true model as the calibrated one), the others on arm6r."""
    program = read_program(CELLS / name)
    others = {"pick.src": ("pick.dat", "$config.dat"), "pick.dat": ("pick.src", "$config.dat")}.get(name, ())
    if name == "glue.mod":
        models = rc.read_model(TH8 / "model.yaml"), rc.read_model(TH8 / "true_model.yaml")
    else:
        nominal = arm6r()
        models = nominal, perturb_model(nominal, rc.candidate_parameters(nominal, ("geometric",)), rng=3)
    return program, tuple(read_program(CELLS / o) for o in others), models


def _frame(programs, name):
    """The pose (4x4) of the tool or work object ``name`` the programs declare (the flange and the
    robot's base at the identity)."""
    if name.lower() in IDENTITY:
        return np.eye(4)
    return next(f.X for p in programs for f in p.frames if f.name.lower() == name.lower())


def _assert_each_lands(name, min_moved):
    """Every compensated pose target of the cell, given to the nominal controller in its tool and work
    object and configuration, puts the calibrated robot's tool where the program meant."""
    program, companions, (nominal, calibrated) = _cell(name)
    result = compensate_program(program, nominal, calibrated, companions=companions)
    module = DIALECTS[program.dialect]
    new = module.read(result.text, program.source)
    by_key = {(t.line, t.column): t for t in new.targets}
    rows = [r for r in result.targets if r.kind == "pose" and r.status == "ok"]
    assert rows and all(r.moved > min_moved for r in rows)
    for r in rows:
        old = next(t for t in program.targets if t.name == r.name and t.line == r.line)
        given = by_key[(old.line, old.column)]
        X_FT, X_BO = _frame((program, *companions), r.tool), _frame((program, *companions), r.wobj)
        tool = rc.Marker(r.tool, nominal.markers[0].frame, tuple(X_FT[:3, 3]), tuple(map(tuple, X_FT[:3, :3])))
        goal = X_BO @ module.poses([old])
        X = X_BO @ module.poses([given])
        want, turn = module.wanted(given, 6) if given.configuration else (np.full(3, -1), np.full(6, np.nan))
        hint = [None if given.configuration else q for q in _hint_rows(new, nominal, [(given, given)])]
        ik = inverse_kinematics(_on_base(nominal).replace(markers=(tool,)), X[:, :3, 3], X[:, :3, :3],
                                want=want[None], turn_from=turn[None],
                                hints=None if hint[0] is None else hint[0][None])
        assert ik.solved.all(), r.name
        _assert_same_pose(*_tool_pose(_on_base(calibrated).replace(markers=(tool,)), ik.q), goal[:, :3, 3],
                          goal[:, :3, :3])
    return result


def test_rapid_targets_by_index_in_a_loop_and_through_offs_and_reltool_keep_their_tool_and_work_object():
    """Why 2: the glue cell's bead (pBead{i} in a FOR loop), its approach through Offs and its
    departure through RelTool, all with the glue gun and the part's work object (\\WObj), land
    where the program meant on the calibrated TH8 (4.3-4.5 mm of correction each)."""
    result = _assert_each_lands("glue.mod", min_moved=1e-3)
    rows = {r.name: r for r in result.targets}
    assert {(r.tool, r.wobj) for n, r in rows.items() if n != "pService"} == {("tGlue", "wPart")}
    assert rows["pStart"].through == "Offs (line 20)" and rows["pEnd"].through == "RelTool (line 25)"
    assert {r.status for r in rows.values()} == {"ok"} and len(rows) == 8


def test_rapid_motions_with_arguments_after_the_tool_take_their_tool(models, tmp_path):
    """MoveLDO's signal and value, and MoveLSync's procedure, follow the tool: its targets were
    flagged 'its tool is not a name' and left unchanged."""
    nominal, calibrated = models
    program = read_program(HERE / "example.mod")
    text = program.text.replace("MoveJ pApproach, v1000, z50, tGripper;",
                                "MoveJDO pApproach, v1000, z50, tGripper, do1, 1;")
    text = text.replace("MoveL pLeave, v100, fine, tGripper;", 'MoveLSync pLeave, v100, fine, tGripper, "proc1";')
    assert text.count("DO pApproach") == 1 and text.count("Sync pLeave") == 1
    changed = _reread(tmp_path, text, "p.mod")
    before = {r.name: r for r in compensate_program(program, nominal, calibrated).targets}
    after = {r.name: r for r in compensate_program(changed, nominal, calibrated).targets}
    assert [(after[n].status, after[n].tool) for n in ("pApproach", "pLeave")] == [("ok", "tGripper")] * 2
    assert after == before


def test_a_rapid_jointtarget_of_external_axes_only_is_read_not_solved(models, tmp_path):
    """A jointtarget whose robot axes are all 9E9 (not used: MoveExtJ moves external axes only) was
    solved at 9E9 degrees and flagged out of reach."""
    nominal, calibrated = models
    unused = "[[9E9, 9E9, 9E9, 9E9, 9E9, 9E9], [1200, 9E9, 9E9, 9E9, 9E9, 9E9]]"
    text = (f"MODULE m\n  CONST jointtarget jTrack := {unused};\n  PROC main()\n    MoveExtJ jTrack, vrot50, z50;\n"
            f"    MoveExtJ {unused}, vrot50, fine;\n  ENDPROC\nENDMODULE\n")
    result = compensate_program(_reread(tmp_path, text, "p.mod"), nominal, calibrated)
    assert [(r.name, r.status) for r in result.targets] == [
        ("jTrack", "read only: its robot axes are 9E9 (not used)"),
        ("line 5", "read only: its robot axes are 9E9 (not used)")]
    assert result.text == text and not result.flagged


def test_a_program_compensated_with_an_identified_marker_says_what_it_cannot_carry(tmp_path, cli):
    """No campaign tells the flange's offset along the last axis from the marker's: a calibration that
    identified its marker puts that error in the marker, and a program's tools, exact on the flange,
    then land off by it without a word (the TH8 example calibrated without --known markers: its j6.r,
    3.7 mm short, went into the marker, and its program landed 3.6 mm off on the true robot against
    0.4 mm for the same targets as a CSV). The compensation now says so, with the figure."""
    nominal = arm6r()
    frames = list(nominal.frames)
    frames[5] = dataclasses.replace(frames[5], r=frames[5].r + 3e-3)
    flange = nominal.replace(frames=tuple(frames))               # the flange's error identified as such
    tool = nominal.markers[0]
    absorbed = nominal.replace(markers=(dataclasses.replace(tool, position=(0.05, 0.02, 0.123)),))
    program = read_program(HERE / "example.mod")
    with pytest.warns(rc.RobocalWarning, match=r"places marker tool 3 mm from its nominal place on the flange.*--known "
                                               "markers"):
        compensate_program(program, nominal, absorbed)
    with warnings.catch_warnings():
        warnings.simplefilter("error", rc.RobocalWarning)
        compensate_program(program, nominal, flange)
    for name, model in (("absorbed", absorbed), ("nominal", nominal)):
        rc.write_model(model, tmp_path / f"{name}.yaml")
    code, _, err = cli("compensate", tmp_path / "nominal.yaml", tmp_path / "absorbed.yaml", HERE / "example.mod",
                       "--out", tmp_path / "out.mod")
    assert code == 0 and err.count("marker tool 3 mm from its nominal place") == 1, err


def test_tool0_is_the_flange():
    """Why 6: tool0 is the flange the controller means, not the model's calibration sphere."""
    result = _assert_each_lands("glue.mod", min_moved=1e-3)
    service = next(r for r in result.targets if r.name == "pService")
    assert (service.tool, service.wobj, service.status) == ("tool0", "wobj0", "ok")


def test_krl_targets_take_the_tool_and_base_of_their_fdat_and_of_tool_and_base_from_config_dat():
    """Why 3: the pick cell's .dat points are moved to in folds (FDAT_ACT, BAS(#PTP_PARAMS) and
    BAS(#CP_PARAMS)) with TOOL_NO 1 and BASE_NO 2, and its .src's hand-written target after $TOOL =
    TOOL_DATA[1] and $BASE = BASE_DATA[2]; the frames are read from $config.dat."""
    for name in ("pick.dat", "pick.src"):
        result = _assert_each_lands(name, min_moved=1e-3)
        assert {(r.tool, r.wobj) for r in result.targets if r.kind == "pose"} == {("TOOL_DATA[1]", "BASE_DATA[2]")}


def test_krl_targets_whose_tool_data_are_not_read_are_flagged_and_left_unchanged():
    """Without the controller's $config.dat, TOOL_DATA[1] is not known: every pose target that uses
    it is flagged, naming the file that holds it, and its line stays as written."""
    program, companions, (nominal, calibrated) = _cell("pick.src")
    without = tuple(c for c in companions if not c.source.endswith("$config.dat"))
    result = compensate_program(program, nominal, calibrated, companions=without)
    (row,) = result.flagged
    assert row.status.startswith("its tool TOOL_DATA[1] is declared neither") and "$config.dat" in row.status
    kept = [ln for ln in result.text.splitlines() if not ln.lstrip().startswith(";")]
    assert kept == [ln for ln in program.text.splitlines() if not ln.lstrip().startswith(";")]


def test_krl_spline_segments_are_compensated_as_any_motion(models, tmp_path):
    """An SPL segment of a SPLINE block was not read: its point stayed where the nominal robot would
    have gone while the SLIN beside it moved, bending the path between them."""
    nominal, calibrated = models
    pose = "X 103.185, Y -20.000, Z -229.637, A 0.0000, B 65.0000, C 180.0000"
    text = ("DEF spline( )\n$TOOL = TOOL_DATA[1]\n$BASE = $NULLFRAME\n"
            "PTP {A1 0.0, A2 -40.0, A3 60.0, A4 0.0, A5 45.0, A6 0.0}\n"
            f"SPLINE\n  SPL {{{pose}}}\n  SLIN {{{pose}}}\n  SPL XP1\nENDSPLINE\nEND\n")
    program = _reread(tmp_path, text, "spline.src")
    assert [(t.name, t.kind) for t in program.targets] == [("line 4", "joint"), ("line 6", "pose"),
                                                           ("line 7", "pose")]
    assert [(u.name, u.line) for u in program.uses] == [("XP1", 8)]
    result = compensate_program(program, nominal, calibrated, companions=(read_program(HERE / "$config.dat"),))
    assert [r.status for r in result.targets] == ["ok"] * 3
    new = _reread(tmp_path, result.text, "new.src").targets
    # the two segments to the same point move alike
    assert new[1].position[0].text == new[2].position[0].text != program.targets[1].position[0].text


def test_krl_tool_and_base_set_to_a_literal_frame_are_those_frames(models, tmp_path):
    """``$TOOL = {X 50, ...}`` was taken for an expression and its targets flagged; a literal frame
    is the frame it writes, as TOOL_DATA[1] holding the same values is."""
    nominal, calibrated = models
    lin = "LIN {X 103.185, Y -20.000, Z -229.637, A 0.0000, B 65.0000, C 180.0000, S 'B000', T 'B001011'}\n"
    named = f"DEF a( )\n$TOOL = TOOL_DATA[1]\n$BASE = BASE_DATA[1]\n{lin}END\n"
    literal = (f"DEF a( )\n$TOOL = {{X 50.0,Y 20.0,Z 120.0,A 0.0,B 0.0,C 0.0}}\n"
               f"$BASE = {{X 100.0,Y 0.0,Z 0.0,A 0.0,B 0.0,C 0.0}}\n{lin}END\n")
    config = (read_program(HERE / "$config.dat"),)
    a = compensate_program(_reread(tmp_path, named, "a.src"), nominal, calibrated, companions=config)
    b = compensate_program(_reread(tmp_path, literal, "b.src"), nominal, calibrated)
    assert [(r.status, r.tool, r.wobj) for r in b.targets] == [("ok", "$TOOL (line 2)", "$BASE (line 3)")]
    assert a.targets[0].status == "ok" and b.text.splitlines()[3] == a.text.splitlines()[3] != lin.strip()


def test_krl_frame_declarations_are_never_moved():
    """Why 4: the fixture's FRAME in the .dat is a frame, not a motion target: its line stays."""
    program, companions, (nominal, calibrated) = _cell("pick.dat")
    result = compensate_program(program, nominal, calibrated, companions=companions)
    line = next(ln for ln in program.text.splitlines() if "XFIXTURE" in ln and "DECL" in ln)
    assert line in result.text.splitlines() and "XFIXTURE" not in {r.name for r in result.targets}
    assert result.text != program.text


def test_a_urscript_pose_reached_only_through_pose_add_is_listed_as_not_compensated(tmp_path, cli):
    """Why 7: `place` is moved to only through pose_add: listed, with the expression, and left as
    written; `pick`, also moved to directly, is compensated in the TCP set_tcp gives."""
    result = _assert_each_lands("pick.script", min_moved=1e-3)
    rows = {r.name.split(" ")[0]: r for r in result.targets}
    assert rows["place"].status == "not compensated: moved to only through pose_add (line 14)"
    assert rows["pick"].status == "ok" and rows["pick"].tool == "set_tcp (line 3)"
    assert rows["pick"].through == "pose_add (line 10), pose_add (line 12)"
    assert rows["place"] not in result.flagged
    program, _, (nominal, calibrated) = _cell("pick.script")
    rc.write_model(nominal, tmp_path / "n.yaml")
    rc.write_model(calibrated, tmp_path / "c.yaml")
    code, out, err = cli("compensate", tmp_path / "n.yaml", tmp_path / "c.yaml", CELLS / "pick.script",
                         "--out", tmp_path / "out.script")
    assert code == 0, err
    assert "place (line 6, pose): not compensated: moved to only through pose_add (line 14)" in out
    assert "2 reached only through expressions" in out


@pytest.mark.parametrize("name", ["glue.mod", "pick.src", "pick.dat", "$config.dat", "pick.script"])
def test_a_cell_comes_back_byte_for_byte_with_the_nominal_model_as_calibrated(name):
    if name == "$config.dat":
        program, companions, (nominal, _) = read_program(CELLS / name), (), _cell("pick.src")[2]
    else:
        program, companions, (nominal, _) = _cell(name)
    result = compensate_program(program, nominal, nominal, companions=companions)
    assert result.text.encode("utf-8") == (CELLS / name).read_bytes() and not result.flagged


@pytest.mark.parametrize("name", ["glue.mod", "pick.src", "pick.dat", "pick.script"])
def test_a_cell_is_blind_to_where_the_instrument_stood(name):
    program, companions, (nominal, calibrated) = _cell(name)
    ref = compensate_program(program, nominal, calibrated, companions=companions)
    for seed in range(2):
        moved = compensate_program(program, _base_moved(nominal, seed), calibrated, companions=companions)
        assert moved.text == ref.text


# peak memory of a process that reads a program, MB: its own (VmHWM), where ru_maxrss would carry
# the peak of the test's process, which forked it
READ_PEAK = """import re, sys
from robocal.io import read_program
try:
    read_program(sys.argv[1])
except Exception as e:
    print(e)
status = open("/proc/self/status").read()
print(int(re.search(r"VmHWM:\\s*(\\d+) kB", status).group(1)) / 1024)
"""


def test_a_program_of_a_million_targets_is_refused_in_little_memory(tmp_path):
    """A million literal moves (21 MB, under the byte bound) are refused by their tokens, counted
    before any is made: under 200 MB of the process, where reading the tokens first took 937 MB
    and 12 s."""
    import subprocess
    import sys
    path = tmp_path / "long.script"
    path.write_text("def p():\n" + "movej([0,0,0,0,0,0])\n" * 1_000_000 + "end\n")
    out = subprocess.run([sys.executable, "-c", READ_PEAK, str(path)], capture_output=True, text=True,
                         check=True).stdout.splitlines()
    assert float(out[1]) < 200, out
    assert "more than 1,000,000 tokens: not a robot program" in out[0] and "line 250000" in out[0]


def test_a_program_beyond_its_targets_is_refused_where_the_next_begins(tmp_path):
    """The targets are counted as they are read: the 30,001st is named, line and column."""
    path = tmp_path / "many.script"
    path.write_text("def p():\n" + "movej([0,0,0,0,0,0])\n" * 30_001 + "end\n")
    with pytest.raises(rc.InputError, match=r"line 30002, column 7: more than 30,000 targets"):
        read_program(path)


def test_a_program_over_its_bytes_is_refused_by_its_size(tmp_path):
    path = tmp_path / "large.mod"
    with open(path, "wb") as f:
        f.truncate(33 * 2 ** 20)
    with pytest.raises(rc.InputError, match="robocal reads files up to 32 MB"):
        read_program(path)


@pytest.mark.parametrize("targets, out, words", [
    ("program.mod", "commands.csv", "names a CSV file (.csv), but a rapid program compensated writes a rapid "
                                    "program file: give it a .mod, .modx, .prg, .sys or .sysx name"),
    ("targets.csv", "program.mod", "names a rapid program file (.mod), but a CSV of targets compensated writes a "
                                   "CSV file: give it a .csv name (a program's targets are compensated from the "
                                   "program itself)"),
    # a RAPID module written under a KRL or URScript name was read back as KRL and refused, exit 0
    ("program.mod", "program.src", "names a krl program file (.src)"),
    ("program.mod", "program.script", "names a urscript program file (.script)"),
    # commands written under a model file's or a URDF's name
    ("targets.csv", "commands.yaml", "names a model file (.yaml)"),
    ("targets.csv", "commands.URDF", "names a URDF file (.urdf)"),
])
def test_an_out_named_as_another_kind_is_refused(targets, out, words, cli, tmp_path):
    """The output is of the input's kind, never of the name's: an --out named as another kind of file
    (another dialect's program too) is refused before anything is read or written, even with --force."""
    th8 = Path(__file__).resolve().parents[1] / "examples" / "th8"
    (tmp_path / out).write_text("kept\n")
    code, _, err = cli("compensate", th8 / "model.yaml", th8 / "true_model.yaml", th8 / targets,
                       "--out", tmp_path / out, "--force")
    assert_one_line_error(code, err, ["--out", words], command="compensate")
    assert (tmp_path / out).read_text() == "kept\n"


def test_an_out_of_the_programs_dialect_is_taken(cli, tmp_path):
    """A RAPID module may be written under any RAPID extension, and a program read by --dialect under
    its own extension or a name robocal gives no kind."""
    th8 = Path(__file__).resolve().parents[1] / "examples" / "th8"
    (tmp_path / "program.txt").write_bytes((th8 / "program.mod").read_bytes())
    (tmp_path / "program.src").write_bytes((th8 / "program.mod").read_bytes())
    for targets, out, extra in ((th8 / "program.mod", "out.prg", ()),
                                (tmp_path / "program.txt", "out.txt", ("--dialect", "rapid")),
                                (tmp_path / "program.src", "out.src", ("--dialect", "rapid"))):
        code, _, err = cli("compensate", th8 / "model.yaml", th8 / "true_model.yaml", targets, "--out",
                           tmp_path / out, *extra)
        assert code == 0 and (tmp_path / out).exists(), err
