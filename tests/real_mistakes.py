"""Mistakes injected into the published tracker campaigns of a UR5 and a Barrett WAM
(tests/data/real): each changes the real measurements (or the model file, or the readings) the way
one mistake would, keeping the robot's own scatter and the instrument's noise, and names the
hypotheses of the diagnosis that should come first (docs/diagnosis.md).

The truth a case's calibrated model is held against is the calibration of the whole clean grid,
evaluated at the campaign's test poses (the random file): a calibration that took up the mistake
places the robot that far from where the clean one does.

Used by tests/test_diagnosis.py (a few cases) and benchmarks/diagnosis_corpus.py (all of them).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace
from functools import cache, partial

import diagnosis_corpus as corpus
import numpy as np
import real_campaigns as real
from scipy.spatial.transform import Rotation

import robocal as rc


@dataclass(frozen=True, eq=False)
class Case(corpus.Case):
    """A simulated corpus' case on a real campaign: the truth is held against it at ``q_eval``, the
    campaign's test readings (None: no truth known)."""

    q_eval: np.ndarray | None = None

    def run(self):
        """The calibration (diagnosed) of the case, warnings silenced."""
        return super().run()[0]

    def model_error(self, result) -> float | None:
        """RMS distance (m) between where the calibrated model and the truth put the first marker at the
        evaluation readings, each in its own measurement frame (None without a truth)."""
        if self.truth is None or self.q_eval is None:
            return None
        marker = self.truth.marker_names[0]
        a = rc.evaluate(result.calibrated_model, self.q_eval).positions[:, result.calibrated_model.marker_names.index(
            marker)]
        b = rc.evaluate(self.truth, self.q_eval).positions[:, 0]
        return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1))))


@cache
def clean(robot: str):
    """(nominal model, the grid campaign, the calibration of the whole grid, the test readings)."""
    model = real.nominal(robot)
    grid = real.campaign(robot, "grid", model)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        truth = rc.calibrate(model, grid).calibrated_model
    return model, grid, truth, real.campaign(robot, "random", model).q


def _case(name, robot, data, expected, model=None, **options) -> Case:
    nominal, _, truth, q_test = clean(robot)
    return Case(f"{robot}: {name}", nominal if model is None else model, data, expected, options, truth, q_test)


def _moved(truth, q, changed):
    """How the measured positions at ``q`` move when the robot is ``changed`` instead of ``truth``."""
    return rc.evaluate(changed, q).positions - rc.evaluate(truth, q).positions


def _with_marker(truth, offset):
    mk = truth.markers[0]
    return truth.replace(markers=(replace(mk, position=tuple(np.add(mk.position, offset))),))


def tool_changed(robot: str, row_share: float = 0.5, offset=(0.02, 0.0, 0.01)) -> Case:
    """The tool changed partway: the marker sits ``offset`` (m, in the flange) elsewhere from a row on."""
    _, grid, truth, _ = clean(robot)
    k = int(row_share * grid.n_poses)
    pos = grid.positions.copy()
    pos[k:] += _moved(truth, grid.q[k:], _with_marker(truth, offset))
    return _case(f"the tool changed at row {k}", robot, replace(grid, positions=pos), ("marker moved",))


def reflector_moved(robot: str) -> Case:
    """The reflector moved 1 mm in its nest from a quarter of the campaign on."""
    c = tool_changed(robot, 0.24, (1e-3, 0.0, 0.0))
    return replace(c, name=f"{robot}: reflector moved 1 mm in its nest")


