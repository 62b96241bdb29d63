"""import-urdf says at which link the chain ended and why, and names the links further down that
--tip-link could end it at: on an arm whose chain runs into a fixed dummy link holding a ball and a
camera (as a Gen3 lite with a ball fitted), the default stops at the dummy link, says so, suggests
--tip-link ball_link, and that option imports the arm to the ball's centre."""

from __future__ import annotations

import numpy as np
import pytest

import robocal as rc
from robocal._files.urdf import chain_end

ARM = ('<link name="base_link"/><link name="l1"/><link name="l2"/><link name="l3"/>'
       '<link name="end_effector_link"/><link name="dummy_link"/>'
       '<joint name="j1" type="revolute"><origin xyz="0 0 0.1"/><parent link="base_link"/><child link="l1"/>'
       '<axis xyz="0 0 1"/><limit lower="-3" upper="3"/></joint>'
       '<joint name="j2" type="revolute"><origin xyz="0 0 0.3"/><parent link="l1"/><child link="l2"/>'
       '<axis xyz="0 1 0"/><limit lower="-3" upper="3"/></joint>'
       '<joint name="j3" type="revolute"><origin xyz="0 0 0.3"/><parent link="l2"/><child link="l3"/>'
       '<axis xyz="0 1 0"/><limit lower="-3" upper="3"/></joint>'
       '<joint name="ee" type="fixed"><origin xyz="0 0 0.1"/><parent link="l3"/><child link="end_effector_link"/>'
       '</joint>'
       '<joint name="dummy" type="fixed"><parent link="end_effector_link"/><child link="dummy_link"/></joint>')
BALL = ('<link name="ball_mount"/><link name="ball_link"/>'
        '<joint name="mount" type="fixed"><origin xyz="0 0 0.05"/><parent link="dummy_link"/>'
        '<child link="ball_mount"/></joint>'
        '<joint name="ball" type="fixed"><origin xyz="0 0 0.02"/><parent link="ball_mount"/><child link="ball_link"/>'
        '</joint>')
CAMERA = ('<link name="camera_link"/><joint name="cam" type="fixed"><origin xyz="0.05 0 0"/>'
          '<parent link="dummy_link"/><child link="camera_link"/></joint>')
FINGERS = "".join(f'<link name="{s}_finger"/><joint name="{s}_finger_joint" type="revolute">'
                  f'<parent link="dummy_link"/><child link="{s}_finger"/><axis xyz="1 0 0"/>'
                  '<limit lower="0" upper="0.8"/></joint>' for s in ("left", "right"))


def urdf(*parts: str) -> str:
    return '<robot name="lite">' + "".join(parts) + "</robot>"


@pytest.mark.parametrize("parts, link, reason, further", [
    ((ARM, BALL, CAMERA), "dummy_link", "it holds 2 fixed branches (links ball_mount, camera_link)",
     ("ball_link", "camera_link")),
    ((ARM, BALL, CAMERA, FINGERS), "dummy_link",
     "2 moving branches part there (joints left_finger_joint, right_finger_joint", ("ball_link", "camera_link")),
    ((ARM, FINGERS), "dummy_link", "2 moving branches part there", ()),
    ((ARM, BALL), "ball_link", "it has no child link", ()),
    ((ARM,), "dummy_link", "it has no child link", ()),
])
def test_the_chain_end_is_named_with_its_reason_and_the_links_further_down(parts, link, reason, further):
    end = chain_end(urdf(*parts))
    assert end.link == link and reason in end.reason and end.further == further
    assert rc.io.read_urdf(urdf(*parts)).description.endswith(f"-> {link}")


def test_import_urdf_says_where_the_chain_ended_and_suggests_the_tip_link(cli, tmp_path):
    path = tmp_path / "lite.urdf"
    path.write_text(urdf(ARM, BALL, CAMERA))
    code, out, err = cli("import-urdf", path, "--out", tmp_path / "a.yaml")
    assert code == 0, err
    said = out.strip().splitlines()[-1]
    assert said.startswith("the chain ends at link 'dummy_link': it holds 2 fixed branches"), said
    assert "--tip-link NAME" in said and "ball_link, camera_link" in said
    assert rc.read_model(tmp_path / "a.yaml").marker_names == ("dummy_link",)
    code, out, err = cli("import-urdf", path, "--out", tmp_path / "b.yaml", "--tip-link", "ball_link")
    assert code == 0, err
    assert out.strip().splitlines()[-1] == "the chain ends at link 'ball_link' (--tip-link)"
    model = rc.read_model(tmp_path / "b.yaml")
    assert model.marker_names == ("ball_link",) and model.description.endswith("-> ball_link")
    # the ball's centre by hand: 0.87 m above the base at rest; j2 at +90 deg swings the 0.47 m above
    # it (at z = 0.4) onto +x
    q = np.array([[0.0, 0.0, 0.0], [0.0, np.pi / 2, 0.0], [np.pi / 2, np.pi / 2, 0.0]])
    expected = np.array([[0.0, 0.0, 0.87], [0.47, 0.0, 0.4], [0.0, 0.47, 0.4]])
    np.testing.assert_allclose(rc.forward_kinematics(model, q).positions[:, 0], expected, atol=1e-9)


def test_where_only_fingers_go_on_nothing_is_suggested(cli, tmp_path):
    path = tmp_path / "arm.urdf"
    path.write_text(urdf(ARM, FINGERS))
    code, out, err = cli("import-urdf", path, "--out", tmp_path / "a.yaml")
    assert code == 0, err
    said = out.strip().splitlines()[-1]
    assert said.startswith("the chain ends at link 'dummy_link': 2 moving branches part there")
    assert "--tip-link" not in said
