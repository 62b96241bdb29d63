"""Compensation: joint commands that put the real (identified) robot where the nominal one was asked to go."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from ._kinematics import evaluate
from ._model import RobotModel
from ._parameters import parameter_layout, parameter_vector
from ._threads import one_blas_thread


def joint_jacobian(model: RobotModel, q) -> np.ndarray:
    """d(marker pose)/d(joint readings): (N, n_markers, 6, n_joints) in W (rows dx, dy, dz, rotation)."""
    lay = parameter_layout(model)
    cols = [lay[f"{f.name}.{'r' if f.joint == 'prismatic' else 'theta'}"].index for f in model.frames]
    ev = evaluate(model, q, jacobian=True, columns=cols)
    moving = np.array([f.joint != "fixed" for f in model.frames])
    Jf = np.where(moving, ev.jacobian, 0.0)                     # per frame variable
    return Jf @ model.coupling_matrix


@dataclass(frozen=True)
class Compensation:
    """``q`` (N, n_joints) corrected readings; ``residual`` (N,) remaining position error (m) and
    ``residual_rot`` (N,) orientation error (rad) of the corrected poses against the targets;
    ``within_limits`` (N,) whether the corrected readings respect the joint limits."""

    q: np.ndarray
    residual: np.ndarray
    residual_rot: np.ndarray
    within_limits: np.ndarray


@one_blas_thread
def compensate(model: RobotModel, targets_q, *, nominal: RobotModel | None = None, marker: int = 0,
               orientation: bool | None = None, iterations: int = 20, tol: float = 1e-10,
               damping: float = 1e-6, max_step: float = 0.05) -> Compensation:
    """Readings q' at which ``model`` reaches the pose ``nominal`` reaches at ``targets_q``.

    This is what a controller holding the nominal model needs to send to the identified robot.
    With six or more joints the full pose of ``marker`` is matched (``orientation`` default True),
    otherwise its position only (least-norm correction). Damped least-squares steps (``damping``
    in the Jacobian's units, each step at most ``max_step`` rad or m per joint), batched over
    poses. ``residual`` tells how well each target was reached: near a singularity the robot may
    not reach the exact nominal pose without a large joint motion, and the damped step settles
    for the nearest pose instead.
    """
    q0 = np.atleast_2d(np.asarray(targets_q, dtype=float))
    nominal = model if nominal is None else nominal
    if orientation is None:
        orientation = model.n_joints >= 6
    target = evaluate(nominal, q0, orientations=True)
    Pt = target.positions[:, marker]
    Rt = target.rotations[:, marker]
    q = q0.copy()
    p = parameter_vector(model)
    for _ in range(iterations):
        ev = evaluate(model, q, p, orientations=True)
        e_pos = ev.positions[:, marker] - Pt
        e_rot = Rotation.from_matrix(ev.rotations[:, marker] @ np.swapaxes(Rt, -1, -2)).as_rotvec()
        if np.max(np.linalg.norm(e_pos, axis=1)) < tol and (not orientation or np.max(np.abs(e_rot)) < tol):
            break
        J = joint_jacobian(model, q)[:, marker]
        if orientation:
            e = np.concatenate([e_pos, e_rot], axis=1)
        else:
            e = e_pos
            J = J[:, :3]
        # damped least squares per pose: near a singularity (wrist aligned) an exact step would
        # swing the joints by radians for a micrometre; damping and a step bound keep it local
        JT = np.swapaxes(J, 1, 2)
        A = JT @ J + damping ** 2 * np.eye(J.shape[2])
        step = np.linalg.solve(A, np.einsum("nji,ni->nj", JT, e)[..., None])[..., 0]
        big = np.abs(step).max(axis=1, keepdims=True)
        q = q - step * np.minimum(1.0, max_step / np.maximum(big, 1e-300))
    ev = evaluate(model, q, p, orientations=True)
    res = np.linalg.norm(ev.positions[:, marker] - Pt, axis=1)
    res_rot = np.linalg.norm(Rotation.from_matrix(ev.rotations[:, marker] @ np.swapaxes(Rt, -1, -2)).as_rotvec(), axis=1)
    inside = np.all((q >= model.lower_limits) & (q <= model.upper_limits), axis=1)
    return Compensation(q=q, residual=res, residual_rot=res_rot, within_limits=inside)
