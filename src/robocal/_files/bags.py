"""ROS bags read into a campaign: ROS 1 ``.bag`` files and ROS 2 bags (a folder of SQLite or MCAP
storage, or one ``.db3``/``.mcap`` file), through the ``rosbags`` package (the optional ``ros``
extra). The joints come from a ``sensor_msgs/JointState`` topic, each marker from a
``geometry_msgs`` ``PointStamped``, ``PoseStamped`` or ``TransformStamped`` topic or a child frame of
a ``tf2_msgs/TFMessage`` topic (``/tf:CHILD``), all by header time; the still moments and their
pairing are ``stills``' (docs/formats.md, "ROS bags").
"""

from __future__ import annotations

import struct
from collections.abc import Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._base.arguments import FLAG, MAPPING, PATH, TEXT, accepts, is_a, optional
from .._base.errors import InputError, RobocalError, excerpt
from .._model.measurements import Measurements
from .._model.robot import RobotModel
from .stills import Left, StillRules, Stream, campaign
from .urdf import read_urdf

JOINT_STATE = "sensor_msgs/msg/JointState"
# what a marker's topic may carry, and the part of the message that holds the point
MARKER_TYPES = {"geometry_msgs/msg/PointStamped": "point", "geometry_msgs/msg/PoseStamped": "pose",
                "geometry_msgs/msg/TransformStamped": "transform", "tf2_msgs/msg/TFMessage": "tf"}
DESCRIPTION = "/robot_description"
# joint messages decoded at once; bounds the raw bytes held while reading (about 200 bytes each)
CHUNK = 100_000
NS = 1_000_000_000


@dataclass(frozen=True)
class BagCampaign:
    """A campaign read from a ROS bag.

    Attributes
    ----------
    data : Measurements
        One pose per still moment kept (labels ``t=12.34s``: its start, seconds from the first joint
        message), SI, ``sigma`` the deviation of each marker's mean (its samples' scatter over the
        square root of their number).
    model : RobotModel
        The model the joints were matched to: the one given, or the bag's ``/robot_description``.
    left : tuple of Left
        Each marker masked in a still moment (missing or moving) and each pose dropped, with times.
    notes : tuple of str
        What was read: topics, message counts, joints matched, times used.
    description : str or None
        The URDF text of the bag's ``/robot_description`` when the model came from it.
    """

    data: Measurements
    model: RobotModel
    left: tuple[Left, ...]
    notes: tuple[str, ...]
    description: str | None = None


def _rosbags():
    """The rosbags modules robocal uses, or a RobocalError saying which extra brings them."""
    try:
        from rosbags import highlevel, rosbag1, rosbag2, serde, typesys
    except ImportError:
        raise RobocalError("reading ROS bags needs the rosbags package: pip install 'robocal[ros]'") from None
    return highlevel, (highlevel.AnyReaderError, rosbag1.ReaderError, rosbag2.ReaderError, serde.SerdeError,
                       typesys.TypesysError)


@accepts(path=PATH, model=optional(is_a(RobotModel)), joints=optional(TEXT),
         markers=lambda v, name, args: _marker_specs(v), joint_names=optional(MAPPING),
         rules=optional(is_a(StillRules)), orientation=FLAG)
