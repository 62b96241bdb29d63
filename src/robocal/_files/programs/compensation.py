"""A robot program compensated: each target replaced by the one the nominal controller must be given
for the calibrated robot to land where the program meant (docs/formats.md, "Robot programs")."""

from __future__ import annotations

import bisect
import dataclasses
import math
import re
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from ..._accuracy.compensation import (
    POSTURE_TOL,
    arm_chain,
    compensate,
    compensate_poses,
    configuration_fits,
    distinct_postures,
    on_robot_base,
    posture_margins,
    ranges_for,
)
from ..._base.arguments import POSITIVE, TEXT, accepts, both, each_a, is_a, marker_of, optional, same_robot_as
from ..._base.errors import InputError, RobocalWarning, suggest, warn
from ..._model.kinematics import evaluate
from ..._model.robot import Marker, RobotModel
from . import (
    BEYOND,
    CONFIGURATION,
    DIALECTS,
    DIGITS,
    KEEP,
    NO_SOLUTION,
    NOT_CONVERGED,
    REACHED,
    UNREACHED,
    joint_units,
    joint_values,
)
from .frames import Catalogue, frames_of, index_uses
from .syntax import SLACK, Program, edited, format_number


@dataclass(frozen=True)
class TargetResult:
    """What became of one target: ``status`` (``ok`` or why it was left unchanged; ``read only: ...``
    for a target that is not a literal, ``not compensated: ...`` for one motions reach only through
    expressions), the ``tool`` and work object ``wobj`` a pose target was solved with, how far its
    tool moved (``moved``, m) and turned (``turned``, rad) between the old target and the new one,
    the largest change of a revolute and of a prismatic reading (rad, m), ``through``: the
    expressions motions also reach it through (``Offs (line 30)``), and ``outside``: the joints
    whose compensated readings lie beyond the ranges the calibration measured (``ranges``)."""

    name: str
    line: int
    kind: str
    status: str
    moved: float = 0.0
    turned: float = 0.0
    angle_change: float = 0.0
    length_change: float = 0.0
    tool: str = ""
    wobj: str = ""
    through: str = ""
    outside: tuple[str, ...] = ()


@dataclass(frozen=True)
class ProgramCompensation:
    """The compensated program's ``text``, a ``TargetResult`` per target in source order, and
    ``notes``: what the user should know of the whole (posture bits the robot does not have)."""

    text: str
    targets: tuple[TargetResult, ...]
    notes: tuple[str, ...] = ()

    @property
    def flagged(self) -> tuple[TargetResult, ...]:
        return tuple(t for t in self.targets if _is_flagged(t))


def _is_flagged(result: TargetResult) -> bool:
    """Whether a target was left unchanged for a reason the user must see (not one only read, nor
    one reached only through expressions)."""
    return result.status != REACHED and not result.status.startswith(("read only", "not compensated"))


TOOLS, WOBJS = ("tool", "frame"), ("wobj", "frame")


def _given(catalogue: Catalogue, program: Program, name: str | None, kinds, option: str) -> None:
    """A frame named on the command line exists and is of a kind robocal can use, or an InputError."""
    if name is None:
        return
    found = catalogue.find(name, kinds)
    if isinstance(found, str):
        names = catalogue.names(kinds)
        hint = suggest(name, names) if names else "; the program declares none"
        what = "tool" if "tool" in kinds else "work object"
        kind = catalogue.frames.get(catalogue.module.key(name))
        raise InputError(f"{name!r} is a {kind.kind}, not something robocal can use here" if kind else
                         f"no {what} {name!r} in {program.source}{hint}", where=option)


def _tool_models(nominal, calibrated, marker, name: str, X):
    """The models with the tool ``X`` (in the flange: the frame the model's tool point hangs on) as
    their only marker: a program's tool is exact in both models."""
    mk = Marker(name, nominal.markers[marker].frame, tuple(X[:3, 3]), tuple(map(tuple, X[:3, :3])))
    return nominal.replace(markers=(mk,)), calibrated.replace(markers=(mk,)), 0


