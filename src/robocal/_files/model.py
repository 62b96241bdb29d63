"""The robot model file (YAML): reading, writing, and the units it is written in.

The format is documented in docs/formats.md. Units are converted to SI here and nowhere else in
the model's path: the file states its length and angle units, masses are kg, compliances are
always rad/(N m) and gravity m/s^2.
"""

from __future__ import annotations

import json
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import yaml

from .._base.arguments import (
    FLAG,
    MAPPING,
    PATH,
    TEXT,
    UNIT_SYSTEM,
    accepts,
    is_a,
    optional,
)
from .._base.errors import InputError, excerpt, suggest
from .._base.options import BACKLASH_SIDES, MAX_MODEL_BYTES
from .._base.spatial import nearest_rotation, pose4, vector3
from .._base.units import ANGLE_UNITS, LENGTH_UNITS, UNITS, check_unit, parse_units
from .._model.parameters import KIND_QUANTITY
from .._model.robot import (
    DEFAULT_PARALLEL_TOL,
    JOINT_TYPES,
    TRANSMISSION_KINDS,
    Frame,
    Marker,
    Payload,
    RobotModel,
    parallel_beta_frames,
    placement_parameters,
)
from .text import load_yaml, read_text, refuse_other_form, write_texts

# the calibrated model `robocal calibrate` writes into its output folder
CALIBRATED_MODEL = "calibrated.yaml"

FORMAT_VERSION = 1
# the file key is the frame's attribute; its quantity says which unit scales it
FRAME_VALUES: dict[str, str | None] = {k: KIND_QUANTITY[k] for k in ("beta", "alpha", "d", "theta", "r", "gamma", "b")}
FRAME_VALUES.update({"mass": None, "k_theta": None, "k_alpha": None, "k_beta": None})
# backlash: half the lost motion (the model's units), the load friction holds and the transition's
# width (N m on a revolute frame, N on a prismatic one, always SI); written where they differ from
# these defaults
BACKLASH_VALUES = {"backlash_theta": 0.0, "backlash_r": 0.0, "backlash_friction": 0.0, "backlash_width": 1.0}
# written where they differ from these (zero: no transmission error, no stated ratio)
DEFAULT_VALUES = {**BACKLASH_VALUES, **{k: 0.0 for k in TRANSMISSION_KINDS + ("reduction",)}}
FRAME_VALUES.update({k: KIND_QUANTITY.get(k) for k in BACKLASH_VALUES})
# transmission (docs/conventions.md): the stated reduction ratio (motor turns per joint turn) and the
# identified terms, the gear scale a plain ratio, the harmonics angles in the model's unit
FRAME_VALUES.update({k: None if KIND_QUANTITY[k] == "ratio" else KIND_QUANTITY[k] for k in TRANSMISSION_KINDS})
FRAME_VALUES["reduction"] = None
FRAME_KEYS = ("name", "joint", "reading", "coupling", "parent", "has_beta", "com", "position",
              "rotation") + tuple(FRAME_VALUES)
# the placement a fixed frame may give as a transform instead
PLACEMENT_KEYS = ("gamma", "b", "beta", "alpha", "d", "theta", "r")
# a printed rotation matrix is re-orthonormalised when its largest entry is at most this far from
# the nearest rotation (three printed decimals are 5e-4 off at worst)
ROTATION_TOLERANCE = 5e-3
TOP_KEYS = ("robocal_model", "name", "description", "units", "base", "gravity", "joints", "frames",
            "markers", "payload", "tolerances", "calibration", "backlash")
# tolerances: family -> the quantities a file may bound, and the unit each is given in
TOLERANCE_KEYS = {"frames": ("length", "angle"), "markers": ("length", "angle"), "base": ("length", "angle"),
                  "compliance": ("deflection",), "backlash": ("length", "angle"), "transmission": ("ratio", "angle")}
IDENTITY = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
# base.* names the base pose parameters, so no frame or marker may be called "base"
RESERVED_NAMES = ("base",)
# no quantity of a model, in any of its units, comes near this; beyond it arithmetic overflows
MAX_MAGNITUDE = 1e12
# the unit of each quantity a model file holds the largest numbers in (mm, deg), and the magnitude
# (SI) below which a value is held in every unit: what an importer may take
FINEST = {kind: min(table, key=table.__getitem__) for kind, table in UNITS.items()}
LARGEST = {kind: MAX_MAGNITUDE * UNITS[kind][FINEST[kind]] for kind in UNITS}
_NUMBER = re.compile(r"^[+-]?(\d+(\.\d*)?|\.\d+)([eE][+-]?\d+)?$")


