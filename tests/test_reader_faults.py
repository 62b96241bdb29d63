"""Each fault a reader finds, and each inconsistent record, is an InputError saying where it is and
what is wrong, in these words: measurement files (the same words whichever reader, row by row or
compiled, reads them), URDF, modified DH tables, profiles, repeatability files, models and
measurement records."""

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml
from fuzz_cases import MDH_TABLE, MEASUREMENTS, MODEL, PROFILE, REPEATABILITY, URDF
from robots import arm6r

import robocal as rc
from robocal.errors import InputError
from robocal.kinematics import Frame, Marker, Payload

LINES = MEASUREMENTS.splitlines()
HEADER = LINES[0]   # pose, j1_deg ... j6_deg, tool_x_mm, tool_y_mm, tool_z_mm, set


def _added(columns: str, values: str) -> str:
    return "\n".join([HEADER + "," + columns] + [ln + "," + values for ln in LINES[1:]]) + "\n"


def _renamed(old: str, new: str) -> str:
    return MEASUREMENTS.replace(HEADER, HEADER.replace(old, new), 1)


def _cell(row: int, column: str, value: str) -> str:
    rows = [ln.split(",") for ln in LINES]
    rows[row][rows[0].index(column)] = value
    return "\n".join(",".join(r) for r in rows) + "\n"


def _mapped(old: str, new: str, row: int, value: str) -> str:
    """The file with column ``old`` named ``new`` and its cell of ``row`` holding ``value``."""
    return _cell(row, old, value).replace(HEADER, HEADER.replace(old, new), 1)


def _fault(read) -> tuple:
    with pytest.raises(InputError) as e:
        read()
    return e.value.where, e.value.detail


ORIENTATION = "tool_qx,tool_qy,tool_qz,tool_qw"
APPROACH = ",".join(f"approach_j{j}" for j in range(1, 7))
NOT_CLOSED = "a quoted cell runs over several lines (a quote not closed?)"
UNSEEN = "\n".join([HEADER] + [",".join("" if 7 <= k <= 9 else c for k, c in enumerate(ln.split(",")))
                               for ln in LINES[1:]]) + "\n"