def _angle(Ra, Rb) -> np.ndarray:
    """(N,) angle (rad) of the rotation between Ra and Rb, accurate near zero."""
    return Rotation.from_matrix(Ra @ np.swapaxes(Rb, -1, -2)).magnitude()


def _status(solved, comp, tol, tol_rot) -> list[str]:
    reached, far = comp.reached(tol, tol_rot), comp.out_of_reach(tol, tol_rot)
    return [NO_SOLUTION if not s else (UNREACHED if f else NOT_CONVERGED) if not r else BEYOND if not inside else
            REACHED for s, r, f, inside in zip(solved, reached, far, comp.within_limits)]


def _results(model, targets, status, ok, comp, moved, turned, ang, lin) -> list[TargetResult]:
    """A result per target; where it was compensated (``ok``), how far it moved and the joints whose
    compensated readings lie beyond the calibrated ranges."""
    return [TargetResult(t.name, t.line, t.kind, st) if not ok[i] else
            TargetResult(t.name, t.line, t.kind, st, moved[i], turned[i], ang[i], lin[i],
                         outside=tuple(n for n, o in zip(model.joint_names, comp.outside[i]) if o))
            for i, (t, st) in enumerate(zip(targets, status))]


def _changes(model, q_old, q_new):
    angle = np.array([k == "angle" for k in model.reading_quantities])
    d = np.abs(q_new - q_old)
    return np.where(angle, d, 0).max(axis=1), np.where(angle, 0, d).max(axis=1)


def _joint_edits(program, model, targets, q_new, edits):
    units = joint_units(model, DIALECTS[program.dialect])
    for t, q in zip(targets, q_new):
        for n, v, u in zip(t.joints, q, units):
            edits.append((n.start, n.end, format_number(v / u, n, digits=DIGITS[u], keep=KEEP / u)))


def _pose_edits(module, targets, X_new, X_old, edits) -> None:
    """Edits of the pose targets' numbers (an orientation rewritten only where it turned by more than
    KEEP); configuration data are never rewritten."""
    L, U = module.LENGTH, module.ORIENTATION
    turned = _angle(X_new[:, :3, :3], X_old[:, :3, :3])
    orientations = module.orientation_values(X_new[:, :3, :3], targets)        # file units
    for i, t in enumerate(targets):
        for n, v in zip(t.position, X_new[i, :3, 3] / L):
            edits.append((n.start, n.end, format_number(v, n, digits=DIGITS[L], keep=KEEP / L)))
        if turned[i] > KEEP:
            for n, v in zip(t.orientation, orientations[i]):
                edits.append((n.start, n.end, format_number(v, n, digits=DIGITS[U], keep=0.0)))


def _configurations(module, targets):
    """Per pose target the posture bits (3,) and turn windows (6,) its configuration data ask for
    (all free where it has none)."""
    conf = [module.wanted(t, 6) if t.configuration else (np.full(3, -1), np.full(6, np.nan)) for t in targets]
    return np.array([c[0] for c in conf]).reshape(-1, 3), np.array([c[1] for c in conf]).reshape(-1, 6)


def _needs(module, nominal, marker, target, q, want) -> str:
    """Why the written configuration data do not reach the compensated readings ``q``: what they would be."""
    margins = posture_margins(nominal, q[None], marker=marker)[0]
    decided = distinct_postures(nominal, marker) & (np.abs(margins) > POSTURE_TOL)
    bits = np.where(decided, margins < 0, want > 0)
    new = module.configuration_values(q, bits, target, SLACK)
    old = [int(n.value) for n in target.configuration]
    return f"{CONFIGURATION}: the compensated joints need {','.join(map(str, new))}, not {','.join(map(str, old))}"