class _Reader:
    """Typed access to a parsed YAML document; every error names the source and the key path."""

    def __init__(self, source: str):
        self.source = source
        self.notes: list[str] = []

    def error(self, where: str, message: str) -> InputError:
        return InputError(message, source=self.source, where=where)

    def mapping(self, value, where: str, allowed, required=()) -> dict:
        if not isinstance(value, dict):
            raise self.error(where, f"expected a mapping (key: value), got {_show(value)}")
        for key in value:
            if key not in allowed:
                raise self.error(_join(where, key), f"unknown key {key!r}{suggest(key, allowed)}")
        for key in required:
            if key not in value:
                raise self.error(_join(where, key), f"missing required key {key!r}")
        return value

    def sequence(self, value, where: str) -> list:
        if not isinstance(value, list):
            raise self.error(where, f"expected a list, got {_show(value)}")
        return value

    def number(self, value, where: str, *, finite: bool = True) -> float:
        # PyYAML reads 1e-3 (no dot) as text: accept numeric text rather than surprise the user
        if isinstance(value, str) and _NUMBER.match(value.strip()):
            value = float(value)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.error(where, f"expected a number, got {_show(value)}")
        if isinstance(value, int) and abs(value) >= MAX_MAGNITUDE:  # float() of a huge int overflows
            value = float("inf") if value > 0 else float("-inf")
        value = float(value)
        if np.isnan(value) or (finite and not abs(value) < MAX_MAGNITUDE):
            raise self.error(where, f"expected a finite number (magnitude below {MAX_MAGNITUDE:g}), got {value}")
        if not finite and np.isfinite(value) and not abs(value) < MAX_MAGNITUDE:  # .inf, or a size of this world
            raise self.error(where, f"expected .inf or a number of magnitude below {MAX_MAGNITUDE:g}, got {value}")
        return value

    def vector(self, value, where: str, n: int, scale: float = 1.0) -> tuple[float, ...]:
        seq = self.sequence(value, where)
        if len(seq) != n:
            raise self.error(where, f"expected {n} numbers, got {len(seq)}")
        return tuple(self.number(v, f"{where}[{i}]") * scale for i, v in enumerate(seq))

    def point(self, value, where: str, scale: float = 1.0) -> tuple[float, float, float]:
        return vector3(self.vector(value, where, 3, scale))

    def name(self, value, where: str) -> str:
        if not isinstance(value, str) or not value.strip():
            raise self.error(where, f"expected a name (text), got {_show(value)}")
        if value in RESERVED_NAMES:
            raise self.error(where, f"{value!r} is reserved for the base pose parameters; choose another name")
        return value

    def rotation(self, value, where: str, angle: float) -> tuple:
        d = self.mapping(value, where, ("rpy", "matrix", "quaternion_xyzw"))
        if len(d) != 1:
            raise self.error(where, "give exactly one of rpy, matrix, quaternion_xyzw")
        (kind, v), = d.items()
        w = f"{where}.{kind}"
        from scipy.spatial.transform import Rotation  # here: half a second of imports a refusal needs not

        if kind == "rpy":
            R = Rotation.from_euler("xyz", self.vector(v, w, 3, angle)).as_matrix()  # extrinsic: Rz Ry Rx
        elif kind == "quaternion_xyzw":
            quat = np.array(self.vector(v, w, 4))
            if np.linalg.norm(quat) < 1e-12:
                raise self.error(w, "quaternion has zero norm")
            R = Rotation.from_quat(quat).as_matrix()
        else:
            rows = self.sequence(v, w)
            if len(rows) != 3:
                raise self.error(w, "expected 3 rows of 3 numbers")
            R = self.proper(np.array([self.vector(row, f"{w}[{i}]", 3) for i, row in enumerate(rows)]), w)
        return tuple(tuple(float(x) for x in row) for row in R)

    def proper(self, M: np.ndarray, where: str) -> np.ndarray:
        """The rotation nearest a printed matrix, within ROTATION_TOLERANCE; the change goes in the notes."""
        R, deviation = nearest_rotation(M)
        if np.linalg.det(R) < 0:
            raise self.error(where, "a reflection (determinant -1), not a rotation: check the signs")
        if deviation > ROTATION_TOLERANCE:
            raise self.error(where, f"not a rotation matrix: an entry is {deviation:.2g} from the nearest rotation; "
                                    f"printed matrices are accepted within {ROTATION_TOLERANCE} "
                                    "(and re-orthonormalised)")
        if deviation > 1e-9:
            self.notes.append(f"{where}: re-orthonormalised (the largest entry moved by {deviation:.1e})")
        return R