def second_nest(robot: str) -> Case:
    """The reflector put in a second nest, 8 mm from the first, on a quarter of the rows here and there."""
    _, grid, truth, _ = clean(robot)
    rows = np.sort(np.random.default_rng(5).choice(grid.n_poses, grid.n_poses // 4, replace=False))
    pos = grid.positions.copy()
    pos[rows] += _moved(truth, grid.q[rows], _with_marker(truth, (0.0, 0.008, 0.0)))
    return _case("a reflector in a second nest on some rows", robot, replace(grid, positions=pos), ("marker moved",))


def gear_ratio(robot: str, ratio: float = 1.02, joint: int = 1) -> Case:
    """A joint that turns ``ratio`` times its reading (a gear ratio off)."""
    _, grid, truth, _ = clean(robot)
    q_true = grid.q.copy()
    q_true[:, joint] *= ratio
    pos = grid.positions + rc.evaluate(truth, q_true).positions - rc.evaluate(truth, grid.q).positions
    return _case(f"joint {joint + 1} turns {ratio} times its reading", robot, replace(grid, positions=pos),
                 ("joint scale",))


def whole_turn(robot: str, joint: int = 3) -> Case:
    """One joint's readings a full turn off (a turn count)."""
    _, grid, _, _ = clean(robot)
    q = grid.q.copy()
    q[:, joint] += 2 * np.pi
    return _case(f"joint {joint + 1} one full turn off", robot, replace(grid, q=q), ("whole turns",))


def targets(robot: str) -> Case:
    """The nominal model's own predictions (the file's targets) exported in place of the measurements."""
    model, grid, _, _ = clean(robot)
    return _case("the targets in place of the measurements", robot,
                 replace(grid, positions=rc.evaluate(model, grid.q).positions), ("nominal predictions",))


def link_off(robot: str, frame: int = 2, error: float = 0.1) -> Case:
    """A link length of the model file ``error`` (m) off (its d)."""
    model, grid, _, _ = clean(robot)
    frames = list(model.frames)
    frames[frame] = replace(frames[frame], d=frames[frame].d + error)
    return _case(f"a link ({frames[frame].name}.d) {error * 1e3:.0f} mm off in the model file", robot, grid,
                 ("model values",),
                 model=model.replace(frames=tuple(frames)))


def model_in_metres(robot: str) -> Case:
    """The model file's lengths in metres where millimetres were declared (every length a thousandth)."""
    model, grid, _, _ = clean(robot)
    markers = tuple(replace(k, position=tuple(np.multiply(k.position, 1e-3))) for k in model.markers)
    small = model.replace(frames=tuple(replace(f, d=f.d * 1e-3, r=f.r * 1e-3) for f in model.frames), markers=markers,
                          base_position=tuple(np.multiply(model.base_position, 1e-3)))
    return _case("the model file's lengths in metres where millimetres were declared", robot, grid,
                 ("model unit", "model values"), model=small)


def missed_shot(robot: str) -> Case:
    """A missed shot: from a row on each row holds the point of the next pose."""
    _, grid, _, _ = clean(robot)
    k = grid.n_poses * 3 // 10
    pos = grid.positions.copy()
    pos[k:-1] = grid.positions[k + 1:]
    return _case(f"a missed shot at row {k}", robot, replace(grid, positions=pos), ("rows shifted",))


def mirrored(robot: str) -> Case:
    """A left-handed measurement frame: y mirrored."""
    _, grid, _, _ = clean(robot)
    return _case("a left-handed tracker frame", robot, replace(grid, positions=grid.positions * [1, -1, 1]),
                 ("mirrored frame",))


def joint_sign(robot: str, joint: int = 4) -> Case:
    _, grid, _, _ = clean(robot)
    q = grid.q.copy()
    q[:, joint] *= -1
    return _case(f"joint {joint + 1}'s sign flipped", robot, replace(grid, q=q), ("joint sign", "model values"))


def joints_swapped(robot: str) -> Case:
    _, grid, _, _ = clean(robot)
    q = grid.q.copy()
    q[:, [1, 2]] = q[:, [2, 1]]
    return _case("joints 2 and 3 swapped", robot, replace(grid, q=q), ("joints swapped",))


def millimetres_as_metres(robot: str) -> Case:
    _, grid, _, _ = clean(robot)
    return _case("positions in millimetres declared as metres", robot, replace(grid, positions=grid.positions * 1e3),
                 ("unit factor",))


def tracker_bumped(robot: str) -> Case:
    """The tracker bumped (turned 0.1 deg about its vertical) at 60 % of the campaign."""
    _, grid, _, _ = clean(robot)
    k = grid.n_poses * 6 // 10
    R = Rotation.from_rotvec([0, 0, np.radians(0.1)]).as_matrix()
    pos = grid.positions.copy()
    pos[k:] = pos[k:] @ R.T
    return _case(f"the tracker bumped at row {k}", robot, replace(grid, positions=pos), ("step change",))


def joint_rehomed(robot: str, joint: int = 1, offset_deg: float = 0.1) -> Case:
    """One joint rehomed (or its encoder slipped) at 40 % of the campaign: from then on it reads
    ``offset_deg`` more than before."""
    _, grid, _, _ = clean(robot)
    k = grid.n_poses * 4 // 10
    q = grid.q.copy()
    q[k:, joint] += np.radians(offset_deg)
    return _case(f"joint {joint + 1} rehomed at row {k} ({offset_deg:g} deg)", robot, replace(grid, q=q),
                 ("joint rehomed",))


def joint_drifting(robot: str, joint: int = 1, drift_deg: float = 0.1) -> Case:
    """One joint's readings drifting off its position along the campaign (warming up), ``drift_deg``
    more by the last row."""
    _, grid, _, _ = clean(robot)
    q = grid.q.copy()
    q[:, joint] += np.radians(drift_deg) * np.linspace(0.0, 1.0, grid.n_poses)
    return _case(f"joint {joint + 1} drifting {drift_deg:g} deg along the campaign", robot, replace(grid, q=q),
                 ("drift",))


def lost_motion(robot: str, joint: int = 1, lost_deg: float = 0.05) -> Case:
    """One joint with ``lost_deg`` of lost motion (backlash) more than the robot has: its readings
    half of it ahead of its position, along the direction of its last move in the grid's order."""
    _, grid, _, _ = clean(robot)
    q = grid.q.copy()
    q[:, joint] += np.radians(lost_deg) / 2 * rc.sim.approach_sides(grid.q)[:, joint]
    return _case(f"joint {joint + 1} with {lost_deg:g} deg of lost motion", robot, replace(grid, q=q),
                 ("lost motion",))


def reading_typo(robot: str) -> Case:
    """One joint reading mistyped (40 deg off)."""
    _, grid, _, _ = clean(robot)
    q = grid.q.copy()
    q[17, 0] += np.radians(40)
    return _case("one reading mistyped", robot, replace(grid, q=q), ("blunders",))


def readings_lag(robot: str) -> Case:
    """The joint log lags the tracker by a third of a row along the campaign's path."""
    _, grid, _, _ = clean(robot)
    q = grid.q - np.gradient(grid.q, axis=0) / 3.0
    return _case("the joint log lags a third of a row", robot, replace(grid, q=q), ("readings lag",))


def validation_repeated(robot: str) -> Case:
    """A validation file that repeats the fitted one (the fitted file's last fifth, rounded)."""
    _, grid, _, _ = clean(robot)
    k = grid.n_poses * 4 // 5
    val = grid.subset(np.arange(k, grid.n_poses))
    val = replace(val, q=np.round(val.q, 6), positions=np.round(val.positions, 6))
    return _case("a validation file repeating fitted poses", robot, grid, ("validation repeated",), validation=val)


MISTAKES = (tool_changed, reflector_moved, second_nest, gear_ratio, whole_turn, targets, link_off, model_in_metres,
            missed_shot, mirrored, joint_sign, joints_swapped, millimetres_as_metres, tracker_bumped, joint_rehomed,
            joint_drifting, lost_motion, reading_typo, readings_lag, validation_repeated)
# the same mistakes elsewhere: another joint, link, ratio, row and tool
VARIANTS = (partial(gear_ratio, ratio=0.99, joint=2), partial(whole_turn, joint=0), partial(joint_sign, joint=1),
            partial(link_off, frame=1, error=0.05), partial(tool_changed, row_share=0.3, offset=(0.0, 0.01, 0.0)))


def mistakes() -> list[Case]:
    """Every mistake injected into the real campaigns, on the UR5 and on the WAM."""
    return [make(robot) for robot in ("UR5", "WAM") for make in MISTAKES + VARIANTS]