MEASUREMENT_FAULTS = [
    (_added(",x", "1,2"), {}, "line 1", "column 12 has no name"),
    (_added("set", "fit"), {}, "line 1", "column 'set' appears twice"),
    (_added("j1_rad", "0.1"), {}, "line 1", "joint 'j1' has two columns"),
    (_added("temp_C", "21"), {}, "line 1",
     "unknown column 'temp_C'; expected one of pose, set, series, payload_kg, j1, j2, j3, j4, j5, j6, tool_x, tool_y, "
     "tool_z; the model has joints j1, j2, j3, j4, j5, j6 and markers tool; map it (--map 'temp_C=NAME'), ignore it "
     "(--ignore 'temp_C') or ignore every unknown column (--unknown ignore)"),
    # a name the column map gave: the map is what to fix, the file's column what it names
    (MEASUREMENTS, {"columns": {"j4_deg": "jj4_deg"}}, "line 1",
     "unknown column 'jj4_deg', the name --map gives the file's column 'j4_deg'; expected one of pose, set, series, "
     "payload_kg, j1, j2, j3, j4, j5, j6, tool_x, tool_y, tool_z; the model has joints j1, j2, j3, j4, j5, j6 and "
     "markers tool; map it to one of those (--map 'j4_deg=NAME')"),
    # a cell of a column the map renamed: named by the file's own column, the map's name after it
    (_mapped("j1_deg", "joint_1", 5, "12.5abc"), {"columns": {"joint_1": "j1_deg"}},
     "line 6, column 'joint_1' (mapped to 'j1_deg')", "expected a number, got '12.5abc'"),
    (_mapped("tool_z_mm", "Z", 3, "1e13"), {"columns": {"Z": "tool_z_mm"}},
     "line 4, column 'Z' (mapped to 'tool_z_mm')", "'1e13' is too large for a measurement (magnitude up to 1e+12)"),
    (_mapped("set", "Split", 4, "train"), {"columns": {"Split": "set"}},
     "line 5, column 'Split' (mapped to 'set')", "set must be fit or validation, got 'train'"),
    (_mapped("j2_mm", "J2", 1, "571.1"), {"columns": {"J2": "j2"}}, "line 1, column 'J2' (mapped to 'j2')",
     "no length unit declared for this column: map it to j2_mm, put '# units: length=mm angle=deg' before the "
     "header, or pass units='mm-deg' (--units mm-deg on the command line)"),
    (_added("approach_j1", "1"), {}, "line 1",
     "missing column approach_j2: approach directions are given per joint, for every joint or none"),
    (_renamed("j1_deg", "jx_deg"), {"unknown": "ignore"}, "line 1",
     "missing column 'j1': the model has 6 joints (j1, j2, j3, j4, j5, j6), the file has 5 of them"),
    (_renamed("tool_x_mm,tool_y_mm,tool_z_mm", "a_mm,b_mm,c_mm"), {"unknown": "ignore"}, "line 1",
     "no marker columns (like tool_x, tool_y, tool_z); the model's markers are tool"),
    (_renamed("tool_z_mm", "z_mm"), {"unknown": "ignore"}, "line 1", "missing column tool_z"),
    (_added("tool_sigma_x_mm", "0.01"), {}, "line 1",
     "marker 'tool': give tool_sigma or all of tool_sigma_x, tool_sigma_y, tool_sigma_z, not a part of them"),
    (_added(ORIENTATION.replace("qx", "qx_deg"), "0,0,0,1"), {}, "line 1, column 'tool_qx_deg'",
     "a quaternion component has no unit"),
    (_added(ORIENTATION + ",tool_roll_deg", "0,0,0,1,0"), {}, "line 1",
     "marker 'tool' has orientation columns of two conventions (quat and rpy)"),
    (_added("tool_e1_deg,tool_e2_deg,tool_e3_deg", "0,0,0"), {}, "line 1",
     "columns tool_e1.. need the Euler sequence: orientation='euler:ZYX' (--orientation euler:ZYX) or a line "
     "'# orientation: euler:ZYX' before the header"),
    (_added("tool_sigma_rot_deg", "0.1"), {}, "line 1", "column tool_sigma_rot without orientation columns"),
    (_added("tool_roll_deg,tool_pitch_deg,tool_yaw_deg", "0,0,0"), {"orientation": "quat_xyzw"}, "line 1",
     "orientation columns of marker 'tool' are rpy, but the declared convention is quat"),
    (_cell(3, "set", "fit,extra"), {}, "line 4", "12 cells where the header has 11 columns"),
    (_added(APPROACH, "1,1,0,1,1,1"), {}, "line 2, column 'approach_j3'", "an approach direction is +1 or -1, got '0'"),
    (_cell(4, "set", "train"), {}, "line 5, column 'set'", "set must be fit or validation, got 'train'"),
    (_added(ORIENTATION, "0,0,0,0"), {}, "line 2, column 'tool_qx'", "quaternion of zero norm (or too large)"),
    (_cell(5, "tool_y_mm", ""), {}, "line 6, column 'tool_y_mm'",
     "empty cell while other tool cells of this group are filled; leave all of tool_x, tool_y, tool_z empty when the "
     "marker was not seen"),
    (_added("tool_sigma_mm", "-0.02"), {}, "line 2, column 'tool_sigma_mm'",
     "a standard deviation must be positive, got -0.02"),
    (UNSEEN, {}, None, "no marker position in any row"),
    (MEASUREMENTS.replace("\nP03,", '\n"P03,', 1), {}, "line 5", NOT_CLOSED),
    ('# note,"open\n' + MEASUREMENTS, {}, "line 2", NOT_CLOSED),
    (_cell(3, "pose", "P" + "x" * 200_000), {}, "line 4",
     "not readable as CSV: field larger than field limit (131072)"),
    ("\n".join(LINES[1:]) + "\n", {"header": HEADER.replace("set", "pose").split(",")}, "header",
     "expected distinct column names, got 'pose,j1_deg,j2_mm,j3_mm,j4_deg,j5_deg,j6_deg,tool_x_mm...' (81 characters)"),
]


@pytest.mark.parametrize("compiled", [False, True], ids=["rows", "compiled"])
@pytest.mark.parametrize("text, options, where, detail", MEASUREMENT_FAULTS,
                         ids=[f"{k}-{fault[3][:30]}" for k, fault in enumerate(MEASUREMENT_FAULTS)])
