"""Campaigns recorded as ROS bags (robocal import-bag, robocal.io.read_bag): bags written with the
rosbags package's own writers from a simulated campaign (tests/bag_campaign.py), in the three
storages, read back into the poses the robot stood still at."""

from __future__ import annotations

import importlib.util
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from bag_campaign import recording, write_bag
from conftest import assert_one_line_error
from scipy.spatial.transform import Rotation

import robocal as rc
from robocal.io import StillRules, read_bag

ROOT = Path(__file__).resolve().parent.parent
TH8 = ROOT / "examples" / "th8"
NOISE = 2e-5
HAS_ROSBAGS = importlib.util.find_spec("rosbags") is not None
WITHOUT = "the ros extra is not installed (pip install 'robocal[ros]')"
needs_rosbags = pytest.mark.skipif(not HAS_ROSBAGS, reason=WITHOUT)
BAGS = {"ros1": "campaign.bag", "sqlite": "campaign-sqlite", "mcap": "campaign-mcap"}
MARKERS = {"ros1": "point", "sqlite": "pose", "mcap": "tf"}


@pytest.fixture(scope="module")
def th8():
    """The TH8's nominal model, a true robot near it and 30 poses to visit."""
    model = rc.read_model(TH8 / "model.yaml")
    true, _ = rc.simulate(model, 5, seed=11)
    return model, true, rc.random_configurations(model, 30, np.random.default_rng(5))


@pytest.fixture(scope="module")
def bags(th8, tmp_path_factory):
    """A recording of the 30 poses as a ROS 2 MCAP bag of /tf transforms, and of the first 12 as a
    ROS 1 bag of points and a ROS 2 SQLite bag of poses: {storage: (bag, marker topic, recording)}."""
    if not HAS_ROSBAGS:
        pytest.skip(WITHOUT)
    model, true, q = th8
    folder = tmp_path_factory.mktemp("bags")
    out = {}
    for storage, name in BAGS.items():
        rec = recording(model, true, q if storage == "mcap" else q[:12], seed=3, noise=NOISE)
        out[storage] = (folder / name, write_bag(folder / name, rec, storage=storage, marker=MARKERS[storage]), rec)
    return out


@needs_rosbags
@pytest.mark.parametrize("storage", list(BAGS))
def test_every_still_pose_is_found_none_invented_each_point_within_its_noise(storage, bags, th8):
    bag, topic, rec = bags[storage]
    model = th8[0]
    found = read_bag(bag, model, joints="/joint_states", markers={"tool": topic},
                     rules=StillRules(clock_offset=rec.clock_offset))
    data = found.data
    assert data.n_poses == len(rec.q_poses) and found.left == ()
    starts = np.array([float(label[2:-1]) for label in data.labels])
    assert np.all((starts >= rec.still[:, 0] - 0.01) & (starts <= rec.still[:, 0] + 0.15)), starts - rec.still[:, 0]
    assert np.abs(data.q - rec.q_poses).max() < 1e-6
    # each averaged point within the deviation written for it: the truth lies within 5 of them, and
    # they are the size the errors show
    z = (data.positions[:, 0] - rec.truth) / data.sigma[:, :1]
    assert np.abs(z).max() < 5.0 and 0.7 < np.sqrt(np.mean(z ** 2)) < 1.3, z
    # the deviation of a mean of 0.8 to 2.8 s of samples at 100 Hz (less the dropouts), not of one sample
    assert np.all((data.sigma > NOISE / np.sqrt(400)) & (data.sigma < NOISE / np.sqrt(50)))
    if MARKERS[storage] != "point":                          # poses and transforms carry orientations
        true_rot = rc.evaluate(th8[1], rec.q_poses, orientations=True).rotations[:, 0]
        turned = Rotation.from_matrix(np.swapaxes(data.rotations[:, 0], 1, 2) @ true_rot).magnitude()
        assert np.all(turned < 5 * data.sigma_rot[:, 0]), turned / data.sigma_rot[:, 0]
        assert np.all(data.sigma_rot < 1e-4 / np.sqrt(50))
    assert any("gripper_finger" in note and "ignored" in note for note in found.notes)


@needs_rosbags
def test_calibrating_the_imported_campaign_gives_the_direct_simulations_estimates(bags, th8, tmp_path, cli):
    bag, topic, rec = bags["mcap"]
    model = th8[0]
    code, out, err = cli("import-bag", bag, "--model", TH8 / "model.yaml", "--joints", "/joint_states",
                         "--marker", f"tool={topic}", "--clock-offset", rec.clock_offset, "--position-only",
                         "--out", tmp_path / "campaign.csv")
    assert code == 0, err
    assert f"{len(rec.q_poses)} poses of th8-like, markers tool: wrote" in out
    imported = rc.read_measurements(tmp_path / "campaign.csv", model)
    direct = rc.Measurements(q=rec.q_poses, positions=rec.truth[:, None], marker_names=("tool",),
                             joint_names=model.joint_names)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rc.RobocalWarning)
        got, want = rc.calibrate(model, imported), rc.calibrate(model, direct)
    assert [p.name for p in got.parameters] == [p.name for p in want.parameters]
    z = np.array([(a.estimate - b.estimate) / a.std for a, b in zip(got.parameters, want.parameters)])
    assert np.abs(z).max() < 4.0 and np.sqrt(np.mean(z ** 2)) < 1.6, dict(zip([p.name for p in got.parameters], z))