def _pose_targets(program, module, nominal, calibrated, marker, X_BO, targets, hints, tol, tol_rot, edits, ranges):
    """Compensate the pose targets (``X_BO``: their work object in the robot's base frame); their
    results (the joint targets' results are made alongside)."""
    chain = arm_chain(nominal, marker)
    if nominal.n_joints != 6 or len(chain) != 6:
        raise InputError(f"Cartesian targets need a six-axis arm, {nominal.name} has {nominal.n_joints} joints and "
                         f"{len(chain)} moving frames to its tool point (first target at line {targets[0].line})",
                         source=program.source)
    X_B = X_BO @ module.poses(targets)
    want, turn = _configurations(module, targets)
    pc = compensate_poses(nominal, calibrated, X_B[:, :3, 3], X_B[:, :3, :3], marker=marker, want=want,
                          turn_from=turn, hints=hints, ranges=ranges)
    status = _status(pc.solved, pc.compensation, tol, tol_rot)
    # the configuration data stay as written: a target they no longer reach is left unchanged
    fits = configuration_fits(nominal, pc.q, want, turn, marker=marker)
    status = [_needs(module, nominal, marker, t, pc.q[i], want[i]) if s == REACHED and not fits[i] else s
              for i, (t, s) in enumerate(zip(targets, status))]
    ok = np.array([s == REACHED for s in status])
    X_new = np.tile(np.eye(4), (len(targets), 1, 1))
    X_new[:, :3, :3], X_new[:, :3, 3] = pc.rotations, pc.positions
    X_new = np.linalg.inv(X_BO) @ X_new
    if ok.any():
        _pose_edits(module, [t for t, k in zip(targets, ok) if k], X_new[ok], module.poses(targets)[ok], edits)
    ang, lin = _changes(nominal, np.nan_to_num(pc.q_nominal), pc.q)
    with np.errstate(over="ignore"):            # a target far out of reach: not reported, its distance may overflow
        moved = np.linalg.norm(pc.positions - X_B[:, :3, 3], axis=1)
    turned = _angle(pc.rotations, X_B[:, :3, :3])
    return _results(nominal, targets, status, ok, pc.compensation, moved, turned, ang, lin)


@accepts(program=is_a(Program), nominal=is_a(RobotModel), calibrated=both(is_a(RobotModel), same_robot_as("nominal")),
         marker=marker_of("nominal"), tool=optional(TEXT), wobj=optional(TEXT), companions=each_a(Program),
         tol=POSITIVE, tol_rot=POSITIVE, ranges=optional(ranges_for("nominal")))