def _join(where: str, key) -> str:
    return f"{where}.{key}" if where else str(key)


def _show(value) -> str:
    return excerpt(value)


@accepts(source=TEXT)
def model_from_dict(d: dict, *, source: str = "<dict>") -> RobotModel:
    """A RobotModel (SI) from the parsed model file ``d`` (docs/formats.md).

    Parameters
    ----------
    d : dict
        A model as ``model_to_dict`` gives it (the parsed YAML file).
    {source}

    Returns
    -------
    RobotModel
        The model.
    """
    return model_and_record(d, source)[0]


def model_and_record(d: dict, source: str = "<dict>") -> tuple[RobotModel, dict | None]:
    """``model_from_dict`` and the file's calibration record (None without one), its
    ``joint_ranges`` a (n_joints, 2) array of readings, SI (NaN for a joint it does not name)."""
    rd = _Reader(source)
    L, A = _units_of(rd, d)
    name = d.get("name", Path(source).stem)
    description = d.get("description", "") or ""
    if not isinstance(description, str):
        raise rd.error("description", f"expected text, got {_show(description)}")
    joint_names, raw_limits = _joints(rd, d["joints"])
    frames = _frames(rd, d["frames"], joint_names, L, A)
    frame_names = [f.name for f in frames]
    limits = _limits(rd, raw_limits, joint_names, frames, L, A)
    markers = _markers(rd, d["markers"], frame_names, L, A)
    base_position, base_rotation = (0.0, 0.0, 0.0), IDENTITY
    if d.get("base") is not None:
        base = rd.mapping(d["base"], "base", ("position", "rotation"))
        if "position" in base:
            base_position = rd.point(base["position"], "base.position", L)
        if "rotation" in base:
            base_rotation = rd.rotation(base["rotation"], "base.rotation", A)
    gravity = rd.point(d["gravity"], "gravity") if "gravity" in d else (0.0, 0.0, -9.81)
    payloads = _payloads(rd, d.get("payload"), frame_names, L)
    tolerances = _tolerances(rd, d.get("tolerances"), L, A)
    record = _calibration(rd, d.get("calibration"), joint_names, frames, L, A)
    try:
        model = RobotModel(name=str(name), frames=tuple(frames), joint_names=tuple(joint_names),
                           joint_limits=tuple(limits), markers=tuple(markers), base_position=base_position,
                           base_rotation=base_rotation, gravity=gravity, payload=payloads[0],
                           other_payloads=tuple(payloads[1:]), description=description, tolerances=tolerances,
                           notes=tuple(f"{source}: {n}" for n in rd.notes),
                           backlash_side=_backlash_side(rd, d.get("backlash")))
    except InputError as e:  # the record's own checks: add the file name
        raise InputError(e.detail, source=source, where=e.where) from None
    return model, record


CALIBRATION_KEYS = ("verdict", "failed", "warned", "date", "data", "poses", "families", "nominal", "joint_ranges")


def _calibration(rd: _Reader, value, joint_names: list[str], frames: list[Frame], L: float, A: float) -> dict | None:
    """The calibration record, its ``joint_ranges`` ({joint: [lo, hi]} in the file's units) as a
    (n_joints, 2) array, SI."""
    if value is None:
        return None
    record = dict(rd.mapping(value, "calibration", CALIBRATION_KEYS))
    if record.get("joint_ranges") is not None:
        given = rd.mapping(record["joint_ranges"], "calibration.joint_ranges", joint_names)
        ranges = np.full((len(joint_names), 2), np.nan)
        for jn, raw in given.items():
            j, where = joint_names.index(jn), f"calibration.joint_ranges.{jn}"
            ranges[j] = [rd.number(v, f"{where}[{k}]") * (L if _drives(frames, j) == "prismatic" else A)
                         for k, v in enumerate(_pair(rd, raw, where))]
            if not ranges[j, 0] <= ranges[j, 1]:
                raise rd.error(where, f"lowest reading exceeds highest ({raw[0]} > {raw[1]})")
        record["joint_ranges"] = ranges
    return record


def _drives(frames: list[Frame], j: int) -> str:
    """What joint ``j``'s reading drives (the first frame it drives): a reading is in the unit of
    that, the length unit for a prismatic frame, else the angle unit."""
    drives = [f.joint for f in frames if any(k == j for k, _ in f.coupling)]
    return drives[0] if drives else "revolute"