def read_bag(path, model: RobotModel | None = None, *, joints: str | None = None, markers: Mapping[str, str],
             joint_names: Mapping[str, str] | None = None, rules: StillRules | None = None,
             orientation: bool = True) -> BagCampaign:
    """The campaign a ROS bag recorded: one pose per still moment of the joints, each marker the
    mean of its samples there.

    Parameters
    ----------
    path : str or path
        A ROS 1 ``.bag`` file, or a ROS 2 bag (its folder, or one ``.db3``/``.mcap`` file).
    model : RobotModel, optional
        The nominal model whose joints the bag's are matched to, by name; None: the bag's
        ``/robot_description`` (URDF), each marker at the tip link's origin.
    joints : str, optional
        The ``sensor_msgs/JointState`` topic (default: the bag's only one; an error listing them
        when it has several).
    markers : mapping of str to str
        Each marker's topic (``PointStamped``, ``PoseStamped``, ``TransformStamped``, or
        ``/tf:CHILD`` for a child frame of a ``TFMessage`` topic), by the model's marker name.
    joint_names : mapping of str to str, optional
        The bag's joint name for a model joint whose name differs (model name -> bag name).
    rules : StillRules, optional
        How still moments are found and paired with the instrument's samples (default
        ``StillRules()``).
    orientation : bool
        Keep the orientations of pose and transform topics (False: positions only).

    Returns
    -------
    BagCampaign
        The measurements, the model, what was left out and what was read.
    """
    highlevel, errors = _rosbags()
    source, rules, from_bag = str(path), rules or StillRules(), model is None
    specs = _marker_specs(markers)
    if not Path(path).exists():
        raise InputError("no such file or folder", source=source)
    if Path(path).is_dir() and not (Path(path) / "metadata.yaml").is_file():
        raise InputError("a folder without metadata.yaml is not a ROS 2 bag (give the bag's folder, or its .db3 or "
                         ".mcap file)", source=source)
    with _as_input_errors(source, errors), highlevel.AnyReader([Path(path)]) as reader:
        chosen = joints or _joint_topic(reader, source)
        topics = _topics(reader, source, chosen, specs, from_bag)
        decoded = _read(reader, topics, source)
    description = decoded.pop(DESCRIPTION, None)
    model = _described(description, source, tuple(specs)) if model is None else model
    names = {jn: (joint_names or {}).get(jn, jn) for jn in model.joint_names}
    t0, joint_stream, notes = _joint_stream(decoded.pop(chosen), names, source)
    if joints is None:
        notes.insert(0, f"joints from {chosen}, the bag's only {JOINT_STATE} topic")
    streams = tuple(_marker_stream(name, topics[spec], t0, orientation, notes)
                    for name, spec in specs.items())
    data, left, scattered = campaign(joint_stream, streams, model, rules, source=source)
    notes += scattered
    notes.append(f"{len(data.labels)} still pose(s) of {rules.min_duration:g} s or more; {len(left)} left out")
    return BagCampaign(data, model, left, tuple(notes), description if from_bag else None)


def _marker_specs(markers) -> dict[str, str]:
    """``{marker: topic}``, each marker and topic named."""
    if not isinstance(markers, Mapping) or not markers:
        raise InputError("give each marker's topic as {marker: topic}", where="markers")
    for name, topic in markers.items():
        if not isinstance(name, str) or not name or not isinstance(topic, str) or not topic.startswith("/"):
            raise InputError(f"expected a marker name and a topic starting with '/', got {excerpt(f'{name}={topic}')}",
                             where="markers")
    return dict(markers)


@contextmanager
def _as_input_errors(source: str, errors: tuple):
    """What the bag library raises on a file it cannot read, as one InputError naming the bag."""
    try:
        yield
    except (*errors, struct.error, EOFError, UnicodeDecodeError) as e:
        raise InputError(f"not a readable ROS bag ({' '.join(str(e).split()) or type(e).__name__})",
                         source=source) from None


def _joint_topic(reader, source: str) -> str:
    """The bag's only ``sensor_msgs/JointState`` topic; an error naming them when there are several or none."""
    found = sorted(name for name, info in reader.topics.items() if info.msgtype == JOINT_STATE)
    if len(found) != 1:
        said = f"{len(found)}: {', '.join(found)}" if found else "none"
        raise InputError(f"name the joints' topic (joints, --joints TOPIC): the bag's {JOINT_STATE} topics are "
                         f"{said}", source=source)
    return found[0]