@needs_rosbags
def test_a_marker_missing_or_moving_in_a_still_moment_is_left_out_and_listed(th8, tmp_path, cli):
    model, true, q = th8
    rec = recording(model, true, q[:8], seed=4, noise=NOISE, lost=(2,))
    bag = tmp_path / "lost.bag"
    write_bag(bag, rec)
    found = read_bag(bag, model, joints="/joint_states", markers={"tool": "/tracker/point"},
                     rules=StillRules(clock_offset=rec.clock_offset))
    assert found.data.n_poses == 7
    assert [(x.marker, x.reason.split(" ")[0]) for x in found.left] == [(None, "no"), ("tool", "missing")]
    assert all(rec.still[2, 0] - 0.01 <= x.start <= rec.still[2, 0] + 0.15 for x in found.left)
    # the instrument's clock taken for the robot's: the samples of the last 0.37 s are of the motion after
    code, out, err = cli("import-bag", bag, "--model", TH8 / "model.yaml", "--joints", "/joint_states", "--marker",
                         "tool=/tracker/point", "--out", tmp_path / "c.csv")
    assert code == 0, err
    # (the last 0.17 s of each arrival): every still moment after the first is a moving marker
    moving = [line for line in out.splitlines() if line.startswith("left out: ") and "marker tool: moving (" in line]
    starts = np.array([float(line.split()[2].split("-")[0]) for line in moving])
    assert starts.size == 6 and np.all(np.abs(starts - rec.still[[1, 3, 4, 5, 6, 7], 0] - 0.07) < 0.08), starts


@needs_rosbags
def test_joints_are_mapped_and_a_model_comes_from_robot_description(th8, tmp_path, cli):
    model, true, q = th8
    rec = recording(model, true, q[:6], seed=6, noise=NOISE)
    bag = tmp_path / "described.bag"
    write_bag(bag, rec, description=rc.urdf_text(model))
    code, out, err = cli("import-bag", bag, "--joints", "/joint_states", "--marker", "tool=/tracker/point",
                         "--clock-offset", "0.37", "--out", tmp_path / "c.csv", "--model-out", tmp_path / "m.yaml")
    assert code == 0, err
    described = rc.read_model(tmp_path / "m.yaml")
    assert described.joint_names == model.joint_names and described.marker_names == ("tool",)
    data = rc.read_measurements(tmp_path / "c.csv", described)
    assert data.n_poses == 6 and np.abs(data.q - rec.q_poses).max() < 1e-6
    # a model whose joints the bag names otherwise: matched by --joint-map
    renamed = rc.read_model(TH8 / "model.yaml")
    text = (TH8 / "model.yaml").read_text().replace("name: j1", "name: base_yaw")
    (tmp_path / "renamed.yaml").write_text(text)
    renamed = rc.read_model(tmp_path / "renamed.yaml")
    assert renamed.joint_names[0] == "base_yaw"
    code, out, err = cli("import-bag", bag, "--model", tmp_path / "renamed.yaml", "--joints", "/joint_states",
                         "--marker", "tool=/tracker/point", "--out", tmp_path / "r.csv")
    assert_one_line_error(code, err, [str(bag), "base_yaw", "--joint-map base_yaw=NAME"], command="import-bag")
    code, out, err = cli("import-bag", bag, "--model", tmp_path / "renamed.yaml", "--joints", "/joint_states",
                         "--marker", "tool=/tracker/point", "--joint-map", "base_yaw=j1", "--out", tmp_path / "r.csv")
    assert code == 0 and "j1 as base_yaw" in out, err