def _units_of(rd: _Reader, d) -> tuple[float, float]:
    """The top-level checks and the file's (length, angle) units as SI factors."""
    rd.mapping(d, "", TOP_KEYS, required=("robocal_model", "units", "joints", "frames", "markers"))
    version = d["robocal_model"]
    if version != FORMAT_VERSION or isinstance(version, bool):
        raise rd.error("robocal_model", f"the format version is the number {FORMAT_VERSION}, written without quotes; "
                                        f"got the text {version!r}" if str(version).strip() == str(FORMAT_VERSION) else
                       f"unsupported format version {excerpt(version)}; this robocal reads version {FORMAT_VERSION}")
    units = rd.mapping(d["units"], "units", ("length", "angle"), required=("length", "angle"))
    L = LENGTH_UNITS[check_unit(units["length"], "length", source=rd.source, where="units.length")]
    A = ANGLE_UNITS[check_unit(units["angle"], "angle", source=rd.source, where="units.angle")]
    return L, A


def _joints(rd: _Reader, value) -> tuple[list[str], list]:
    """Joint names and their raw limits (read once the frames say what each reading drives)."""
    joint_names: list[str] = []
    raw_limits = []
    for j, item in enumerate(rd.sequence(value, "joints")):
        where = f"joints[{j}]"
        if isinstance(item, str):
            item = {"name": item}
        rd.mapping(item, where, ("name", "limits"), required=("name",))
        jn = rd.name(item["name"], f"{where}.name")
        if jn in joint_names:
            raise rd.error(f"{where}.name", f"joint {jn!r} is named twice (also joints[{joint_names.index(jn)}])")
        joint_names.append(jn)
        raw_limits.append(item.get("limits"))
    return joint_names, raw_limits


def _frames(rd: _Reader, value, joint_names: list[str], L: float, A: float) -> list[Frame]:
    frame_items = rd.sequence(value, "frames")
    if not frame_items:
        raise rd.error("frames", "a model needs at least one frame")
    frames: list[Frame] = []
    used_joints: set[int] = set()
    auto_beta: list[int] = []
    for i, item in enumerate(frame_items):
        frame, auto = _frame(rd, item, f"frames[{i}]", i, frames, joint_names, used_joints, L, A)
        used_joints.update(j for j, _ in frame.coupling)
        if auto:
            auto_beta.append(i)
        frames.append(frame)
    beta = parallel_beta_frames(frames, DEFAULT_PARALLEL_TOL)
    return [replace(f, has_beta=beta[i]) if i in auto_beta else f for i, f in enumerate(frames)]


def _frame(rd: _Reader, item, where: str, i: int, earlier: list[Frame], joint_names: list[str],
           used_joints: set[int], L: float, A: float) -> tuple[Frame, bool]:
    """One frame, and whether its has_beta is left to the parallel-axes rule."""
    frame_names = [f.name for f in earlier]
    rd.mapping(item, where, FRAME_KEYS, required=("name", "joint"))
    fn = rd.name(item["name"], f"{where}.name")
    if fn in frame_names:
        raise rd.error(f"{where}.name", f"frame {fn!r} is named twice (also frames[{frame_names.index(fn)}])")
    joint = item["joint"]
    if joint not in JOINT_TYPES:
        raise rd.error(f"{where}.joint", f"joint type must be one of {', '.join(JOINT_TYPES)}, got {_show(joint)}")
    coupling = _coupling(rd, item, where, fn, joint, joint_names, used_joints)
    parent = _parent(rd, item.get("parent"), f"{where}.parent", i, frame_names)
    values = {k: rd.number(item[k], f"{where}.{k}") * (L if u == "length" else A if u == "angle" else 1.0)
              for k, u in FRAME_VALUES.items() if k in item}
    values.update(_placement(rd, item, where, joint, L, A))
    com = rd.point(item["com"], f"{where}.com", L) if "com" in item else (0.0, 0.0, 0.0)
    hb = item.get("has_beta", "auto")
    if hb not in (True, False, "auto"):
        raise rd.error(f"{where}.has_beta", f"expected auto, true or false, got {_show(hb)}")
    return Frame(name=fn, joint=joint, parent=parent, coupling=coupling, com=com, has_beta=bool(hb is True),
                 **values), hb == "auto"