def test_a_measurement_files_fault_is_named_where_it_is(text, options, where, detail, compiled, tmp_path,
                                                         monkeypatch):
    """The compiled reader steps back wherever the file is at fault: the row reader names it."""
    import robocal._files.measurements as measurements

    def rows_only(*args, **kwargs):
        raise measurements.Unfit

    if not compiled:
        monkeypatch.setattr(measurements, "_read_fast", rows_only)
    (tmp_path / "model.yaml").write_text(MODEL)
    (tmp_path / "d.csv").write_text(text)
    model = rc.read_model(tmp_path / "model.yaml")
    assert _fault(lambda: rc.read_measurements(tmp_path / "d.csv", model, **options)) == (where, detail)


@pytest.mark.parametrize("old, new, where, detail", [
    ('<link name="l1">', "<link>", "link", "a <link> has no name"),
    ('<link name="l1">', '<link name="l0">', "link 'l0'", "link named twice"),
    ('<joint name="j1"', "<joint", "joint", "a <joint> has no name"),
    ('<joint name="j2"', '<joint name="j1"', "joint 'j1'", "joint named twice"),
    ('<parent link="l0"/>', "", "joint 'j1'", "<parent link=...> is missing"),
    ('<child link="l1"/>', '<child link="lx"/>', "joint 'j1'", "child link 'lx' is not defined"),
    ('<child link="l2"/>', '<child link="l1"/>', "joint 'j2'", "link 'l1' is the child of two joints ('j1')"),
    ('upper="1"/></joint>', 'upper="1"/><mimic multiplier="2"/></joint>', "joint 'j1'", "<mimic> needs joint=..."),
    ('lower="-1" upper="1"', 'lower="0" upper="0"', "joint 'j1'", "limit lower and upper are both 0 (a <limit> "
                                                                  "without them gives 0 and 0): a joint that cannot "
                                                                  "move; give its range"),
    # a negative mass became 0 kg on its frame, silently
    ('<link name="l1"><inertial><mass value="1"/>', '<link name="l1"><inertial><mass value="-1.377"/>',
     "link 'l1' inertial mass", "mass must be non-negative, got -1.377 kg"),
    # beyond what a model file holds (below 1e12 in mm and degrees): the import wrote a model that
    # did not read back
    ('<origin xyz="0 0 0.3"', '<origin xyz="0 0 1e11"', "joint 'j1' origin xyz",
     "'0 0 1e11' is too large (magnitude below 1e+09 m, what a model file holds)"),
    ('<mass value="1"/><origin xyz="0 0 0.1"/>', '<mass value="1"/><origin xyz="2e9 0 0.1"/>',
     "link 'l0' inertial origin xyz", "'2e9 0 0.1' is too large (magnitude below 1e+09 m, what a model file holds)"),
    ('lower="-1" upper="1"', 'lower="-1e11" upper="1"', "joint 'j1' limit lower",
     "'-1e11' is too large (magnitude below 1.74533e+10 rad, what a model file holds)"),
    ('<child link="l2"/><origin xyz="0 0 0.3" rpy="0 0.5 0"/><axis xyz="0 0 1"/><limit lower="-1" upper="1"/>',
     '<child link="l2"/><origin xyz="0 0 0.3" rpy="0 0.5 0"/><axis xyz="0 0 1"/><limit lower="-1" upper="2e9"/>',
     "joint 'j2' limit upper", "'2e9' is too large (magnitude below 1e+09 m, what a model file holds)"),
    ('upper="1"/></joint>', 'upper="1"/><mimic joint="j3" offset="1e11"/></joint>', "joint 'j1' mimic offset",
     "'1e11' is too large (magnitude below 1.74533e+10 rad, what a model file holds)"),
])
def test_a_urdf_links_and_joints_faults(old, new, where, detail):
    assert _fault(lambda: rc.io.read_urdf(URDF.replace(old, new, 1))) == (where, detail)


UR5_DH = (Path(__file__).resolve().parents[1] / "examples" / "dh" / "ur5-dh.csv").read_text()