def _topics(reader, source: str, joints: str, specs: dict[str, str], description: bool) -> dict:
    """The collector of each topic the campaign needs (keyed by the topic, or by ``/tf:CHILD``),
    each checked to exist in the bag with a message type it can be read from."""
    available = {name: info.msgtype for name, info in reader.topics.items()}

    def msgtype(topic: str, what: str) -> str:
        if topic not in available:
            shown = ", ".join(f"{n} ({t})" for n, t in sorted(available.items())[:12])
            more = f" and {len(available) - 12} more" if len(available) > 12 else ""
            raise InputError(f"no topic {topic} in the bag ({what}); its topics: {shown or 'none'}{more}",
                             source=source)
        return available[topic] or "several types"

    found = msgtype(joints, "the joints")
    if found != JOINT_STATE:
        raise InputError(f"topic {joints} carries {found}, not the joints' {JOINT_STATE}", source=source)
    out: dict = {joints: _Joints(joints, reader.is2)}
    for name, spec in specs.items():
        topic, _, child = spec.partition(":")
        kind = MARKER_TYPES.get(found := msgtype(topic, f"marker {name}"))
        if kind is None or (kind == "tf") != bool(child):
            wanted = f"{topic}:CHILD_FRAME for a {found}" if kind == "tf" else \
                f"a topic of {', '.join(t for t, k in MARKER_TYPES.items() if k != 'tf')} (or /tf:CHILD_FRAME)"
            raise InputError(f"marker {name}: topic {spec} carries {found}; give {wanted}", source=source)
        out[spec] = _Samples(topic, kind, child.lstrip("/") or None, reader.is2)
    if description:
        if msgtype(DESCRIPTION, "no model was given: the robot's URDF") != "std_msgs/msg/String":
            raise InputError(f"topic {DESCRIPTION} carries {available[DESCRIPTION]}, not the URDF text of a "
                             "std_msgs/String", source=source)
        out[DESCRIPTION] = _Description(DESCRIPTION)
    return out


def _read(reader, topics: dict, source: str) -> dict:
    """One pass over the bag, each message to the collectors of its topic; ``{key: collected}``."""
    by_topic: dict = {}
    for collector in topics.values():
        by_topic.setdefault(collector.topic, []).append(collector)
    wanted = [c for c in reader.connections if c.topic in by_topic]
    for connection, ns, raw in reader.messages(connections=wanted):
        for collector in by_topic[connection.topic]:
            collector.take(reader, connection.msgtype, ns, raw)
    return {key: collector.done(reader, source) for key, collector in topics.items()}


class _Description:
    """The first message of ``/robot_description``: the URDF text."""

    def __init__(self, topic: str):
        self.topic, self.text = topic, None

    def take(self, reader, msgtype: str, ns: int, raw: bytes) -> None:
        if self.text is None:
            self.text = reader.deserialize(raw, msgtype).data

    def done(self, reader, source: str):
        return self.text


class _Samples:
    """A marker's samples: header and bag times (ns), position, and quaternion (x, y, z, w) where the
    message has one. A point, pose or transform topic's messages are kept serialized and decoded
    together (``stamped_values``); a ``/tf`` topic's one by one, for the child frame's transforms."""

    def __init__(self, topic: str, kind: str, child: str | None, cdr: bool):
        self.topic, self.kind, self.child, self.cdr = topic, kind, child, cdr
        self.raw: list[bytes] = []
        self.header_ns: list[int] = []
        self.bag_ns: list[int] = []
        self.values: list[tuple] = []
        self.parents: set[str] = set()
        self.msgtype = ""
        # what done() leaves: header and bag times (n,) ns, values (n, 3 or 7)
        self.stamps: np.ndarray = np.zeros(0, dtype=np.int64)
        self.received: np.ndarray = self.stamps
        self.samples: np.ndarray = np.zeros((0, 3))

    def take(self, reader, msgtype: str, ns: int, raw: bytes) -> None:
        if self.kind != "tf":
            self.raw.append(raw)
            self.bag_ns.append(ns)
            self.msgtype = msgtype
            return
        for tr in reader.deserialize(raw, msgtype).transforms:
            if tr.child_frame_id.lstrip("/") == self.child:
                self.parents.add(tr.header.frame_id)
                self.header_ns.append(tr.header.stamp.sec * NS + tr.header.stamp.nanosec)
                self.bag_ns.append(ns)
                self.values.append(_point(tr.transform.translation) + _point(tr.transform.rotation))

    def done(self, reader, source: str) -> _Samples:
        what = f"{self.topic}:{self.child}" if self.child else self.topic
        self.received = np.array(self.bag_ns, dtype=np.int64)
        if self.kind == "tf":
            self.stamps, self.samples = np.array(self.header_ns, dtype=np.int64), np.array(self.values, dtype=float)
        elif self.raw:
            self.stamps, self.samples = stamped_values(self.raw, self.cdr,
                                                       lambda raw: reader.deserialize(raw, self.msgtype), self.kind)
        self.raw, self.bag_ns, self.header_ns, self.values = [], [], [], []
        if not self.stamps.size:
            raise InputError(f"{what}: no sample in the bag" + (f" (no transform of child frame {self.child})"
                                                                  if self.child else ""), source=source)
        if len(self.parents) > 1:
            raise InputError(f"{what}: frame {self.child} is the child of several frames "
                             f"({', '.join(sorted(self.parents))}): one instrument frame is needed", source=source)
        return self