def compensate_program(program: Program, nominal: RobotModel, calibrated: RobotModel, *, marker: int = 0,
                       tool: str | None = None, wobj: str | None = None, companions=(), tol: float = 1e-6,
                       tol_rot: float = math.radians(1e-4), ranges=None) -> ProgramCompensation:
    """The program with every literal target compensated for the calibrated robot.

    Targets are in the robot's base frame: both models are taken on it (``on_robot_base``), so
    neither model's base (where an instrument saw the robot) moves a target. Joint targets become
    the readings at which ``calibrated`` reaches the pose ``nominal`` reaches at the old ones
    (``compensate``); Cartesian targets become the poses whose nominal inverse kinematics, in the
    target's configuration, gives those readings (``compensate_poses``). Configuration data are
    kept as written. A target out of reach, whose new readings pass a joint limit or that its
    configuration data no longer reach is left unchanged and flagged in a comment on the line
    before it.

    Parameters
    ----------
    program : Program
        As ``read_program`` gives it.
    nominal : RobotModel
        The model the controller holds.
    calibrated : RobotModel
        The calibrated model (the nominal's joints and markers).
    marker : int
        The model's tool point (default its first marker): the frame it hangs on is the flange.
    tool : str, optional
        A tool (tooldata, FRAME or TOOL_DATA[n], pose variable) in the flange, declared in the
        program or a companion, that every Cartesian target uses (default: each target's own, from
        the motions that move to it).
    wobj : str, optional
        A work object (wobjdata, FRAME or BASE_DATA[n], pose variable) in the robot's base frame,
        declared in the program or a companion, that every Cartesian target is in (default: each
        target's own). With ``tool``, targets whose frames the program does not tell are solved too.
    companions : sequence of Program
        Files read with the program, of its dialect: their tools and work objects (a KRL
        ``$config.dat``, a RAPID module of tooldata) and their motions' uses of the program's
        declared targets (a KRL ``.src`` for its ``.dat``).
    tol : float
        Position residual above which a target counts as out of reach, m.
    tol_rot : float
        Rotation residual above which a target counts as out of reach, rad.
    ranges : array_like, shape (n_joints, 2), optional
        Each joint's lowest and highest reading where ``calibrated`` was calibrated (SI, NaN where
        not known: ``read_calibration``); each target names the joints its compensated readings
        take beyond them (``TargetResult.outside``).

    Returns
    -------
    ProgramCompensation
        The compensated program text and what happened to each target.
    """
    module = DIALECTS[program.dialect]
    # a program's targets are in the robot's base frame: both models on it, the instrument's frame gone
    nominal, calibrated = on_robot_base(nominal), on_robot_base(calibrated)
    catalogue = Catalogue(module, program, companions)
    _given(catalogue, program, tool, TOOLS, "--tool")
    _given(catalogue, program, wobj, WOBJS, "--wobj")
    live = [t for t in program.targets if not t.skip and t.name not in (tool, wobj)]
    if live:
        _marker_moved(nominal, calibrated, marker, tol)
    joints = [t for t in live if t.kind == "joint"]
    edits: list[tuple[int, int, str]] = []
    results: dict[int, TargetResult] = {}
    if joints:      # a six-axis arm's joint targets match the flange's pose, which carries any tool
        results.update(_joint_targets(program, nominal, calibrated.replace(markers=nominal.markers), marker,
                                      joints, tol, tol_rot, edits, ranges))
    uses = program.uses + tuple(u for c in companions for u in c.uses)
    for (tool_name, wobj_name), poses in _pose_groups(module, live, uses, tool, wobj, results).items():
        X_FT, X_BO = catalogue.find(tool_name, TOOLS), catalogue.find(wobj_name, WOBJS)
        names = dict(tool=catalogue.canonical(tool_name), wobj=catalogue.canonical(wobj_name))
        if isinstance(X_FT, str) or isinstance(X_BO, str):
            why = X_FT if isinstance(X_FT, str) else X_BO
            results.update({id(t): TargetResult(t.name, t.line, t.kind, str(why), through=through,
                                                tool=names["tool"], wobj=names["wobj"]) for t, through in poses})
            continue
        n_, c_, m_ = _tool_models(nominal, calibrated, marker, tool_name, X_FT)
        targets = [t for t, _ in poses]
        done = _pose_targets(program, module, n_, c_, m_, X_BO, targets, _hints(program, n_, targets), tol,
                             tol_rot, edits, ranges)
        results.update({id(t): dataclasses.replace(r, through=via, **names) for (t, via), r in zip(poses, done)})
    rows = [results.get(id(t), TargetResult(t.name, t.line, t.kind, f"read only: {t.skip or 'a frame in use'}"))
            for t in program.targets]
    return ProgramCompensation(text=edited(program.text, edits, _flags(program, rows), comment=module.COMMENT),
                               targets=tuple(rows), notes=_posture_notes(nominal, marker, live)
                               + _relative_notes(program))


def _relative_notes(program: Program) -> tuple[str, ...]:
    """What a program's relative motions (KRL's ``LIN_REL``) get: nothing of their own."""
    if not program.relative:
        return ()
    listed = ", ".join(f"{what} (line {line})" for what, line in program.relative)
    return (f"{listed} left as written: a relative motion moves by its offset from wherever the robot is, so it "
            "carries the compensation of the target before it, not one of its own (the calibration's change over "
            "the offset is not compensated)",)


def _marker_moved(nominal: RobotModel, calibrated: RobotModel, marker: int, tol: float) -> None:
    """Warn where the calibration moved a marker on the flange by more than ``tol`` (m): a program's
    tools are exact on the flange, and the flange's own error that no campaign tells from the
    marker's (its offset along the last axis) is then in the marker, not compensated."""
    frame = nominal.markers[marker].frame
    moved = [(float(np.linalg.norm(np.subtract(c.position, m.position))), m.name)
             for m, c in zip(nominal.markers, calibrated.markers) if m.frame == frame]
    gap, name = max(moved)
    if gap > tol:
        warn(f"the calibrated model places marker {name} {gap * 1e3:.3g} mm from its nominal place on the flange: a "
             "program's tools are taken as exact on the flange, so what of that is the flange's own error (its "
             "offset along the last axis, which no campaign tells from the marker's) is not compensated; with the "
             "marker's place measured and held (calibrate --known markers) the flange's error is identified as such",
             RobocalWarning)