def _placement(rd: _Reader, item: dict, where: str, joint: str, L: float, A: float) -> dict:
    """A fixed frame given by ``position`` and ``rotation`` in its parent: the equivalent gamma ... r."""
    given = [k for k in ("position", "rotation") if k in item]
    if not given:
        return {}
    if joint != "fixed":
        raise rd.error(f"{where}.{given[0]}", "only a fixed frame may be placed by position and rotation; a moving "
                                              "frame's placement is its DH values (alpha, d, theta, r...)")
    both = [k for k in PLACEMENT_KEYS if k in item]
    if both:
        raise rd.error(f"{where}.{both[0]}",
                       f"give the placement either as position/rotation or as {', '.join(PLACEMENT_KEYS)}, "
                                             "not both")
    p = rd.point(item["position"], f"{where}.position", L) if "position" in item else (0.0, 0.0, 0.0)
    R = rd.rotation(item["rotation"], f"{where}.rotation", A) if "rotation" in item else IDENTITY
    return placement_parameters(pose4(np.asarray(R), p))


def _limits(rd: _Reader, raw_limits: list, joint_names: list[str], frames: list[Frame], L: float,
            A: float) -> list[tuple[float, float]]:
    limits = []
    for j, raw in enumerate(raw_limits):
        # a limit is in the unit of what the reading drives: a length for a prismatic frame
        if not any(k == j for f in frames for k, _ in f.coupling):     # declared, yet moving nothing
            raise rd.error(f"joints[{j}]", f"joint {joint_names[j]!r} drives no frame (no frame's reading or "
                                           "coupling names it): add the frame it moves, or leave the joint out")
        where = f"joints[{j}].limits"
        if raw is None:
            if _drives(frames, j) == "prismatic":
                raise rd.error(where, f"missing required key 'limits' (joint {joint_names[j]!r} is prismatic)")
            limits.append((-np.pi, np.pi))
            continue
        scale = L if _drives(frames, j) == "prismatic" else A
        lo, hi = (rd.number(v, f"{where}[{k}]", finite=False) * scale
                  for k, v in enumerate(_pair(rd, raw, where)))
        if not lo <= hi:
            raise rd.error(where, f"lower limit exceeds upper limit ({raw[0]} > {raw[1]})")
        if lo == hi and np.isfinite(lo):     # (both infinite: no finite range, said where it is sampled)
            raise rd.error(where, f"lower and upper limit are both {raw[0]}: a joint that cannot move can be neither "
                                  "moved nor calibrated (a locked joint's frame is fixed)")
        limits.append((lo, hi))
    return limits


def _markers(rd: _Reader, value, frame_names: list[str], L: float, A: float) -> list[Marker]:
    markers = []
    marker_names: list[str] = []
    for m, item in enumerate(rd.sequence(value, "markers")):
        where = f"markers[{m}]"
        rd.mapping(item, where, ("name", "frame", "position", "rotation"), required=("name", "frame"))
        mn = rd.name(item["name"], f"{where}.name")
        if mn in marker_names:
            raise rd.error(f"{where}.name", f"marker {mn!r} is named twice (also markers[{marker_names.index(mn)}])")
        marker_names.append(mn)
        fi = _frame_ref(rd, item["frame"], f"{where}.frame", frame_names)
        pos = rd.point(item["position"], f"{where}.position", L) if "position" in item else (0.0, 0.0, 0.0)
        # 'rotation: unknown': the tool's orientation is not known; it starts at identity, and a
        # calibration gives its change no tolerance
        unknown = item.get("rotation") == "unknown"
        rot = rd.rotation(item["rotation"], f"{where}.rotation", A) if "rotation" in item and not unknown else IDENTITY
        markers.append(Marker(mn, fi, pos, rot, rotation_known=not unknown))
    return markers


def _backlash_side(rd: _Reader, value) -> str:
    """``backlash: {side: gravity | approach}`` (default gravity)."""
    if value is None:
        return "gravity"
    side = rd.mapping(value, "backlash", ("side",)).get("side", "gravity")
    if side not in BACKLASH_SIDES:
        raise rd.error("backlash.side", f"expected one of {', '.join(BACKLASH_SIDES)}, got {_show(side)}")
    return side


def _payloads(rd: _Reader, value, frame_names: list[str], L: float) -> list[Payload]:
    """One payload (a mapping) or several (a list of them, each on its own frame)."""
    if value is None:
        return [Payload()]
    if not isinstance(value, list):
        return [_payload(rd, value, "payload", frame_names, L)]
    if not value:
        raise rd.error("payload", "an empty list: leave the key out for no payload")
    return [_payload(rd, v, f"payload[{k}]", frame_names, L) for k, v in enumerate(value)]


