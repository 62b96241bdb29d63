"""Small rigid-body helpers on plain numpy arrays: elementary rotations, 4x4 placements, angle sets.

Rotations are active and compose by right-multiplication (``R @ Rot(x, a)`` turns about the
rotated x axis), as in docs/conventions.md.
"""

from __future__ import annotations

import math

import numpy as np


def rot_matrix(axis: int, angle: float) -> np.ndarray:
    """Rot(axis, angle) as a 3x3 matrix, ``axis`` 0, 1 or 2 for x, y, z.

    >>> rot_matrix(2, np.pi / 2).round(12) @ [1.0, 0.0, 0.0]
    array([0., 1., 0.])
    """
    c, s = np.cos(angle), np.sin(angle)
    if axis == 0:
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == 1:
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def rot4(axis: int, angle: float) -> np.ndarray:
    """Rot(axis, angle) as a 4x4 placement."""
    X = np.eye(4)
    X[:3, :3] = rot_matrix(axis, angle)
    return X


def trans4(axis: int, dist: float) -> np.ndarray:
    """Trans(axis, dist) as a 4x4 placement."""
    X = np.eye(4)
    X[axis, 3] = dist
    return X


def pose4(R, p) -> np.ndarray:
    """The 4x4 placement with rotation ``R`` (3x3) and translation ``p`` (3,)."""
    X = np.eye(4)
    X[:3, :3] = R
    X[:3, 3] = p
    return X


def inverse4(X: np.ndarray) -> np.ndarray:
    """The inverse of a 4x4 rigid placement."""
    R, p = X[:3, :3], X[:3, 3]
    return pose4(R.T, -R.T @ p)


def small_rotation(rx: float, ry: float, rz: float) -> np.ndarray:
    """The rotation by the rotation vector (rx, ry, rz) (axis times angle, Rodrigues): the rotation
    corrections of the base and the markers. A rotation vector has no gimbal lock: a tool turned
    120 deg from its guess is 120 deg about one axis, however that axis lies.

    >>> small_rotation(0.0, 0.0, np.pi / 2).round(12) @ [1.0, 0.0, 0.0]
    array([0., 1., 0.])
    """
    v = np.array([rx, ry, rz], dtype=float)
    angle = float(np.linalg.norm(v))
    return np.eye(3) if angle == 0.0 else axis_angle_matrix(v / angle, angle)


def rotation_vector(R: np.ndarray) -> np.ndarray:
    """The rotation vector (axis times angle, angle in [0, pi]) of ``R``, the inverse of ``small_rotation``."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(R).as_rotvec()


def left_jacobian(v) -> np.ndarray:
    """J with small_rotation(v + dv) = small_rotation(J dv) small_rotation(v) to first order: the
    columns are the axes (in the rotated frame's parent) about which each component of v turns."""
    v = np.asarray(v, dtype=float)
    angle = float(np.linalg.norm(v))
    K = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    if angle < 1e-8:
        return np.eye(3) + 0.5 * K
    return (np.eye(3) + (1 - math.cos(angle)) / angle ** 2 * K
            + (angle - math.sin(angle)) / angle ** 3 * K @ K)


def rpy_matrix(rpy) -> np.ndarray:
    """Fixed-axis roll, pitch, yaw (URDF's rule): R = Rot(z, yaw) Rot(y, pitch) Rot(x, roll)."""
    roll, pitch, yaw = rpy
    return rot_matrix(2, yaw) @ rot_matrix(1, pitch) @ rot_matrix(0, roll)


def matrix_rpy(R: np.ndarray) -> tuple[float, float, float]:
    """Inverse of ``rpy_matrix``, stable through gimbal lock.

    Yaw first, then roll and pitch from ``Rot(z, -yaw) R``: near pitch = +-pi/2 a poor yaw is
    absorbed by roll, so the rebuilt matrix stays accurate to rounding (separate atan2s would not).
    """
    yaw = math.atan2(R[1, 0], R[0, 0]) if math.hypot(R[1, 0], R[0, 0]) > 1e-300 else 0.0
    M = rot_matrix(2, -yaw) @ R
    roll = math.atan2(-M[1, 2], M[1, 1])
    pitch = math.atan2(-M[2, 0], M[0, 0])
    return roll, pitch, yaw


def axis_angle_matrix(k: np.ndarray, angle: float) -> np.ndarray:
    """Rotation by ``angle`` about the unit axis ``k`` (Rodrigues)."""
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def nearest_rotation(M) -> tuple[np.ndarray, float]:
    """The rotation nearest ``M`` (3x3, Frobenius norm: U V^T of its SVD) and the largest entry
    change that takes ``M`` there; a reflection (det < 0) comes back with det -1 for the caller to refuse.

    >>> R, dev = nearest_rotation([[0.866, -0.5, 0], [0.5, 0.866, 0], [0, 0, 1]])
    >>> bool(np.allclose(R @ R.T, np.eye(3))), bool(1e-5 < dev < 1e-4)
    (True, True)
    """
    M = np.asarray(M, dtype=float)
    U, _, Vt = np.linalg.svd(M)
    R = U @ Vt
    return R, float(np.abs(R - M).max())


def unit_vector(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def vector3(v) -> tuple[float, float, float]:
    """The three components of ``v`` as a tuple of floats (a record's point or direction).

    >>> vector3(np.array([1, 2, 3]))
    (1.0, 2.0, 3.0)
    """
    x, y, z = (float(c) for c in v)
    return x, y, z


def matrix_tuple(R) -> tuple:
    """A 3x3 matrix as the nested tuple of floats the frozen model records hold."""
    return tuple(tuple(float(v) for v in row) for row in R)


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product over the last axis; numpy's own is several times slower on small vectors."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)
