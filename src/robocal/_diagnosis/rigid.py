"""Cheap rigid matches: how well the nominal robot, moved rigidly, matches measured points, from
sums of the closed-form registration's statistics (docs/diagnosis.md). What chooses, among the
discrete repairs of a hypothesis (which rows, axes, joints, unit), the one to refit, and predicts
whether refitting it is worth it."""

from __future__ import annotations

import numpy as np

from .._model.kinematics import evaluate
from .._model.measurements import Measurements
from .._model.robot import RobotModel
from .reference import SCREEN_POSES, Reference, nominal_positions, working_rows

# the nominal robot's rigid match misses the measured points by more than this share of their spread
# only when the data hold a gross mistake (a joint's sign or unit, swapped columns, shifted rows): real
# robots' nominal models miss by 0.3 % (a UR5) to 2 % (a cable-driven arm); below it the discrete
# hypotheses are ruled out without a match
GROSS_SHARE = 0.01


def moments(P: np.ndarray, Q: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """(n, 18) per row the sufficient statistics of a rigid match of points ``P`` to ``Q`` (n, m, 3)
    over the markers ``mask`` (n, m): count, sums of P and Q, sums of squares, sum of P Q^T."""
    w = mask.astype(float)[..., None]
    P, Q = np.where(w > 0, P, 0.0), np.where(w > 0, Q, 0.0)
    return np.concatenate([w[..., 0].sum(1)[:, None], P.sum(1), Q.sum(1), (P ** 2).sum((1, 2))[:, None],
                           (Q ** 2).sum((1, 2))[:, None], np.einsum("nmi,nmj->nij", P, Q).reshape(len(P), 9)], axis=1)


def rigid_misfit(summed: np.ndarray) -> np.ndarray:
    """Sum of squared distances left by the best rigid motion of P onto Q, from summed ``moments``
    (..., 18); infinite with fewer than three points."""
    c, sp, sq = summed[..., 0], summed[..., 1:4], summed[..., 4:7]
    cs = np.maximum(c, 1.0)[..., None]
    H = summed[..., 9:].reshape(summed.shape[:-1] + (3, 3)) - sp[..., :, None] * sq[..., None, :] / cs[..., None]
    s = np.linalg.svd(H, compute_uv=False)
    sign = np.sign(np.linalg.det(H))
    spread = summed[..., 7] - np.sum(sp ** 2, -1) / cs[..., 0] + summed[..., 8] - np.sum(sq ** 2, -1) / cs[..., 0]
    out = spread - 2.0 * (s[..., 0] + s[..., 1] + np.where(sign < 0, -1.0, 1.0) * s[..., 2])
    return np.where(c >= 3, np.maximum(out, 0.0), np.inf)


def per_point(P: np.ndarray, data: Measurements) -> float:
    """The mean squared distance per point left by the best rigid motion of ``P`` onto ``data``."""
    m = moments(P, data.positions, data.mask).sum(0)
    return float(rigid_misfit(m)) / max(float(m[0]), 1.0)


def screen_data(ref: Reference) -> Measurements:
    """The poses the rigid matches look at (at most ``SCREEN_POSES`` of the poses diagnosed)."""
    return ref.cached("screen_data", lambda: ref.data.subset(working_rows(ref.data.n_poses, SCREEN_POSES)))


def screen_positions(ref: Reference) -> np.ndarray:
    """The nominal robot's positions at the screened poses."""
    return ref.cached("screen_positions", lambda: nominal_positions(ref.model, screen_data(ref)))


def plain(ref: Reference) -> float:
    """The nominal robot's rigid misfit per point on the screened poses, the data as they are."""
    return ref.cached("plain", lambda: per_point(screen_positions(ref), screen_data(ref)))


def gross(ref: Reference) -> bool:
    """Whether a gross mistake can be in the data: the calibration found points beyond the outlier bar,
    or the nominal robot's rigid match leaves more than ``GROSS_SHARE`` of the measured cloud's spread
    and the calibration shows a mistake (``Reference.shows``). A calibration that fits with plausible
    changes holds no sign, swap, unit or shift: the nominal robot is merely far from the real one."""
    def make():
        if any(c.name == "outliers" and c.items for c in ref.result.checks):
            return True
        if not ref.shows:
            return False
        d = screen_data(ref)
        X = d.positions[d.mask]
        spread = float(np.sqrt(np.mean(np.sum((X - X.mean(0)) ** 2, axis=1)))) if len(X) else 0.0
        return bool(np.sqrt(plain(ref)) > GROSS_SHARE * spread)

    return ref.cached("gross", make)


def predicted(ref: Reference, misfit: float, scale: float = 1.0) -> float:
    """The factor a change is predicted to divide the residual variance by: the nominal robot's rigid
    misfit on the data as they are over that on the changed data (in the data's unit: ``scale``)."""
    return plain(ref) / max(misfit * scale ** 2, 1e-300)


def screened_data(ref: Reference, changed: Measurements) -> float:
    """The nominal robot's rigid misfit per point on ``changed`` (the screened poses changed), at the
    readings it holds."""
    P = screen_positions(ref) if np.array_equal(changed.q, screen_data(ref).q) else \
        nominal_positions(ref.model, changed)
    return per_point(P, changed)


def screened_model(ref: Reference, model: RobotModel) -> float:
    """``model``'s rigid misfit per point on the screened poses."""
    return per_point(nominal_positions(model, screen_data(ref)), screen_data(ref))


def screened_readings(ref: Reference, readings: list[np.ndarray]) -> np.ndarray:
    """The nominal robot's rigid misfit per point on the screened poses at each of ``readings`` (each
    (n_screened, n_joints)): one evaluation of them all."""
    d = screen_data(ref)
    n = d.n_poses
    load = None if d.payload_mass is None else np.tile(d.payload_mass, len(readings))
    ev = evaluate(ref.model, np.vstack(readings), payload_mass=load)
    P = ev.positions[:, [ref.model.marker_names.index(m) for m in d.marker_names]]
    return np.array([per_point(P[k * n:(k + 1) * n], d) for k in range(len(readings))])


def registered(P: np.ndarray, Q: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """``P`` (n, m, 3) moved by the rigid motion that best matches its points ``mask`` onto ``Q``'s
    (Kabsch)."""
    a, b = P[mask], Q[mask]
    ca, cb = a.mean(0), b.mean(0)
    U, _, Vt = np.linalg.svd((a - ca).T @ (b - cb))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    R = (U @ D @ Vt).T
    return (P - ca) @ R.T + cb