def _payload(rd: _Reader, value, where: str, frame_names: list[str], L: float) -> Payload:
    pl = rd.mapping(value, where, ("mass", "com", "frame"))
    return Payload(
        mass=rd.number(pl["mass"], f"{where}.mass") if "mass" in pl else 0.0,
        com=rd.point(pl["com"], f"{where}.com", L) if "com" in pl else (0.0, 0.0, 0.0),
        frame=_frame_ref(rd, pl["frame"], f"{where}.frame", frame_names) if "frame" in pl else -1)


def _tolerances(rd: _Reader, value, L: float, A: float) -> tuple:
    """``tolerances: {frames: {length: 10, angle: 2}, compliance: {deflection: 1}, ...}`` in the file's
    units (a deflection is an angle); null for no bound. Returns (family, quantity, SI value) triples."""
    if value is None:
        return ()
    out = []
    for family, bounds in rd.mapping(value, "tolerances", tuple(TOLERANCE_KEYS)).items():
        where = f"tolerances.{family}"
        for key, v in rd.mapping(bounds, where, TOLERANCE_KEYS[family]).items():
            if v is not None:
                v = rd.number(v, f"{where}.{key}")
                if v <= 0:
                    raise rd.error(f"{where}.{key}", f"a tolerance must be positive (or null for none), got {v}")
                v *= L if key == "length" else 1.0 if key == "ratio" else A
            out.append((family, "compliance" if key == "deflection" else key, v))
    return tuple(out)


def _tolerances_dict(model: RobotModel, L: float, A: float) -> dict:
    out: dict = {}
    for family, quantity, v in model.tolerances:
        key = "deflection" if quantity == "compliance" else quantity
        unit = L if key == "length" else 1.0 if key == "ratio" else A
        out.setdefault(family, {})[key] = None if v is None else float(f"{v / unit:.15g}")
    return out


def _pair(rd: _Reader, raw, where: str) -> list:
    seq = rd.sequence(raw, where)
    if len(seq) != 2:
        raise rd.error(where, f"expected [lower, upper], got {len(seq)} numbers")
    return seq


def _frame_ref(rd: _Reader, value, where: str, frame_names: list[str]) -> int:
    if value not in frame_names:
        raise rd.error(where, f"unknown frame {_show(value)}{suggest(value, frame_names)}")
    return frame_names.index(value)


def _parent(rd: _Reader, value, where: str, i: int, earlier: list[str]) -> int:
    if value is None:
        return i - 1  # the previous frame; for the first frame, the base (-1)
    if value == "base":
        return -1
    if value not in earlier:
        raise rd.error(where, f"parent {_show(value)} is not a frame defined before this one"
                              f"{suggest(value, earlier + ['base'])}")
    return earlier.index(value)


def _coupling(rd: _Reader, item: dict, where: str, fname: str, joint: str, joint_names: list[str],
              used: set[int]) -> tuple:
    if joint == "fixed":
        for key in ("reading", "coupling"):
            if key in item:
                raise rd.error(f"{where}.{key}", "a fixed frame has no joint reading")
        return ()
    if "reading" in item and "coupling" in item:
        raise rd.error(f"{where}.coupling", "give either reading or coupling, not both")
    if "coupling" in item:
        c = rd.mapping(item["coupling"], f"{where}.coupling", joint_names)
        if not c:
            raise rd.error(f"{where}.coupling", "a coupling needs at least one joint")
        return tuple((joint_names.index(jn), rd.number(v, f"{where}.coupling.{jn}")) for jn, v in c.items())
    if "reading" in item:
        jn = item["reading"]
        if jn not in joint_names:
            raise rd.error(f"{where}.reading", f"unknown joint {_show(jn)}{suggest(jn, joint_names)}")
        return ((joint_names.index(jn), 1.0),)
    if fname in joint_names:
        return ((joint_names.index(fname), 1.0),)
    free = [j for j in range(len(joint_names)) if j not in used]
    if not free:
        raise rd.error(f"{where}.reading", "no joint reading is left for this moving frame; add one under "
                                           "joints or set reading/coupling")
    return ((free[0], 1.0),)


def _calibrated_beside(text: str) -> str:
    """Where the calibrated model of the result in ``text`` is: beside it, unless the calibration
    failed its checks (then it is written only when asked, carrying the verdict)."""
    try:
        failed = json.loads(text).get("verdict") == "fail"
    except (ValueError, AttributeError, RecursionError):     # no result to tell: say where it would be
        failed = False
    if not failed:
        return f"the calibrated model is {CALIBRATED_MODEL}, written beside it"
    return (f"its calibration failed its checks (the verdict in the file): {CALIBRATED_MODEL} is written beside it "
            "only by `robocal calibrate --write-failed`, carrying that verdict; `robocal report` on it says why")


