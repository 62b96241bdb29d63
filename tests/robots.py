"""Test robots built in code (SI): a 6R industrial arm, a TH8-like cylindrical arm, a 7-joint arm."""

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
        coms = [(0, 0, -0.1), (0.2, 0, 0.05), (0.1, -0.02, 0.2), (0, 0.05, 0), (0, 0, 0.05), (0, 0, 0.02)]
        for row, m, c in zip(rows, [20, 15, 10, 5, 2, 1], coms):
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


def arm7(masses=False):
    """A 7-joint arm of the collaborative shape of examples/arm7 (alternating perpendicular axes,
    about 0.8 m reach), placed in a tracker's frame."""
    rows = [dict(joint="revolute", r=0.34), dict(joint="revolute", alpha=-90 * DEG),
            dict(joint="revolute", alpha=90 * DEG, r=0.4), dict(joint="revolute", alpha=90 * DEG),
            dict(joint="revolute", alpha=-90 * DEG, r=0.4), dict(joint="revolute", alpha=-90 * DEG),
            dict(joint="revolute", alpha=90 * DEG, r=0.126)]
    if masses:
        coms = [(0, -0.03, -0.1), (0, -0.1, 0.03), (0.03, 0, -0.12), (0, 0.1, 0.03), (0, 0.03, -0.1), (0.05, 0, 0),
                (0, 0, 0.05)]
        for row, m, c in zip(rows, [4.0, 4.0, 3.0, 2.7, 1.7, 1.6, 0.5], coms):
            row.update(mass=m, com=c)
    limits = [(-170 * DEG, 170 * DEG), (-120 * DEG, 120 * DEG)] * 3 + [(-175 * DEG, 175 * DEG)]
    c, s = np.cos(-0.5), np.sin(-0.5)
    return serial_model("arm7", rows, markers=[("ball", (0.03, 0.02, 0.1))], joint_limits=limits,
                        base_position=(1.0, 0.8, 0.0), base_rotation=[[c, -s, 0], [s, c, 0], [0, 0, 1]])


def beyond_model(n: int, rng, *, poses=(60, 300), presets=None):
    """``n`` campaigns of simulated robots with effects beyond the model: the 6R and the cylindrical
    arm with masses in turn, each perturbed, the presets of ``robocal.sim.PRESETS`` in turn (in the
    order of ``presets``, default the table's), ``poses[0]`` to ``poses[1]`` random poses measured with
    20 um of noise, all drawn from ``rng``; yields (robot name, preset, k, nominal model, data)."""
    from robocal.sim import PRESETS, measure_campaign

    order = list(PRESETS) if presets is None else list(presets)
    robots = [("arm6r", arm6r(masses=True)), ("cylindrical", cylindrical(masses=True))]
    for k in range(n):
        name, nominal = robots[k % 2]
        preset = order[k % len(order)]
        true = rc.perturb_model(nominal, rc.identifiability(nominal).identified, rng=int(rng.integers(1 << 30)))
        q = rc.random_configurations(nominal, int(rng.integers(poses[0], poses[1] + 1)), rng=int(rng.integers(1 << 30)))
        data = measure_campaign(true, q, PRESETS[preset], rng=int(rng.integers(1 << 30)), robot_seed=k)
        yield name, preset, k, nominal, data


# the effects a real campaign meets, at the sizes industrial arms and a tracker show (SI)
EFFECTS = ("encoder", "repeatability", "backlash", "gears", "elasticity", "drift")


def imperfections(model: rc.RobotModel, effects, rng):
    """``RobotImperfections`` with the ``effects`` named (of ``EFFECTS``) at sizes drawn from ``rng``,
    and a tracker's noise: a 17 to 20 bit encoder on each revolute joint (1 to 5 um on a prismatic
    one); a per-axis repeatability of 10 to 50 um; lost motion of 0.005 to 0.03 deg (5 to 30 um) per
    joint, held on gravity's side where the load beats a friction of 0.5 to 50 N m (5 to 500 N); gear
    errors of 0.005 to 0.03 deg; the elastic preset's elasticity and bending; a drift of 1e-4 to 5e-4."""
    from robocal.sim import PRESETS, RobotImperfections

    angle = np.array([k == "angle" for k in model.reading_quantities])
    n = model.n_joints
    kw: dict = {"instrument_noise": rc.Noise.of("tracker").position}
    if "encoder" in effects:
        bits = int(rng.integers(17, 21))
        kw["encoder_resolution"] = tuple(np.where(angle, 2 * np.pi / 2 ** bits, rng.uniform(1e-6, 5e-6, n)))
    if "repeatability" in effects:
        kw["repeatability_sigma"] = float(rng.uniform(10e-6, 50e-6))
    if "backlash" in effects:
        kw["backlash"] = tuple(np.where(angle, rng.uniform(0.005, 0.03, n) * DEG, rng.uniform(5e-6, 30e-6, n)))
        kw["backlash_friction"] = tuple(np.exp(rng.uniform(np.log(0.5), np.log(50.0), n)) * np.where(angle, 1, 10))
    if "gears" in effects:
        kw["gear_error"] = float(rng.uniform(0.005, 0.03) * DEG)
    if "elasticity" in effects:
        kw.update(elasticity=PRESETS["elastic"].elasticity, bending=PRESETS["elastic"].bending)
    if "drift" in effects:
        kw["drift"] = float(rng.uniform(1e-4, 5e-4))
    return RobotImperfections(**kw)