def _posture_notes(nominal: RobotModel, marker: int, live) -> tuple[str, ...]:
    """A note where the configuration data hold posture bits the robot's geometry does not have."""
    if not any(t.kind == "pose" and t.configuration for t in live) or len(arm_chain(nominal, marker)) < 6:
        return ()
    missing = [name for name, d in zip(("shoulder", "elbow", "wrist"), distinct_postures(nominal, marker)) if not d]
    if not missing:
        return ()
    return (f"{nominal.name} has no distinct {' or '.join(missing)} configurations (the posture tests are zero "
            f"over its joint ranges): the configuration data's {', '.join(missing)} bits are kept as written "
            "and ask nothing",)


def _pose_groups(module, live, uses, tool: str | None, wobj: str | None, results) -> dict[tuple, list]:
    """The pose targets (with the expressions they are also reached through) by the (tool, work
    object) they move with, the command line's winning over the program's; a target whose frames
    are not known gets its result in ``results``."""
    groups: dict[tuple, list] = {}
    index = index_uses(module, uses)
    for t in live:
        if t.kind != "pose":
            continue
        f = frames_of(module, t, index)
        if f.unknown and not (tool and wobj):
            results[id(t)] = TargetResult(t.name, t.line, t.kind, f.unknown, through=f.through)
        else:
            groups.setdefault((tool or f.tool, wobj or f.wobj), []).append((t, f.through))
    return groups


def _flags(program: Program, rows) -> list[tuple[int, str]]:
    """The comments flagging the targets left unchanged, each where its target is written."""
    starts = [0] + [m.end() for m in re.finditer(r"\r\n|\r|\n", program.text)]
    return [(t.anchor if t.anchor >= 0 else starts[t.line - 1] + t.column - 1, f"{r.name}: {r.status}; left unchanged")
            for t, r in zip(program.targets, rows) if _is_flagged(r)]


def _joint_targets(program, nominal, calibrated, marker, joints, tol, tol_rot, edits, ranges) -> dict:
    """Compensate the joint targets; their results by ``id``."""
    q = joint_values(program, joints, nominal)
    comp = compensate(calibrated, q, nominal=nominal, marker=marker, ranges=ranges)
    status = _status(np.ones(len(q), dtype=bool), comp, tol, tol_rot)
    ok = np.array([s == REACHED for s in status])
    _joint_edits(program, nominal, [t for t, k in zip(joints, ok) if k], comp.q[ok], edits)
    a, b = evaluate(nominal, q, orientations=True), evaluate(nominal, comp.q, orientations=True)
    moved = np.linalg.norm(a.positions[:, marker] - b.positions[:, marker], axis=1)
    turned = _angle(a.rotations[:, marker], b.rotations[:, marker])
    ang, lin = _changes(nominal, q, comp.q)
    return {id(t): r for t, r in zip(joints, _results(nominal, joints, status, ok, comp, moved, turned, ang, lin))}


def _hints(program: Program, nominal: RobotModel, poses) -> np.ndarray:
    """Per pose target without configuration data, the readings of the joint target before it in the
    program (the controller's current joints), NaN where there is none."""
    out = np.full((len(poses), nominal.n_joints), np.nan)
    joints = [t for t in program.targets if t.kind == "joint" and not t.skip and len(t.joints) >= nominal.n_joints]
    if not joints:
        return out
    q = joint_values(program, joints, nominal)
    key = [(t.line, t.column) for t in joints]
    for i, t in enumerate(poses):
        k = bisect.bisect_left(key, (t.line, t.column)) - 1
        if not t.configuration and k >= 0:
            out[i] = q[k]
    return out