@accepts(path=PATH)
def read_model(path) -> RobotModel:
    """Read a model file (docs/formats.md) into a RobotModel in SI units.

    Parameters
    ----------
    {path}

    Returns
    -------
    RobotModel
        The model.
    """
    return read_model_and_record(path)[0]


def read_model_and_record(path) -> tuple[RobotModel, dict | None]:
    """``read_model`` and the file's calibration record (``read_calibration``)."""
    source = str(path)
    if Path(path).is_dir() and (Path(path) / CALIBRATED_MODEL).is_file():
        raise InputError(f"a folder of a calibration's outputs, not a model file: its calibrated model is "
                         f"{Path(path) / CALIBRATED_MODEL}", source=source)
    text = read_text(path, limit=MAX_MODEL_BYTES)[0]
    refuse_other_form(text, source, "a robocal model file", ("model", "json"),       # a model may be JSON too
                      {"result": _calibrated_beside(text)})
    d = load_yaml(text, source)
    if d is None:
        raise InputError("the file is empty", source=source)
    return model_and_record(d, source)


@accepts(path=PATH)
def read_calibration(path) -> dict | None:
    """The calibration record of a calibrated model file (``calibration_record``'s, as the file holds
    it), None for a model no calibration wrote.

    Parameters
    ----------
    {path}

    Returns
    -------
    dict or None
        The record; its ``joint_ranges``, where present, a (n_joints, 2) array of each joint's
        lowest and highest reading over the poses the model was fitted on, SI (NaN for a joint the
        file does not name).
    """
    return read_model_and_record(path)[1]


@accepts(model=is_a(RobotModel), units=UNIT_SYSTEM, calibration=optional(MAPPING))
def model_to_dict(model: RobotModel, *, units: str = "mm-deg", calibration: dict | None = None) -> dict:
    """The model file form of ``model`` (plain Python types, ready for YAML or JSON).

    ``calibration``: what a calibration said of this model (its verdict and the checks that did not
    pass), written under the key of that name so that nobody mistakes a failed result for a good one;
    the description then says the model is calibrated, from what and when (``calibrated_description``).

    Parameters
    ----------
    {model, units, calibration}

    Returns
    -------
    dict
        The model as the YAML file holds it.
    """
    lu, au = parse_units(units)
    L, A = LENGTH_UNITS[lu], ANGLE_UNITS[au]
    scale = {"length": 1.0 / L, "angle": 1.0 / A, None: 1.0}
    d = {"robocal_model": FORMAT_VERSION, "name": model.name}
    description = model.description
    if calibration:     # not the nominal's; imported here, as reading a model needs none of the results
        from .._identification.result import calibrated_description

        description = calibrated_description(calibration)
    if description:
        d["description"] = description
    d.update({"units": {"length": lu, "angle": au}, "base": _base_dict(model, scale["length"]),
              "gravity": _vec(model.gravity),
              "joints": [{"name": jn, "limits": _vec(model.joint_limits[j], scale[model.reading_quantities[j]])}
                         for j, jn in enumerate(model.joint_names)],
              "frames": [_frame_dict(model, i, scale) for i in range(len(model.frames))],
              "markers": [_marker_dict(model, mk, scale["length"]) for mk in model.markers]})
    payload = _payload_dict(model, scale["length"])
    if payload is not None:
        d["payload"] = payload
    if model.tolerances:
        d["tolerances"] = _tolerances_dict(model, L, A)
    if model.backlash_side != "gravity" or model.has_backlash:
        d["backlash"] = {"side": model.backlash_side}
    if calibration:
        d["calibration"] = _calibration_dict(model, calibration, scale)
    return d


def _calibration_dict(model: RobotModel, calibration: dict, scale: dict) -> dict:
    """The calibration record as the file holds it: ``joint_ranges`` ({joint: [lo, hi]}, SI, or a
    (n_joints, 2) array as ``model_and_record`` reads it) in the file's units."""
    out = dict(calibration)
    ranges = calibration.get("joint_ranges")
    if ranges is None:
        return out
    if not isinstance(ranges, dict):
        ranges = dict(zip(model.joint_names, np.asarray(ranges, dtype=float)))
    out["joint_ranges"] = {jn: _vec(ranges[jn], scale[k]) for jn, k in zip(model.joint_names, model.reading_quantities)
                           if jn in ranges and np.all(np.isfinite(ranges[jn]))}
    return out