@pytest.mark.parametrize("table, old, new, where, detail", [
    (MDH_TABLE, "j3,j2,revolute,j3,", "j3,j2,revolute,x*j3,", "line 5, column 'reading'",
     "a reading is NAME or COEF*NAME, got 'x*j3'"),
    (MDH_TABLE, "j3,j2,revolute,j3,", "j3,j2,revolute,,", "line 5, column 'reading'",
     "a moving frame needs a reading"),
    (MDH_TABLE, "j2,j1,revolute", "j2,j3,revolute", "line 4, column 'parent'",
     "parent 'j3' is not 'base' or an earlier frame"),
    (MDH_TABLE, "ball,j3,marker", "ball,j7,marker", "line 6, column 'parent'", "marker parent 'j7' is not a frame"),
    (MDH_TABLE, "reading,beta_deg", "reading,bta_deg", "line 1, column 'bta_deg'",
     "unknown column 'bta_deg'; did you mean 'beta_deg'?"),
    (MDH_TABLE, "j3,j2,revolute", "j2,j2,revolute", "line 5, column 'frame'", "'j2' already names line 4"),
    # a second base row: the last won, silently
    (UR5_DH, "base,base,,,,,,,0,0,0,0,0,0\n", "base,base,,,,,,,0,0,0,0,0,0\nbase,base,,,,,,,0,0,100,0,0,0\n",
     "line 5, column 'joint'", "a second base row (the first is line 4): a table places its first frame once"),
    # misspelt limit columns: ignored, and the limits +-180 degrees, not the table's
    (UR5_DH, "lower_deg,upper_deg", "lower_dg,uper_deg", "line 3, column 'lower_dg'",
     "unknown column 'lower_dg'; did you mean 'lower_deg'?"),
    (UR5_DH, "lower_deg,upper_deg", "lower_deg,uper_deg", "line 3, column 'uper_deg'",
     "unknown column 'uper_deg'; did you mean 'upper_deg'?"),
    # a name twice: 'frames: frame name 'shoulder_pan' is used twice', no line
    (UR5_DH, "elbow,revolute", "shoulder_pan,revolute", "line 7, column 'name'", "'shoulder_pan' already names line 5"),
    # beyond what a model file holds: named frames[2].d of the model it would have written
    (UR5_DH, "0,0,-425,0", "0,0,1e13,0", "line 6, column 'a_mm'",
     "'1e13' is too large for a robot (magnitude below 1e+12 in mm)"),
    # an angle's column suggested alpha_mm
    (UR5_DH, ",alpha_deg,", ",alpha,", "line 3, column 'alpha'", "alpha needs its unit: alpha_deg or alpha_rad"),
    (UR5_DH, ",a_mm,", ",a_deg,", "line 3, column 'a_deg'", "a is a length: a_mm or a_m"),
    (UR5_DH, ",lower_deg,", ",lower_mm,", "line 5, column 'lower_mm'",
     "a revolute joint's limits are lower_deg or lower_rad"),
    (UR5_DH, "0,0,-392.25,0,-180,180", "0,0,-392.25,0,10,10", "line 7",
     "lower limit '10' is not below upper limit '10': a joint that cannot move"),
    (UR5_DH, "tool,marker", "tool,fixed", "line 11, column 'joint'",
     "a classic DH row is a revolute or prismatic joint"),
])
def test_a_dh_tables_faults(table, old, new, where, detail, tmp_path):
    assert old in table
    (tmp_path / "t.csv").write_text(table.replace(old, new))
    assert _fault(lambda: rc.io.read_dh_table(tmp_path / "t.csv")) == (where, detail)


def test_a_dh_table_without_a_column_names_it_with_its_units(tmp_path):
    rows = [ln.split(",") for ln in UR5_DH.splitlines()]
    (tmp_path / "t.csv").write_text("\n".join(",".join(r[:5] + r[6:]) if len(r) > 5 else r[0] for r in rows))
    assert _fault(lambda: rc.io.read_dh_table(tmp_path / "t.csv")) == ("line 3",
                                                                     "no column alpha (alpha_deg or alpha_rad)")


def test_coupled_readings_in_a_modified_dh_table(tmp_path):
    """A reading that is a sum of coefficients times readings; the limits come from the first frame a
    reading drives alone."""
    (tmp_path / "t.csv").write_text(MDH_TABLE.replace("j3,j2,revolute,j3,", "j3,j2,revolute,j3 + 0.5*j2,"))
    model = rc.io.read_dh_table(tmp_path / "t.csv")
    assert [f.coupling for f in model.frames] == [((0, 1.0),), ((1, 1.0),), ((2, 1.0), (1, 0.5))]
    assert model.joint_names == ("j1", "j2", "j3")
    assert np.allclose(np.degrees(model.joint_limits), [(-170, 170), (-120, 120), (-170, 170)])


