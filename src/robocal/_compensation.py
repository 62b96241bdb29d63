"""Compensation: joint commands that put the real (identified) robot where the nominal one was asked to go."""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from ._kinematics import evaluate
from ._model import RobotModel
from ._parameters import parameter_layout, parameter_vector
from ._threads import one_blas_thread

log = logging.getLogger(__name__)


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
    ``residual_rot`` (N,) orientation error (rad, 0 where orientation was not matched) of the
    corrected poses against the targets; ``within_limits`` (N,) whether the corrected readings
    respect the joint limits; ``oriented`` (N,) whether each target's orientation was matched."""

    q: np.ndarray
    residual: np.ndarray
    residual_rot: np.ndarray
    within_limits: np.ndarray
    oriented: np.ndarray

    def reached(self, tol: float = 1e-6, tol_rot: float = 1e-6) -> np.ndarray:
        """(N,) whether each target was reached within ``tol`` (m) and ``tol_rot`` (rad)."""
        return (self.residual <= tol) & (self.residual_rot <= tol_rot)


def _targets(model, nominal, q0, positions, rotations, marker, orientation):
    """Target positions and rotations in W (N, 3), (N, 3, 3) and which rows match orientation."""
    target = evaluate(nominal, q0, orientations=True)
    Pt = target.positions[:, marker].copy()
    Rt = target.rotations[:, marker].copy()
    if orientation is None:
        orientation = model.n_joints >= 6
    oriented = np.full(len(q0), bool(orientation))
    if positions is not None:
        given = np.all(np.isfinite(positions), axis=1)
        Pt[given] = positions[given]
        oriented[given] = False
        if rotations is not None:
            rot_given = given & np.all(np.isfinite(rotations), axis=(1, 2))
            Rt[rot_given] = rotations[rot_given]
            oriented[rot_given] = True
    return Pt, Rt, oriented


def _errors(model, q, p, marker, Pt, Rt):
    ev = evaluate(model, q, p, orientations=True)
    e_pos = ev.positions[:, marker] - Pt
    e_rot = Rotation.from_matrix(ev.rotations[:, marker] @ np.swapaxes(Rt, -1, -2)).as_rotvec()
    return e_pos, e_rot


@one_blas_thread
def compensate(model: RobotModel, targets_q, *, nominal: RobotModel | None = None, positions=None,
               rotations=None, marker: int = 0, orientation: bool | None = None, iterations: int = 50,
               tol: float = 1e-10, damping: float = 1e-6, max_step: float = 0.05) -> Compensation:
    """Readings q' at which ``model`` reaches the pose ``nominal`` reaches at ``targets_q``.

    This is what a controller holding the nominal model needs to send to the identified robot.
    With six or more joints the full pose of ``marker`` is matched (``orientation`` default True),
    otherwise its position only (least-norm correction). ``positions`` (N, 3) and ``rotations``
    (N, 3, 3), W: Cartesian targets instead, where a row is finite; ``targets_q`` is then the
    starting guess (e.g. the nominal controller's inverse kinematics), and orientation is matched
    where a rotation is given. Damped least-squares steps (``damping`` in the Jacobian's units,
    each step at most ``max_step`` rad or m per joint), batched over poses. ``residual`` tells how
    well each target was reached: out of reach, or near a singularity where the exact pose would
    need a large joint motion, the damped step settles for the nearest pose instead.
    """
    q0 = np.atleast_2d(np.asarray(targets_q, dtype=float))
    nominal = model if nominal is None else nominal
    Pt, Rt, oriented = _targets(model, nominal, q0,
                                None if positions is None else np.asarray(positions, dtype=float).reshape(-1, 3),
                                None if rotations is None else np.asarray(rotations, dtype=float).reshape(-1, 3, 3),
                                marker, orientation)
    q = q0.copy()
    p = parameter_vector(model)
    for it in range(iterations):
        e_pos, e_rot = _errors(model, q, p, marker, Pt, Rt)
        e_rot[~oriented] = 0.0
        log.info("compensation step %d: largest position error %.3g m", it, np.max(np.linalg.norm(e_pos, axis=1)))
        if np.max(np.linalg.norm(e_pos, axis=1)) < tol and np.max(np.abs(e_rot)) < tol:
            break
        J = joint_jacobian(model, q)[:, marker].copy()
        J[~oriented, 3:] = 0.0          # position-only rows: the rotation rows ask nothing
        e = np.concatenate([e_pos, e_rot], axis=1)
        # damped least squares per pose: near a singularity (wrist aligned) an exact step would
        # swing the joints by radians for a micrometre; damping and a step bound keep it local
        JT = np.swapaxes(J, 1, 2)
        A = JT @ J + damping ** 2 * np.eye(J.shape[2])
        # pinv, not solve: where the damping is lost in round-off (joints that move the marker alike,
        # far from it) A is singular and solve raised LinAlgError for every pose
        step = (np.linalg.pinv(A, hermitian=True) @ np.einsum("nji,ni->nj", JT, e)[..., None])[..., 0]
        big = np.abs(step).max(axis=1, keepdims=True)
        q = q - step * np.minimum(1.0, max_step / np.maximum(big, 1e-300))
    e_pos, e_rot = _errors(model, q, p, marker, Pt, Rt)
    res_rot = np.where(oriented, np.linalg.norm(e_rot, axis=1), 0.0)
    inside = np.all((q >= model.lower_limits) & (q <= model.upper_limits), axis=1)
    return Compensation(q=q, residual=np.linalg.norm(e_pos, axis=1), residual_rot=res_rot, within_limits=inside,
                        oriented=oriented)