def _point(v) -> tuple:
    """(x, y, z) of a point or vector message, (x, y, z, w) of a quaternion."""
    return (v.x, v.y, v.z, v.w) if hasattr(v, "w") else (v.x, v.y, v.z)


def _values(msg, kind: str) -> tuple:
    """The position, and the quaternion (x, y, z, w) where it has one, of a deserialized marker message."""
    if kind == "point":
        return _point(msg.point)
    if kind == "pose":
        return _point(msg.pose.position) + _point(msg.pose.orientation)
    return _point(msg.transform.translation) + _point(msg.transform.rotation)


def stamped_values(raws: list[bytes], cdr: bool, deserialize, kind: str) -> tuple[np.ndarray, np.ndarray]:
    """(header times (n,) ns, values (n, 3 or 7)) of serialized ``PointStamped`` (``kind`` point),
    ``PoseStamped`` (pose) or ``TransformStamped`` (transform) messages.

    Each ends with its doubles (the point; or position and quaternion) and starts with its header's
    stamp at bytes 4 to 12 in both encodings: the messages of one length are decoded together from
    there, once ``deserialize``'s reading of the first of them agrees; any other one by one.
    """
    width = 3 if kind == "point" else 7
    lengths = np.fromiter(map(len, raws), dtype=np.int64, count=len(raws))
    stamps = np.zeros(len(raws), dtype=np.int64)
    values = np.zeros((len(raws), width))
    for length in np.unique(lengths):
        rows = np.flatnonzero(lengths == length)
        got = _stamped_block([raws[i] for i in rows], cdr, deserialize, kind, width)
        if got is None:
            for i in rows:
                msg = deserialize(raws[i])
                stamps[i] = msg.header.stamp.sec * NS + msg.header.stamp.nanosec
                values[i] = _values(msg, kind)
            continue
        got_ns, got = got
        stamps[rows], values[rows] = got_ns, got
    return stamps, values


def _stamped_block(raws: list[bytes], cdr: bool, deserialize, kind: str, width: int):
    """(header times, values) of messages of one length read from their bytes, or None where the
    first of them does not read so (a big-endian CDR message, a layout not understood)."""
    length = len(raws[0])
    if (cdr and raws[0][1:2] != b"\x01") or length < 12 + 8 * width:
        return None
    block = np.frombuffer(b"".join(raws), dtype=np.uint8).reshape(len(raws), length)
    if cdr and np.any(block[:, 1] != 1):
        return None
    got = block[:, length - 8 * width:].copy().view("<f8")
    seconds = block[:, 4:8].copy().view("<i4" if cdr else "<u4")[:, 0].astype(np.int64)
    got_ns = seconds * NS + block[:, 8:12].copy().view("<u4")[:, 0]
    msg = deserialize(raws[0])
    if got_ns[0] != msg.header.stamp.sec * NS + msg.header.stamp.nanosec or \
            not np.array_equal(got[0], _values(msg, kind), equal_nan=True):
        return None
    return got_ns, got