GOOD_PROFILE = yaml.safe_load(PROFILE)


@pytest.mark.parametrize("d, where, detail", [
    ([1], None, "expected a mapping (key: value) at the top"),
    ({**GOOD_PROFILE, "sepp": ";"}, "sepp", "unknown key 'sepp'; did you mean 'sep'?"),
    ({**GOOD_PROFILE, "robocal_profile": 2}, "robocal_profile", "expected robocal_profile: 1, got 2"),
    ({**GOOD_PROFILE, "key": 3}, "key", "expected text, got 3"),
    ({**GOOD_PROFILE, "sep": "ab"}, "sep", "a separator is one character, '\\t' or 'whitespace'; got 'ab'"),
    ({**GOOD_PROFILE, "ignore": "x"}, "ignore", "expected a list of column names, got 'x'"),
    ({**GOOD_PROFILE, "unknown": "maybe"}, "unknown", "unknown columns must be 'refuse' or 'ignore', got 'maybe'"),
    ({**GOOD_PROFILE, "header": ["a", " "]}, "header",
     "expected a list of column names (a file without a header line), got ['a', ' ']"),
])
def test_a_profiles_faults(d, where, detail):
    assert _fault(lambda: rc.io.profile_from_dict(d, source="p.yaml")) == (where, detail)


REPEATED = REPEATABILITY.splitlines()   # pose, cycle, x_mm, y_mm, z_mm; row 4 is pose 3, cycle 1


@pytest.mark.parametrize("text, units, where, detail", [
    (REPEATABILITY.replace(REPEATED[3], REPEATED[3].rsplit(",", 1)[0] + ","), None, "line 4, column 'z_mm'",
     "empty cell"),
    (REPEATABILITY.replace(REPEATED[3], REPEATED[3].replace(",1,", ",1.5,", 1)), None, "line 4, column 'cycle'",
     "expected an integer cycle number, got '1.5'"),
    (REPEATABILITY.replace(REPEATED[3], REPEATED[3].replace(",1,", ",1234567890,", 1)), None, "line 4, column 'cycle'",
     "expected an integer cycle number, got '1234567890'"),
    (REPEATABILITY.replace(REPEATED[3], REPEATED[3].rsplit(",", 1)[0] + ",x"), None, "line 4, column 'z_mm'",
     "expected a number, got 'x'"),
    (REPEATABILITY.replace(REPEATED[3], REPEATED[3].rsplit(",", 1)[0] + ",1e400"), None, "line 4, column 'z_mm'",
     "'1e400' is too large for a measurement (magnitude up to 1e+12)"),
    (REPEATABILITY + REPEATED[3] + "\n", None, "line 42", "pose '3' cycle 1 already given in line 4"),
    ("\n".join(REPEATED[:3] + [REPEATED[1].replace("1,1,", "99,1,", 1)]) + "\n", None, "line 2",
     "pose '1' has a single cycle; repeatability needs at least two"),
    (REPEATABILITY, "m", "line 1", "column 'x_mm' says mm but units 'm' were given"),
    # a position's axes in two units read 'repeatability 260.3 mm'
    (REPEATABILITY.replace("y_mm", "y_m", 1), None, "line 1",
     "columns 'x_mm', 'y_m', 'z_mm' are in different units: a position's axes share one unit (a column misnamed?)"),
])
def test_a_repeatability_files_faults(text, units, where, detail, tmp_path):
    (tmp_path / "r.csv").write_text(text)
    assert _fault(lambda: rc.io.read_repeatability_csv(tmp_path / "r.csv", units=units)) == (where, detail)


ARM = arm6r()
F = ARM.frames


