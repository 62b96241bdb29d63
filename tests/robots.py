"""Test robots built in code (SI): a 6R industrial arm and a TH8-like cylindrical arm."""

from pathlib import Path

import numpy as np

import robocal as rc
from robocal import serial_model

DEG = np.pi / 180


def arm6r(markers=(("tool", (0.05, 0.02, 0.12)),), masses=False):
    """A 6R arm in modified DH, of the usual anthropomorphic shape (about 1 m reach)."""
    rows = [
        dict(joint="revolute"),
        dict(joint="revolute", alpha=-90 * DEG),
        dict(joint="revolute", d=0.45),
        dict(joint="revolute", alpha=-90 * DEG, r=0.45),
        dict(joint="revolute", alpha=90 * DEG),
        dict(joint="revolute", alpha=-90 * DEG),
    ]
    if masses:
        for row, m, c in zip(rows, [20, 15, 10, 5, 2, 1],
                             [(0, 0, -0.1), (0.2, 0, 0.05), (0.1, -0.02, 0.2), (0, 0.05, 0), (0, 0, 0.05), (0, 0, 0.02)]):
            row.update(mass=m, com=c)
    limits = [(-170 * DEG, 170 * DEG), (-120 * DEG, 60 * DEG), (-60 * DEG, 160 * DEG),
              (-170 * DEG, 170 * DEG), (-110 * DEG, 110 * DEG), (-180 * DEG, 180 * DEG)]
    c, s = np.cos(0.3), np.sin(0.3)
    return serial_model("arm6r", rows, markers=markers, joint_limits=limits, base_position=(1.5, -0.4, 0.2),
                        base_rotation=[[c, -s, 0], [s, c, 0], [0, 0, 1]])


def cylindrical(masses=False):
    """A TH8-like cylindrical arm: revolute base, prismatic vertical and radial joints, 3R wrist."""
    rows = [
        dict(joint="revolute"),
        dict(joint="prismatic", r=0.3),
        dict(joint="prismatic", alpha=-90 * DEG, theta=-90 * DEG, r=0.2),
        dict(joint="revolute", r=0.1),
        dict(joint="revolute", alpha=90 * DEG),
        dict(joint="revolute", alpha=-90 * DEG),
    ]
    if masses:
        for row, m, c in zip(rows, [30, 25, 12, 3, 2, 1],
                             [(0, 0, 0.2), (0.05, 0, -0.1), (0, 0.03, -0.3), (0, 0, 0.05), (0, 0.03, 0), (0, 0, 0.03)]):
            row.update(mass=m, com=c)
    limits = [(-150 * DEG, 150 * DEG), (0.0, 0.8), (0.0, 0.6), (-170 * DEG, 170 * DEG),
              (-100 * DEG, 100 * DEG), (-180 * DEG, 180 * DEG)]
    return serial_model("cylindrical", rows, markers=[("tool", (0.03, 0.02, 0.15))], joint_limits=limits,
                        base_position=(2.0, 0.5, -0.3))


TORSO = Path(__file__).resolve().parents[1] / "examples" / "torso" / "model.yaml"


def torso() -> rc.RobotModel:
    """examples/torso/model.yaml: a two-armed tree with a coupled joint."""
    return rc.read_model(TORSO)
