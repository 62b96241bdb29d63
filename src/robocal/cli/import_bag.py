"""``robocal import-bag``: a campaign file from a ROS bag (docs/formats.md, "ROS bags")."""

from __future__ import annotations

import argparse

from .._base.errors import InputError, excerpt
from . import common

EXAMPLE = """example:
  robocal import-bag examples/th8/mocap.bag --model examples/th8/model.yaml --joints /joint_states \\
      --marker tool=/mocap/tool/pose --clock-offset 0.37 --out runs/mocap/campaign.csv

A pose is each moment the joints stand still (every joint within --still-deg-s or --still-mm-s,
for --min-still-s or more); each marker is the mean of its samples from --settle-s after the
moment starts to its end, by header time, the deviation of that mean written as its sigma. A marker
missing there (fewer than --min-samples samples) or moving (its two halves' means further apart
than --drift-mm and their noise) is left out of that pose, and listed with its times. Without
--model the joints are matched to the bag's /robot_description (URDF); --model-out writes it."""


def register(sub) -> None:
    p = common.command(sub, "import-bag", summary="write a campaign file from a ROS bag (needs robocal[ros])",
                       description="Read the joint states and an instrument's points, poses or transforms from a "
                                   "ROS 1 .bag or a ROS 2 bag (SQLite or MCAP), find the moments the robot stands "
                                   "still, and write each as a pose of a measurement file.",
                       example=EXAMPLE, inputs=[("bag", "BAG", "a ROS 1 .bag file, or a ROS 2 bag folder (or its "
                                                               ".db3 or .mcap file)")])
    p.add_argument("--model", metavar="MODEL.yaml", help="the nominal model whose joints the bag's are matched to "
                                                        "(default: the bag's /robot_description)")
    p.add_argument("--joints", metavar="TOPIC", help="the sensor_msgs/JointState topic (default: the bag's only "
                                                     "one)")
    p.add_argument("--marker", required=True, action="append", type=_marker, metavar="NAME=TOPIC",
                   help="a marker of the model and its topic: geometry_msgs PointStamped, PoseStamped or "
                        "TransformStamped, or /tf:CHILD_FRAME (repeatable)")
    p.add_argument("--joint-map", type=common.column_pairs, action="append", default=[], metavar="MODEL=BAG,...",
                   help="the bag's name of a model joint whose name differs, e.g. 'j1=shoulder_pan_joint'")
    p.add_argument("--clock-offset", type=common.number_in(lambda v: abs(v) <= 1e6, "seconds"), default=0.0,
                   metavar="S", help="the instrument's clock minus the robot's: a stamp t is robot time t - S "
                                     "(default 0)")
    p.add_argument("--still-deg-s", type=common.positive, default=0.1, metavar="X",
                   help="a revolute joint stands still below this speed, deg/s (default 0.1)")
    p.add_argument("--still-mm-s", type=common.positive, default=0.1, metavar="X",
                   help="a prismatic joint stands still below this speed, mm/s (default 0.1)")
    p.add_argument("--min-still-s", type=common.positive, default=0.5, metavar="S",
                   help="the shortest still moment that is a pose, s (default 0.5)")
    p.add_argument("--settle-s", type=common.number_in(lambda v: 0 <= v < 1e3, "seconds from 0"), default=0.2,
                   metavar="S", help="the instrument's samples count from this long after the joints stop, s "
                                     "(default 0.2)")
    p.add_argument("--min-samples", type=common.integer(2, 10 ** 9), default=10, metavar="N",
                   help="fewer of a marker's samples in a still moment: missing there (default 10)")
    p.add_argument("--drift-mm", type=common.positive, default=0.02, metavar="X",
                   help="a marker whose halves' means lie further apart (and beyond their noise) is moving, mm "
                        "(default 0.02)")
    p.add_argument("--position-only", action="store_true", help="leave out the orientations of pose and "
                                                                "transform topics")
    p.add_argument("--out", required=True, metavar="CAMPAIGN.csv", help="the measurement file to write")
    p.add_argument("--model-out", metavar="MODEL.yaml", help="also write the model of /robot_description (without "
                                                             "--model)")
    p.add_argument("--units", type=common.units, default="mm-deg", help="units of the written files (default mm-deg)")
    p.add_argument("--force", action="store_true", help="overwrite existing output files")
    p.set_defaults(func=run)


def _marker(text: str) -> tuple[str, str]:
    name, eq, topic = (s.strip() for s in text.partition("="))
    if not eq or not name or not topic.startswith("/"):
        raise argparse.ArgumentTypeError(f"expected NAME=TOPIC with the topic starting with '/', got {excerpt(text)}")
    return name, topic


def run(args) -> int:
    from .._files.bags import read_bag
    from .._files.measurements import measurements_to_csv
    from .._files.model import model_to_yaml, read_model
    from .._files.stills import StillRules

    try:
        import rosbags  # noqa: F401
    except ImportError:
        raise common.MissingExtra("ros extra not installed (pip install 'robocal[ros]')") from None
    if args.model_out and args.model:
        raise InputError("--model-out writes the model of the bag's /robot_description: not with --model",
                                where="--model-out")
    common.refuse_existing([args.out] + ([args.model_out] if args.model_out else []), args.force)
    markers = dict(args.marker)
    if len(markers) != len(args.marker):
        raise InputError("a marker is named twice", where="--marker")
    rules = StillRules(speed_revolute=args.still_deg_s / common.DEG, speed_prismatic=args.still_mm_s / common.MM,
                       min_duration=args.min_still_s, settle=args.settle_s, min_samples=args.min_samples,
                       drift=args.drift_mm / common.MM, clock_offset=args.clock_offset)
    found = read_bag(args.bag, read_model(args.model) if args.model else None, joints=args.joints, markers=markers,
                     joint_names={k: v for m in args.joint_map for k, v in m.items()} or None, rules=rules,
                     orientation=not args.position_only)
    files = {args.out: measurements_to_csv(found.data, model=found.model, units=args.units)}
    if args.model_out:
        files[args.model_out] = model_to_yaml(found.model, units=args.units)
    common.write_outputs(files, force=args.force)
    for line in found.notes:
        print(line)
    for left in found.left:
        print(f"left out: {left}")
    print(f"{found.data.n_poses} poses of {found.model.name}, markers {', '.join(found.data.marker_names)}: wrote "
          f"{', '.join(map(str, files))}")
    return 0