@pytest.mark.parametrize("changes, where, detail", [
    ({"frames": ()}, "frames", "a model needs at least one frame"),
    ({"frames": (F[0], replace(F[1], name="j1")) + F[2:]}, "frames", "frame name 'j1' is used twice"),
    ({"joint_names": ("j1",) * 6}, "joints", "joint name 'j1' is used twice"),
    ({"joint_limits": ARM.joint_limits[:5]}, "joint_limits", "one (lower, upper) limit pair is needed per joint"),
    ({"joint_limits": ((1.0, -1.0),) + ARM.joint_limits[1:]}, "joints[0].limits",
     "lower limit 1.0 exceeds upper limit -1.0"),
    ({"joint_limits": ARM.joint_limits[:2] + ((0.5, 0.5),) + ARM.joint_limits[3:]}, "joints[2].limits",
     "lower and upper limit are both 0.5: a joint that cannot move"),
    ({"frames": (replace(F[0], joint="ball"),) + F[1:]}, "frames[0] (j1)",
     "joint type must be one of revolute, prismatic, fixed, got 'ball'"),
    ({"frames": (F[0], replace(F[1], parent=3)) + F[2:]}, "frames[1] (j2)",
     "a frame's parent must come before it (or be the base, -1)"),
    ({"frames": F + (Frame("flange", joint="fixed", coupling=((0, 1.0),)),)}, "frames[6] (flange)",
     "a fixed frame has no joint variable"),
    ({"frames": (replace(F[0], coupling=()),) + F[1:]}, "frames[0] (j1)",
     "a moving frame needs a joint reading (coupling)"),
    ({"frames": (replace(F[0], coupling=((7, 1.0),)),) + F[1:]}, "frames[0] (j1)",
     "coupling refers to joint 7, which does not exist"),
    ({"frames": (replace(F[0], mass=-1.0),) + F[1:]}, "frames[0] (j1)", "mass must be a non-negative number, got -1.0"),
    ({"frames": (replace(F[0], d=math.inf),) + F[1:]}, "frames[0] (j1)", "d is not a finite number"),
    ({"frames": (replace(F[0], backlash_width=0.0),) + F[1:]}, "frames[0] (j1)",
     "backlash_width must be positive and backlash_friction non-negative"),
    ({"backlash_side": "left"}, "backlash.side", "backlash side must be one of gravity, approach, got 'left'"),
    ({"payload": Payload(mass=-2.0)}, "payload", "payload mass must be non-negative, got -2.0"),
    ({"other_payloads": (Payload(mass=1.0, frame=9),)}, "payload[1]", "payload frame does not exist"),
    ({"markers": ARM.markers * 2}, "markers", "marker name 'tool' is used twice"),
    ({"markers": ()}, "markers", "a model needs at least one marker (tool point)"),
    ({"markers": (Marker("tool", 9),)}, "markers[0]", "marker 'tool' is attached to a frame that does not exist"),
    ({"markers": (Marker("tool", 5, rotation=((1, 0, 0), (0, 1, 0), (0, 0, -1))),)}, "markers[0].rotation",
     "not a proper rotation matrix"),
    ({"base_rotation": ((2, 0, 0), (0, 1, 0), (0, 0, 1))}, "base.rotation", "not a proper rotation matrix"),
])
def test_a_models_faults(changes, where, detail):
    assert _fault(lambda: ARM.replace(**changes)) == (where, detail)


NAN = np.nan


@pytest.mark.parametrize("changes, where, detail", [
    ({"positions": np.zeros((2, 1, 3))}, None, "positions must have shape (3, 1, 3), got (2, 1, 3)"),
    ({"q": [[0, 0], [0, NAN], [0, 0]]}, "b, joint 1", "joint reading is not a finite number"),
    ({"mask": np.ones((3, 2), bool)}, None, "mask shape does not match positions"),
    ({"positions": [[[0, 0, 0]], [[NAN, 0, 0]], [[0, 0, 0]]], "mask": np.ones((3, 1), bool)}, "b",
     "marker 'tool' position is not finite"),
    ({"rotations": np.zeros((3, 1, 3))}, None, "rotations must have shape (n_poses, n_markers, 3, 3)"),
    ({"sigma": [[1.0], [0.0], [1.0]]}, "b, marker 'tool'", "sigma must be a positive number"),
    ({"rotations": np.tile(np.eye(3), (3, 1, 1, 1)), "sigma_rot": -1.0}, "a, marker 'tool'",
     "sigma_rot must be a positive number"),
    ({"payload_mass": [1.0, -1.0, 1.0]}, "b", "payload mass must be a non-negative number"),
])
def test_a_measurement_records_faults(changes, where, detail):
    fields = {"q": np.zeros((3, 2)), "positions": np.zeros((3, 1, 3)), "marker_names": ("tool",),
              "labels": ("a", "b", "c"), "source": "m.csv"}
    assert _fault(lambda: rc.io.Measurements(**{**fields, **changes})) == (where, detail)