class _Joints:
    """The joint messages' header and bag times (ns) and positions, decoded a chunk at a time."""

    def __init__(self, topic: str, cdr: bool):
        self.topic, self.cdr = topic, cdr
        self.raw: list[bytes] = []
        self.bag_ns: list[int] = []
        self.parts: list = []
        self.msgtype = JOINT_STATE

    def take(self, reader, msgtype: str, ns: int, raw: bytes) -> None:
        self.raw.append(raw)
        self.bag_ns.append(ns)
        self.msgtype = msgtype
        if len(self.raw) >= CHUNK:
            self._decode(reader)

    def _decode(self, reader) -> None:
        stamps, groups = joint_states(self.raw, self.cdr, lambda raw: reader.deserialize(raw, self.msgtype),
                                      self.topic)
        self.parts.append((stamps, np.array(self.bag_ns, dtype=np.int64), groups))
        self.raw, self.bag_ns = [], []

    def done(self, reader, source: str) -> _Joints:
        if self.raw:
            self._decode(reader)
        if not self.parts:
            raise InputError(f"{self.topic}: no joint message in the bag", source=source)
        return self


def joint_states(raws: list[bytes], cdr: bool, deserialize, topic: str = "joints"):
    """(header times (n,) ns, groups ``(rows, joint names, positions (k, n_names))``) of serialized
    ``sensor_msgs/JointState`` messages (``cdr``: ROS 2's encoding, else ROS 1's).

    Messages of one layout (length, frame, joint names) are decoded together from their bytes, at
    the offsets found in the first of them and checked against ``deserialize``'s reading of it (the
    bag library's); any other message is read by ``deserialize`` alone.
    """
    lengths = np.fromiter(map(len, raws), dtype=np.int64, count=len(raws))
    stamps = np.zeros(len(raws), dtype=np.int64)
    groups, others = [], []
    for length in np.unique(lengths):
        rows = np.flatnonzero(lengths == length)
        layout = _layout(raws[rows[0]], cdr, deserialize)
        if layout is None:
            others += rows.tolist()
            continue
        fixed, start, names = layout
        block = np.frombuffer(b"".join([raws[i] for i in rows]), dtype=np.uint8).reshape(rows.size, length)
        same = np.all(block[:, fixed] == block[0, fixed], axis=1)
        b = block[same]
        seconds = b[:, 4:8].copy().view("<i4" if cdr else "<u4")[:, 0].astype(np.int64)
        stamps[rows[same]] = seconds * NS + b[:, 8:12].copy().view("<u4")[:, 0]
        groups.append((rows[same], names, b[:, start:start + 8 * len(names)].copy().view("<f8")))
        others += rows[~same].tolist()
    by_names: dict = {}
    for i in others:
        msg = deserialize(raws[i])
        stamps[i] = msg.header.stamp.sec * NS + msg.header.stamp.nanosec
        names, position = tuple(msg.name), np.asarray(msg.position, dtype=float)
        if position.size != len(names):
            raise InputError(f"{topic}: a message names {len(names)} joints and gives {position.size} positions "
                             f"(header time {stamps[i] / NS:.3f} s)")
        by_names.setdefault(names, []).append((i, position))
    groups += [(np.array([i for i, _ in v]), names, np.array([p for _, p in v])) for names, v in by_names.items()]
    return stamps, groups


def _layout(raw: bytes, cdr: bool, deserialize):
    """(the bytes that fix the layout, offset of the first position, joint names) of one serialized
    JointState whose positions follow its names, one per joint, as ``deserialize`` reads it; None
    for any other (a big-endian CDR message, names without positions, a layout not understood)."""
    if cdr and raw[1:2] != b"\x01":
        return None
    start, count = _position_offset(raw, cdr)
    msg = deserialize(raw)
    names = tuple(msg.name)
    if start < 0 or count != len(names) or start + 8 * count > len(raw) or not names:
        return None
    position = np.frombuffer(raw, dtype="<f8", count=count, offset=start)
    seconds = int.from_bytes(raw[4:8], "little", signed=cdr)
    if not np.array_equal(position, np.asarray(msg.position, dtype=float), equal_nan=True) or \
            seconds != msg.header.stamp.sec or int.from_bytes(raw[8:12], "little") != msg.header.stamp.nanosec:
        return None
    fixed = np.r_[0:4, 12:start] if cdr else np.r_[12:start]   # ROS 1's first 4 bytes: a sequence number
    return fixed, start, names