def combined_effects(n: int, rng, *, poses=(60, 300)):
    """``n`` campaigns of simulated robots with several effects beyond the model at once: the 6R, the
    cylindrical and the 7-joint arm with masses in turn, each perturbed, with 2 to 4 of ``EFFECTS``
    (``imperfections``), ``poses[0]`` to ``poses[1]`` random poses, all drawn from ``rng``; yields
    (robot name, effects, k, nominal model, true model, imperfections, data)."""
    from robocal.sim import measure_campaign

    robots = [("arm6r", arm6r(masses=True)), ("cylindrical", cylindrical(masses=True)), ("arm7", arm7(masses=True))]
    for k in range(n):
        name, nominal = robots[k % len(robots)]
        effects = tuple(sorted(rng.choice(len(EFFECTS), int(rng.integers(2, 5)), replace=False)))
        effects = tuple(EFFECTS[i] for i in effects)
        imp = imperfections(nominal, effects, rng)
        true = rc.perturb_model(nominal, rc.identifiability(nominal).identified, rng=int(rng.integers(1 << 30)))
        q = rc.random_configurations(nominal, int(rng.integers(poses[0], poses[1] + 1)), rng=int(rng.integers(1 << 30)))
        data = measure_campaign(true, q, imp, rng=int(rng.integers(1 << 30)), robot_seed=k)
        yield name, effects, k, nominal, true, imp, data


TORSO = Path(__file__).resolve().parents[1] / "examples" / "torso" / "model.yaml"


def torso() -> rc.RobotModel:
    """examples/torso/model.yaml: a two-armed tree with a coupled joint."""
    return rc.read_model(TORSO)


HUMANOID = """
robocal_model: 1
name: humanoid-like
description: simulated upper body of a humanoid, 19 joints; dimensions chosen by us
units: {length: mm, angle: deg}
base: {position: [1800, -400, 250], rotation: {rpy: [0, 0, 20]}}
joints:
%(joints)s
frames:
  - {name: t1, joint: revolute, r: 300}
  - {name: t2, joint: revolute, alpha: -90, theta: -90}
  - {name: t3, joint: revolute, alpha: 90, d: 120}
  - {name: l1, joint: revolute, alpha: -90, d: 420, r: 210}
  - {name: l2, joint: revolute, alpha: 90, d: 40}
  - {name: l3, joint: revolute, alpha: -90, r: 260}
  - {name: l4, joint: revolute, alpha: 90, d: 30}
  - {name: l5, joint: revolute, alpha: -90, r: 230}
  - {name: l6, joint: revolute, alpha: 90}
  - {name: l7, joint: revolute, alpha: -90, r: 60}
  - {name: ltool, joint: fixed, parent: l7, position: [0, 0, 110],
     rotation: {matrix: [[0, 0, 1], [1, 0, 0], [0, 1, 0]]}}
  - {name: r1, joint: revolute, parent: t3, alpha: -90, gamma: 180, b: 0, d: 420, r: -210}
  - {name: r2, joint: revolute, alpha: 90, d: 40}
  - {name: r3, joint: revolute, alpha: -90, r: 260}
  - {name: r4, joint: revolute, alpha: 90, d: 30}
  - {name: r5, joint: revolute, alpha: -90, r: 230}
  - {name: r6, joint: revolute, alpha: 90}
  - {name: r7, joint: revolute, alpha: -90, r: 60}
  - {name: rtool, joint: fixed, parent: r7, position: [0, 0, 110],
     rotation: {matrix: [[0, 1, 0], [0, 0, 1], [1, 0, 0]]}}
  - {name: h1, joint: revolute, parent: t3, d: 520, r: 40}
  - {name: h2, joint: revolute, alpha: -90, d: 30}
  - {name: head, joint: fixed, parent: h2, position: [60, 0, 80], rotation: {rpy: [0, 90, 0]}}
markers:
  - {name: lhand, frame: ltool, position: [20, 10, 30]}
  - {name: lhand2, frame: ltool, position: [-30, 40, 10]}
  - {name: rhand, frame: rtool, position: [20, -10, 30]}
  - {name: rhand2, frame: rtool, position: [-30, -40, 10]}
  - {name: headset, frame: head, position: [0, 50, 40]}
"""
HUMANOID_JOINTS = ("t1", "t2", "t3", "l1", "l2", "l3", "l4", "l5", "l6", "l7", "r1", "r2", "r3", "r4", "r5", "r6",
                   "r7", "h1", "h2")


def humanoid(markers=None) -> rc.RobotModel:
    """A simulated humanoid-sized tree: 19 joints (trunk, two 7-joint arms, a head), three fixed
    frames placed by matrices (the hands' tools and the head), five markers (or those named in
    ``markers``); masses assumed from the geometry (relative compliances)."""
    import yaml

    from robocal.io import model_from_dict

    joints = "\n".join(f"  - {{name: {n}, limits: [-{60 if n.startswith(('t', 'h')) else 150}, "
                       f"{60 if n.startswith(('t', 'h')) else 150}]}}" for n in HUMANOID_JOINTS)
    d = yaml.safe_load(HUMANOID % {"joints": joints})
    if markers is not None:
        d["markers"] = [mk for mk in d["markers"] if mk["name"] in markers]
    return rc.default_masses(model_from_dict(d, source="humanoid"))