def _truncated(path: Path, to: Path) -> Path:
    """A copy of the bag ``path`` cut at half its bytes (its one data file, for a ROS 2 folder)."""
    if path.is_dir():
        to.mkdir()
        for f in path.iterdir():
            data = f.read_bytes()
            (to / f.name).write_bytes(data if f.name == "metadata.yaml" else data[:len(data) // 2])
    else:
        to.write_bytes(path.read_bytes()[:path.stat().st_size // 2])
    return to


@needs_rosbags
@pytest.mark.parametrize("storage", list(BAGS))
def test_a_bag_without_the_topics_truncated_or_of_another_type_is_one_line(storage, bags, tmp_path, cli):
    bag, topic, _ = bags[storage]
    out = tmp_path / "c.csv"

    def refused(words, *args):
        code, _, err = cli("import-bag", *args, "--model", TH8 / "model.yaml", "--out", out)
        assert_one_line_error(code, err, words, command="import-bag")
        assert not out.exists() and list(tmp_path.iterdir()) in ([], [tmp_path / "cut"], [tmp_path / "cut.bag"])

    refused([str(bag), "no topic /nope in the bag", "/joint_states (sensor_msgs/msg/JointState)"],
            bag, "--joints", "/nope", "--marker", f"tool={topic}")
    refused([str(bag), "no topic /tracker/nope"], bag, "--joints", "/joint_states", "--marker", "tool=/tracker/nope")
    refused([str(bag), f"topic {topic.split(':')[0]} carries", "not the joints' sensor_msgs/msg/JointState"],
            bag, "--joints", topic.split(":")[0], "--marker", f"tool={topic}")
    refused([str(bag), "marker tool: topic /joint_states carries sensor_msgs/msg/JointState"],
            bag, "--joints", "/joint_states", "--marker", "tool=/joint_states")
    cut = _truncated(bag, tmp_path / ("cut.bag" if storage == "ros1" else "cut"))
    refused([str(cut), "not a readable ROS bag"], cut, "--joints", "/joint_states", "--marker", f"tool={topic}")


@needs_rosbags
def test_the_joints_topic_defaults_to_the_bags_only_one_and_several_are_named(th8, tmp_path, cli):
    model, true, q = th8
    rec = recording(model, true, q[:4], seed=3, noise=NOISE)
    one = write_bag(tmp_path / "one.bag", rec)
    code, out, err = cli("import-bag", tmp_path / "one.bag", "--model", TH8 / "model.yaml", "--marker", f"tool={one}",
                         "--clock-offset", rec.clock_offset, "--out", tmp_path / "one.csv")
    assert code == 0, err
    assert "joints from /joint_states, the bag's only sensor_msgs/msg/JointState topic" in out
    assert rc.read_measurements(tmp_path / "one.csv", model).n_poses == 4
    two = write_bag(tmp_path / "two.bag", rec, extra_topics=[("/other/joint_states", "sensor_msgs/msg/JointState")])
    code, _, err = cli("import-bag", tmp_path / "two.bag", "--model", TH8 / "model.yaml", "--marker", f"tool={two}",
                       "--out", tmp_path / "two.csv")
    assert_one_line_error(code, err, [str(tmp_path / "two.bag"), "--joints TOPIC", "2: /joint_states, "
                                      "/other/joint_states"], command="import-bag")
    assert not (tmp_path / "two.csv").exists()


@needs_rosbags
def test_a_path_that_is_no_bag_is_one_line(tmp_path, cli):
    (tmp_path / "notes.bag").write_text("not a bag\n")
    (tmp_path / "folder").mkdir()
    for bag, words in [(tmp_path / "none.bag", "no such file or folder"),
                       (tmp_path / "notes.bag", "not a readable ROS bag"),
                       (tmp_path / "folder", "a folder without metadata.yaml is not a ROS 2 bag")]:
        code, _, err = cli("import-bag", bag, "--model", TH8 / "model.yaml", "--joints", "/joint_states", "--marker",
                           "tool=/p", "--out", tmp_path / "c.csv")
        assert_one_line_error(code, err, [str(bag), words], command="import-bag")
    assert not (tmp_path / "c.csv").exists()


def test_without_the_ros_extra_the_command_says_which_and_exits_1(cli, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "rosbags", None)
    code, out, err = cli("import-bag", tmp_path / "any.bag", "--joints", "/joint_states", "--marker", "tool=/p",
                         "--out", tmp_path / "c.csv")
    assert code == 1 and "pip install 'robocal[ros]'" in err and len(err.strip().splitlines()) == 1
    with pytest.raises(rc.RobocalError, match=r"pip install 'robocal\[ros\]'"):
        read_bag(tmp_path / "any.bag", joints="/joint_states", markers={"tool": "/p"})
    assert not (tmp_path / "c.csv").exists()


def test_the_commands_defaults_are_the_rules_defaults():
    from robocal.cli import build_parser

    args = build_parser().parse_args(["import-bag", "x.bag", "--joints", "/j", "--marker", "a=/b", "--out", "c.csv"])
    rules = StillRules()
    assert np.isclose(np.deg2rad(args.still_deg_s), rules.speed_revolute)
    assert np.isclose(args.still_mm_s / 1e3, rules.speed_prismatic)
    assert np.isclose(args.drift_mm / 1e3, rules.drift)
    assert (args.min_still_s, args.settle_s, args.min_samples, args.clock_offset) == \
        (rules.min_duration, rules.settle, rules.min_samples, rules.clock_offset)