def _position_offset(raw: bytes, cdr: bool) -> tuple[int, int]:
    """(offset of the first position, their count) of a serialized JointState: the header (a sequence
    number in ROS 1; the stamp; the frame's name, its length at byte 12 in both), the joint names,
    then the positions; CDR aligns each value to its size counted from byte 4. (-1, 0) if the bytes
    end before."""
    def u32(at: int) -> int:
        return int.from_bytes(raw[at:at + 4], "little") if at + 4 <= len(raw) else len(raw)

    def aligned(at: int, size: int) -> int:
        return at + (-(at - 4)) % size if cdr else at

    at = 16 + u32(12)
    at = aligned(at, 4)
    n_names, at = u32(at), at + 4
    for _ in range(min(n_names, len(raw))):
        at = aligned(at, 4)
        at += 4 + u32(at)
        if at > len(raw):
            return -1, 0
    at = aligned(at, 4)
    count = u32(at)
    return aligned(at + 4, 8), count


def _joint_stream(joints: _Joints, names: dict[str, str], source: str) -> tuple[int, Stream, list[str]]:
    """(the first joint time, ns; the joints in the model's order, seconds from it; notes)."""
    stamps = np.concatenate([p[0] for p in joints.parts])
    bag_ns = np.concatenate([p[1] for p in joints.parts])
    q = np.full((stamps.size, len(names)), np.nan)
    offsets = np.cumsum([0] + [p[0].size for p in joints.parts])
    seen: set[str] = set()
    for offset, (_, _, groups) in zip(offsets, joints.parts):
        for rows, bag_names, positions in groups:
            missing = [(m, b) for m, b in names.items() if b not in bag_names]
            if missing:
                m, b = missing[0]
                raise InputError(f"{joints.topic}: the model's joint {m} is not among its joints "
                                 f"({', '.join(bag_names[:12])}); map it to the bag's name (--joint-map {m}=NAME)",
                                 source=source)
            q[offset + rows] = positions[:, [bag_names.index(b) for b in names.values()]]
            seen.update(bag_names)
    matched = ", ".join(f"{b} as {m}" if b != m else m for m, b in names.items())
    ignored = ", ".join(sorted(seen - set(names.values())))
    notes = [f"{joints.topic}: {stamps.size} messages, joints {matched}"
             + (f"; not in the model, ignored: {ignored}" if ignored else "")]
    t_ns = _times(stamps, bag_ns, joints.topic, notes)
    order = np.argsort(t_ns, kind="stable")
    if not np.all(np.isfinite(q)):
        raise InputError(f"{joints.topic}: a joint position is not a finite number", source=source)
    t0 = int(t_ns[order[0]])
    return t0, Stream(joints.topic, (t_ns[order] - t0) / NS, q[order]), notes


def _times(header_ns: np.ndarray, bag_ns: np.ndarray, topic: str, notes: list[str]) -> np.ndarray:
    """The header times, or the bag's receive times (said in ``notes``) where no message is stamped."""
    if np.any(header_ns != 0):
        return header_ns
    notes.append(f"{topic}: no header stamps; the times the bag received the messages are used")
    return bag_ns


def _marker_stream(name: str, samples: _Samples, t0: int, orientation: bool, notes: list[str]) -> Stream:
    """Marker ``name``'s samples in time order, seconds from ``t0`` on the instrument's clock."""
    values = samples.samples
    t_ns = _times(samples.stamps, samples.received, samples.topic, notes)
    order = np.argsort(t_ns, kind="stable")
    rotations = values[order, 3:] if values.shape[1] == 7 and orientation else None
    what = f"{samples.topic}:{samples.child} (child of {next(iter(samples.parents))})" if samples.child \
        else samples.topic
    notes.append(f"marker {name}: {what}, {len(values)} samples" + (", with orientations" if rotations is not None
                                                                        else ""))
    return Stream(name, (t_ns[order] - t0) / NS, values[order, :3], rotations)


def _described(text: str | None, source: str, markers: tuple[str, ...]) -> RobotModel:
    """The model of the bag's URDF, each marker at the tip link's origin."""
    if not text:
        raise InputError(f"no model was given and {DESCRIPTION} is empty", source=source)
    try:
        return read_urdf(text, markers=[(m, (0.0, 0.0, 0.0)) for m in markers])
    except InputError as e:
        raise InputError(e.detail, source=f"{source}: {DESCRIPTION}", where=e.where) from None
