"""A calibration campaign as ROS records it, simulated, and written as a bag with the rosbags package's
own writers (ROS 1 .bag, ROS 2 SQLite and MCAP): the robot moves from pose to pose and stands still
at each while a tracker samples its marker; joints at 250 Hz with encoder noise, the tracker at
100 Hz with noise, dropouts and its own clock.

Used by tests/test_bags.py and benchmarks/bench_bags.py."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

import robocal as rc

EPOCH = 1_700_000_000.0      # the robot's clock at the campaign's start, s (as ROS stamps run)


@dataclass(frozen=True)
class Recording:
    """What the bag holds and what it should give.

    ``q_poses`` (n_poses, n_joints) where the robot stood, ``still`` (n_poses, 2) when (robot time,
    s from the start), ``truth`` (n_poses, 3) the true marker position there; the streams: joint
    times and readings, and the tracker's times (its own clock), positions and quaternions.
    """

    q_poses: np.ndarray
    still: np.ndarray
    truth: np.ndarray
    joint_t: np.ndarray
    joint_q: np.ndarray
    tracker_t: np.ndarray
    tracker_xyz: np.ndarray
    tracker_quat: np.ndarray
    clock_offset: float
    joint_names: tuple[str, ...]
    extra_joints: tuple[str, ...] = field(default=("gripper_finger",))


def recording(model: rc.RobotModel, true: rc.RobotModel, q_poses, *, seed: int = 0, still=(1.0, 3.0),
              move=(0.8, 1.6), joint_rate: float = 250.0, tracker_rate: float = 100.0, noise: float = 2e-5,
              joint_noise: float = 1e-6, rot_noise: float = 1e-4, dropout: float = 0.05, clock_offset: float = 0.37,
              lost=()) -> Recording:
    """The recording of ``true`` visiting ``q_poses`` in order: still for a time drawn in ``still`` (s)
    at each, moving between them in a time drawn in ``move`` (a cosine profile, every joint at once).

    The tracker's points have ``noise`` (m) and its orientations ``rot_noise`` (rad) per axis; it
    drops ``dropout`` of its samples at random and every sample of the still moments listed in
    ``lost``; its clock runs ``clock_offset`` s ahead of the robot's.
    """
    rng = np.random.default_rng(seed)
    q_poses = np.asarray(q_poses, dtype=float)
    n = len(q_poses)
    stand, go = rng.uniform(*still, n), rng.uniform(*move, n)
    starts = np.concatenate([[0.0], np.cumsum(stand + go)[:-1]])    # still from the first sample
    ends = starts + stand
    t_end = ends[-1] + 0.5
    joint_t = np.arange(0.0, t_end, 1.0 / joint_rate)
    tracker_t = np.arange(0.0, t_end, 1.0 / tracker_rate)
    joint_q = _motion(q_poses, starts, ends, joint_t) + rng.normal(0.0, joint_noise, (joint_t.size, q_poses.shape[1]))
    ev = rc.evaluate(true, _motion(q_poses, starts, ends, tracker_t), orientations=True)
    xyz = ev.positions[:, 0] + rng.normal(0.0, noise, (tracker_t.size, 3))
    turn = Rotation.from_rotvec(rng.normal(0.0, rot_noise, (tracker_t.size, 3)))
    quat = (Rotation.from_matrix(ev.rotations[:, 0]) * turn).as_quat()
    keep = rng.random(tracker_t.size) >= dropout
    for k in lost:
        keep &= ~((tracker_t >= starts[k] - 0.2) & (tracker_t <= ends[k] + 0.2))
    truth = rc.evaluate(true, q_poses).positions[:, 0]
    return Recording(q_poses, np.column_stack([starts, ends]), truth, joint_t, joint_q, tracker_t[keep] + clock_offset,
                     xyz[keep], quat[keep], clock_offset, model.joint_names)


def _motion(q_poses: np.ndarray, starts: np.ndarray, ends: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The joints at times ``t``: at pose k from ``starts[k]`` to ``ends[k]``, then on the way to the next."""
    k = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(q_poses) - 1)
    nxt = np.minimum(k + 1, len(q_poses) - 1)
    span = np.where(nxt > k, starts[nxt] - ends[k], 1.0)
    s = np.clip((t - ends[k]) / span, 0.0, 1.0)
    s = np.where(t < starts[0], 0.0, s)
    w = (1.0 - np.cos(np.pi * s)) / 2.0
    return q_poses[k] + (q_poses[nxt] - q_poses[k]) * w[:, None]


TOPICS = {"point": ("/tracker/point", "geometry_msgs/msg/PointStamped"),
          "pose": ("/mocap/tool/pose", "geometry_msgs/msg/PoseStamped"),
          "transform": ("/tracker/transform", "geometry_msgs/msg/TransformStamped"),
          "tf": ("/tf", "tf2_msgs/msg/TFMessage")}