def _num(x, s: float = 1.0) -> float:
    """``x`` in the file's unit (``s``: file units per SI unit)."""
    # 15 digits drop the conversion's last-bit noise (-119.99999999999999 deg); still exact to 1e-15
    return float(f"{float(x) * s:.15g}") if s != 1.0 else float(x)


def _vec(v, s: float = 1.0) -> list[float]:
    return [_num(x, s) for x in v]


def _matrix(R) -> dict:
    return {"matrix": [_vec(row) for row in R]}  # a matrix keeps a calibrated rotation exact


def _frame_dict(model: RobotModel, i: int, scale: dict) -> dict:
    """Frame ``i`` as the file holds it: what differs from the defaults of a serial chain."""
    f = model.frames[i]
    row: dict[str, object] = {"name": f.name, "joint": f.joint, **_reading_dict(model, f)}
    if f.parent != i - 1:
        row["parent"] = "base" if f.parent < 0 else model.frames[f.parent].name
    for k, u in FRAME_VALUES.items():
        if k in ("gamma", "b") and f.parent == i - 1 and getattr(f, k) == 0.0:
            continue  # tree offsets: only worth showing where they are used
        if getattr(f, k) == DEFAULT_VALUES.get(k):
            continue
        row[k] = _num(getattr(f, k), scale[u])
        if k == "r":
            row["has_beta"] = bool(f.has_beta)
        if k == "mass":
            row["com"] = _vec(f.com, scale["length"])
    return row


def _reading_dict(model: RobotModel, f: Frame) -> dict:
    """A frame's joint variable: one joint's reading, a sum of readings (coupling), or none (fixed)."""
    if len(f.coupling) == 1 and f.coupling[0][1] == 1.0:
        return {"reading": model.joint_names[f.coupling[0][0]]}
    c: dict[str, float] = {}
    for j, coef in f.coupling:
        c[model.joint_names[j]] = c.get(model.joint_names[j], 0.0) + float(coef)
    return {"coupling": c} if c else {}


def _marker_dict(model: RobotModel, mk: Marker, length: float) -> dict:
    row: dict[str, object] = {"name": mk.name, "frame": model.frames[mk.frame].name,
                              "position": _vec(mk.position, length)}
    if not np.array_equal(np.asarray(mk.rotation), np.eye(3)):
        row["rotation"] = _matrix(mk.rotation)
    elif not mk.rotation_known:
        row["rotation"] = "unknown"
    return row


def _base_dict(model: RobotModel, length: float) -> dict:
    base: dict[str, object] = {"position": _vec(model.base_position, length)}
    if not np.array_equal(np.asarray(model.base_rotation), np.eye(3)):
        base["rotation"] = _matrix(model.base_rotation)
    return base


def _payload_dict(model: RobotModel, length: float) -> list | dict | None:
    """The payloads (a list), the one payload, or None where there is none to write."""
    payloads = []
    for pl in model.payloads:
        payloads.append({"mass": float(pl.mass), "com": _vec(pl.com, length)})
        if pl.frame != -1:  # -1 means the last frame; keep it so
            payloads[-1]["frame"] = model.frames[pl.frame].name
    pl = model.payload
    if model.other_payloads:
        return payloads
    if pl.mass or any(pl.com) or pl.frame != -1:
        return payloads[0]
    return None


@accepts(model=is_a(RobotModel), units=UNIT_SYSTEM, calibration=optional(MAPPING))
def model_to_yaml(model: RobotModel, *, units: str = "mm-deg", calibration: dict | None = None) -> str:
    """The model file text (see model_to_dict).

    Parameters
    ----------
    {model, units, calibration}

    Returns
    -------
    str
        The YAML text.
    """
    return yaml.safe_dump(model_to_dict(model, units=units, calibration=calibration), sort_keys=False,
                          default_flow_style=None, width=110, allow_unicode=True)


@accepts(model=is_a(RobotModel), path=PATH, units=UNIT_SYSTEM, force=FLAG, calibration=optional(MAPPING))
def write_model(model: RobotModel, path, *, units: str = "mm-deg", force: bool = False,
                calibration: dict | None = None) -> None:
    """Write ``model`` as a model file in ``units`` ("mm-deg", "m-rad"...), atomically.

    An existing file is an InputError unless ``force``. ``calibration``: what a calibration said of
    the model (see ``model_to_dict``; ``robocal.io.calibration_record(result)`` gives it).

    Parameters
    ----------
    {model, path}
    units : str
        Units of the written file.
    {force, calibration}

    Returns
    -------
    None
    """
    write_texts({path: model_to_yaml(model, units=units, calibration=calibration)}, force=force)
