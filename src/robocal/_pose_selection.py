"""Choosing measurement configurations before the robot is touched (D-optimal selection)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._errors import DegenerateDataError, InputError, check_choice
from ._identifiability import ONE_SIDE, identifiability
from ._options import POSE_CRITERIA
from ._model import RobotModel
from ._parameters import has_backlash_parameters, parameter_vector
from ._problem import design_problem, random_configurations


@dataclass(frozen=True)
class PoseSelection:
    """Chosen configurations ``q`` (n, n_joints), their indices among the candidates, and how they
    compare with as many random candidates: log det of the scaled normal matrix per pose (higher
    is better), its condition number, and the average prediction variance over the candidates
    in units of the measurement variance (tr(W M^-1), lower is better).

    ``approach`` (n, n_joints): for an approach-sided backlash model, the direction (+1, -1) each
    joint must come from at each pose (end its move that way, past an overshoot); None otherwise.
    ``one_sided``: backlash parameters whose joint rests on one side at every chosen pose, which a
    joint offset then absorbs: those poses cannot identify them."""

    q: np.ndarray
    indices: np.ndarray
    parameters: tuple[str, ...]
    criterion: str
    log_det_random: float
    log_det_selected: float
    condition_random: float
    condition_selected: float
    prediction_random: float
    prediction_selected: float
    approach: np.ndarray | None = None
    one_sided: tuple[str, ...] = ()


CRITERIA = POSE_CRITERIA


def select_poses(model: RobotModel, n: int, *, candidates=None, n_candidates: int = 2000, parameters=("geometric",),
                 known=(), orientation: bool = False, criterion: str = "I", rng=0, sweeps: int = 2) -> PoseSelection:
    """Pick ``n`` configurations for identifying the identifiable parameters.

    ``criterion="I"`` minimises the average prediction variance of the calibrated model over the
    candidate configurations, tr(W M^-1) with M = J^T J of the chosen poses and W = J^T J over
    all candidates / their count: what the held-out error after calibration depends on.
    ``criterion="D"`` maximises det(M). Columns are scaled to unit norm over the candidates, so
    metres and radians weigh alike. Greedy forward selection (Woodbury updates) from a random
    start, then ``sweeps`` passes of exchanges. ``candidates``: joint readings to choose from,
    default ``n_candidates`` drawn within the joint limits.

    Backlash needs both sides of each joint visited: under the gravity-sided model the side is the
    pose's (its load), so the criterion sees it; under the approach-sided model each candidate is
    given a random approach direction per joint, the criterion chooses among them, and the result
    says which direction to come from (``approach``).
    """
    check_choice(criterion, CRITERIA, "criterion")
    rng = np.random.default_rng(rng)
    q = random_configurations(model, n_candidates, rng) if candidates is None else np.atleast_2d(candidates)
    if n > len(q):
        raise InputError(f"cannot choose {n} poses from {len(q)} candidates", where="n")
    names = identifiability(model, None, parameters=parameters, known=known, orientation=orientation,
                            rng=rng).identified
    approach = None
    if model.backlash_side == "approach" and has_backlash_parameters(model, names):
        approach = rng.choice([-1.0, 1.0], size=q.shape)
    prob = design_problem(model, q, names, orientation, approach=approach)
    B = prob.pose_blocks(parameter_vector(model))                                          # (n_cand, rows, k)
    k = B.shape[2]
    if n * B.shape[1] <= k:
        raise DegenerateDataError(f"{n} poses give {n * B.shape[1]} equations for {k} identifiable parameters")
    B = B / np.linalg.norm(B, axis=(0, 1))
    ridge = 1e-9 * np.eye(k)

    def logdet(idx):
        M = np.einsum("pri,prj->ij", B[idx], B[idx]) + ridge
        return np.linalg.slogdet(M)[1]

    Wbar = np.einsum("pri,prj->ij", B, B) / len(q)

    def gains(Minv, idx_pool):
        Bp = B[idx_pool]
        BM = np.einsum("pri,ij->prj", Bp, Minv)
        S = np.einsum("prj,psj->prs", BM, Bp) + np.eye(B.shape[1])       # I + Bi Minv Bi^T
        if criterion == "D":
            # det(M + Bi^T Bi) / det(M) = det(I + Bi Minv Bi^T)
            return np.linalg.slogdet(S)[1]
        # tr(W M^-1) falls by tr(S^-1 Bi G Bi^T) with G = Minv W Minv (Woodbury)
        G = Minv @ Wbar @ Minv
        BGB = np.einsum("pri,ij,psj->prs", Bp, G, Bp)
        return np.einsum("prr->p", np.linalg.solve(S, BGB))

    start = list(rng.choice(len(q), size=max(1, k // B.shape[1] + 1), replace=False))
    chosen = list(start)
    while len(chosen) < n:
        M = np.einsum("pri,prj->ij", B[chosen], B[chosen]) + ridge
        pool = np.setdiff1d(np.arange(len(q)), chosen)
        g = gains(np.linalg.inv(M), pool)
        chosen.append(int(pool[np.argmax(g)]))
    for _ in range(sweeps):
        for pos in range(n):
            rest = chosen[:pos] + chosen[pos + 1:]
            M = np.einsum("pri,prj->ij", B[rest], B[rest]) + ridge
            pool = np.setdiff1d(np.arange(len(q)), rest)
            g = gains(np.linalg.inv(M), pool)
            chosen[pos] = int(pool[np.argmax(g)])
    chosen_arr = np.array(chosen)
    rand = rng.choice(len(q), size=n, replace=False)

    def cond(idx):
        s = np.linalg.svd(B[idx].reshape(-1, k), compute_uv=False)
        return float(s[0] / s[-1])

    def prediction(idx):
        M = np.einsum("pri,prj->ij", B[idx], B[idx]) + ridge
        return float(np.trace(np.linalg.solve(M, Wbar)))

    sides = prob.backlash_sides(parameter_vector(model))
    one_sided = tuple(nm for nm, sd in sides.items() if nm in names and
                      not (np.any(sd[chosen_arr] > ONE_SIDE) and np.any(sd[chosen_arr] < -ONE_SIDE)))
    return PoseSelection(q=q[chosen_arr], indices=chosen_arr, parameters=names, criterion=criterion,
                         approach=None if approach is None else approach[chosen_arr], one_sided=one_sided,
                         log_det_random=float(logdet(rand)) / n, log_det_selected=float(logdet(chosen_arr)) / n,
                         condition_random=cond(rand), condition_selected=cond(chosen_arr),
                         prediction_random=prediction(rand), prediction_selected=prediction(chosen_arr))