def write_bag(path: Path, rec: Recording, *, storage: str = "ros1", marker: str = "point",
              description: str | None = None, joint_topic: str = "/joint_states", extra_topics=(),
              compressed: bool = False) -> str:
    """Write ``rec`` as a bag (``storage`` ros1, sqlite or mcap) with the marker as a ``marker``
    topic (point, pose, transform or tf: child frame ``tool_ball`` of ``tracker``); ``description``:
    a URDF text as ``/robot_description``; ``extra_topics``: (topic, msgtype) connections with no
    message; ``compressed``: a ROS 1 bag's chunks in bz2. Returns the marker's topic as
    ``import-bag`` names it."""
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    ros1 = storage == "ros1"
    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    if ros1:
        ts.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"))
    serialize = ts.serialize_ros1 if ros1 else ts.serialize_cdr
    writer = Writer1(path) if ros1 else Writer2(path, version=9, storage_plugin={
        "sqlite": StoragePlugin.SQLITE3, "mcap": StoragePlugin.MCAP}[storage])
    if compressed:
        writer.set_compression(Writer1.CompressionFormat.BZ2)
    messages = _Messages(ts, ros1)
    topic, msgtype = TOPICS[marker]
    with writer:
        joints = writer.add_connection(joint_topic, "sensor_msgs/msg/JointState", typestore=ts)
        tracker = writer.add_connection(topic, msgtype, typestore=ts)
        for extra, extra_type in extra_topics:
            writer.add_connection(extra, extra_type, typestore=ts)
        if description is not None:
            conn = writer.add_connection("/robot_description", "std_msgs/msg/String", typestore=ts)
            writer.write(conn, int(EPOCH * 1e9), serialize(ts.types["std_msgs/msg/String"](data=description),
                                                           "std_msgs/msg/String"))
        # the bag's order: receive times, a millisecond after each stamp
        events = [(t, 0, i) for i, t in enumerate(rec.joint_t)] + [(t - rec.clock_offset, 1, i)
                                                                    for i, t in enumerate(rec.tracker_t)]
        events.sort()
        names = ("gripper_finger",) + tuple(reversed(rec.joint_names))   # not the model's order
        for t, which, i in events:
            received = int((EPOCH + t + 0.001) * 1e9)
            if which == 0:
                msg = messages.joint_state(EPOCH + rec.joint_t[i], names,
                                           np.concatenate([[0.01], rec.joint_q[i][::-1]]))
                writer.write(joints, received, serialize(msg, "sensor_msgs/msg/JointState"))
            else:
                msg = messages.marker(marker, EPOCH + rec.tracker_t[i], rec.tracker_xyz[i], rec.tracker_quat[i])
                writer.write(tracker, received, serialize(msg, msgtype))
    return f"{topic}:tool_ball" if marker == "tf" else topic


class _Messages:
    """The message records of a type store, stamped."""

    def __init__(self, ts, ros1: bool):
        self.ts, self.ros1 = ts, ros1
        self.T = ts.types

    def header(self, t: float, frame: str):
        sec = int(np.floor(t))
        stamp = self.T["builtin_interfaces/msg/Time"](sec=sec, nanosec=int(round((t - sec) * 1e9)) % 1_000_000_000)
        extra = {"seq": 0} if self.ros1 else {}
        return self.T["std_msgs/msg/Header"](**extra, stamp=stamp, frame_id=frame)

    def joint_state(self, t: float, names, q):
        return self.T["sensor_msgs/msg/JointState"](header=self.header(t, ""), name=list(names),
                                                    position=np.asarray(q, dtype=float), velocity=np.zeros(0),
                                                    effort=np.zeros(0))

    def marker(self, kind: str, t: float, p, quat):
        T = self.T
        point = T["geometry_msgs/msg/Point"](x=p[0], y=p[1], z=p[2])
        q = T["geometry_msgs/msg/Quaternion"](x=quat[0], y=quat[1], z=quat[2], w=quat[3])
        if kind == "point":
            return T["geometry_msgs/msg/PointStamped"](header=self.header(t, "tracker"), point=point)
        if kind == "pose":
            return T["geometry_msgs/msg/PoseStamped"](header=self.header(t, "tracker"),
                                                      pose=T["geometry_msgs/msg/Pose"](position=point, orientation=q))
        transform = T["geometry_msgs/msg/TransformStamped"](
            header=self.header(t, "tracker"), child_frame_id="tool_ball",
            transform=T["geometry_msgs/msg/Transform"](translation=T["geometry_msgs/msg/Vector3"](x=p[0], y=p[1],
                                                                                                     z=p[2]),
                                                       rotation=q))
        if kind == "transform":
            return transform
        other = T["geometry_msgs/msg/TransformStamped"](header=self.header(t, "world"), child_frame_id="tracker_base",
                                                        transform=transform.transform)
        return T["tf2_msgs/msg/TFMessage"](transforms=[other, transform])


def example(path: Path) -> None:
    """examples/th8/mocap.bag: the TH8 (its true_model.yaml) standing still at 8 poses, its joint
    states at 50 Hz, a motion-capture bridge's PoseStamped of the tool at 100 Hz on a clock 0.37 s
    ahead, 5 % of its samples dropped."""
    examples = Path(__file__).resolve().parent.parent / "examples" / "th8"
    model, true = rc.read_model(examples / "model.yaml"), rc.read_model(examples / "true_model.yaml")
    q = rc.random_configurations(model, 8, np.random.default_rng(44))
    rec = recording(model, true, q, seed=44, still=(1.0, 1.5), move=(0.6, 1.0), joint_rate=50.0)
    write_bag(path, rec, marker="pose", compressed=True)


if __name__ == "__main__":
    import sys

    example(Path(sys.argv[1]))
