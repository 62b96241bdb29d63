"""Choosing measurement configurations before the robot is touched (D- and I-optimal selection),
and what a campaign at chosen configurations will give (predicted standard deviations and errors)."""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from .._base.arguments import (
    FLAG,
    FRACTION,
    NAMES,
    POSITIVE,
    SEED,
    accepts,
    is_a,
    one_of,
    optional,
    readings_of,
    whole,
)
from .._base.errors import DegenerateDataError, InputError, check_choice
from .._base.options import MAX_POSES, MAX_SELECTION_BLOCKS, MAX_SELECTION_WORK, POSE_CRITERIA
from .._base.threads import one_blas_thread
from .._identification.estimates import weak_words
from .._identification.identifiability import (
    ONE_SIDE,
    identifiability,
    theoretical_identifiability,
    weakly_identifiable,
)
from .._identification.points import design_problem
from .._model.configurations import random_configurations
from .._model.parameters import has_backlash_parameters, parameter_layout, parameter_vector
from .._model.robot import RobotModel

log = logging.getLogger(__name__)


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
# what an operation of the selection's updates takes on one core, seconds (benchmarks/README.md), for messages
SECONDS_PER_OPERATION = 2e-10


class _Greedy:
    """The inverse of the scaled normal matrix M of a set of poses, kept up to date as poses come
    and go (rank-``rows`` Woodbury updates), with each candidate's ``H_i = B_i M^-1 B_i^T`` and,
    for the I criterion, ``F_i = B_i M^-1 W M^-1 B_i^T`` (rows x rows each): an update costs two
    products of all candidates' blocks with a (k, rows) matrix, a gain O(rows^3) per candidate."""

    def __init__(self, B: np.ndarray, W: np.ndarray, criterion: str, chosen):
        self.B, self.W, self.criterion = B, W, criterion
        self.flat = B.reshape(-1, B.shape[2])                               # (n_cand * rows, k)
        self.taken = np.zeros(len(B), dtype=bool)
        self.reset(chosen)

    def _sandwich(self, X: np.ndarray, Y: np.ndarray) -> np.ndarray:
        """(n_cand, rows, rows): X_i Y_i^T for per-candidate blocks given flat, (n_cand * rows, m)."""
        n, r = self.B.shape[:2]
        X, Y = X.reshape(n, r, -1), Y.reshape(n, r, -1)
        out = np.zeros((n, r, r))
        for t in range(X.shape[2]):     # m is small (rows): plain products beat a batched einsum
            out += X[:, :, None, t] * Y[:, None, :, t]
        return out

    def reset(self, chosen) -> None:
        """Recompute from scratch (also what keeps round-off of many updates in check)."""
        self.taken[:] = False
        self.taken[list(chosen)] = True
        Bc = self.B[self.taken].reshape(-1, self.B.shape[2])
        self.Minv = np.linalg.inv(Bc.T @ Bc + 1e-9 * np.eye(self.B.shape[2]))
        BM = self.flat @ self.Minv
        self.H = self._sandwich(BM, self.flat)
        self.F = self._sandwich(BM @ self.W, BM) if self.criterion == "I" else None

    def _update(self, i: int, sign: float) -> None:
        """M += sign * b^T b for candidate i's block b; H and F follow (Woodbury)."""
        b = self.B[i]
        u = b @ self.Minv                                                   # (rows, k)
        Sinv = np.linalg.inv(np.eye(len(b)) + sign * (u @ b.T))
        r = len(b)
        if self.F is None:
            C = self.flat @ u.T                                             # B_i M^-1 b^T, flat
        else:
            # one product gives C and D = B_i M^-1 W M^-1 b^T; then F_i += [C D] K [C D]^T with
            # K = [[E, -s S^-1], [-s S^-1, 0]], E = S^-1 u W u^T S^-1: the three terms of
            # (M^-1 - s u^T S^-1 u) W (...) in one product
            Z = self.flat @ np.hstack([u.T, self.Minv @ self.W @ u.T])
            C = Z[:, :r]
            K = np.zeros((2 * r, 2 * r))
            K[:r, :r] = Sinv @ (u @ self.W @ u.T) @ Sinv
            K[:r, r:] = K[r:, :r] = -sign * Sinv
            self.F = self.F + self._sandwich(Z @ K, Z)
        self.H = self.H - sign * self._sandwich(C @ Sinv, C)
        self.Minv = self.Minv - sign * (u.T @ Sinv @ u)
        self.taken[i] = sign > 0

    def state(self) -> tuple:
        return self.Minv, self.H, self.F, self.taken.copy()

    def restore(self, state: tuple) -> None:
        self.Minv, self.H, self.F, self.taken = state

    def add(self, i: int) -> None:
        self._update(i, 1.0)

    def remove(self, i: int) -> None:
        self._update(i, -1.0)

    def gains(self) -> np.ndarray:
        """Each candidate's gain if added: log det(I + H_i) (D), or the fall of tr(W M^-1),
        tr((I + H_i)^-1 F_i) (I); -inf for poses already taken."""
        S = self.H + np.eye(self.H.shape[1])
        F = self.F  # held for the I criterion only
        g = np.linalg.slogdet(S)[1] if F is None else np.einsum("nrs,nsr->n", _inverses(S), F)
        g[self.taken] = -np.inf
        return g


def _inverses(S: np.ndarray) -> np.ndarray:
    """Inverses of a stack of small matrices (n, r, r): 3x3 by cofactors (a batched LAPACK call per
    3x3 matrix costs more than the arithmetic), others by numpy."""
    if S.shape[1:] != (3, 3):
        return np.linalg.inv(S)
    a, b, c = S[:, 0, 0], S[:, 0, 1], S[:, 0, 2]
    d, e, f = S[:, 1, 0], S[:, 1, 1], S[:, 1, 2]
    g, h, i = S[:, 2, 0], S[:, 2, 1], S[:, 2, 2]
    cof = np.stack([e * i - f * h, c * h - b * i, b * f - c * e,
                    f * g - d * i, a * i - c * g, c * d - a * f,
                    d * h - e * g, b * g - a * h, a * e - b * d], axis=1).reshape(-1, 3, 3)
    det = a * cof[:, 0, 0] + b * cof[:, 1, 0] + c * cof[:, 2, 0]
    return cof / det[:, None, None]


def _scaled_blocks(model: RobotModel, q, names, orientation: bool, approach=None):
    """Each candidate's Jacobian block (n_cand, rows, k), columns scaled to unit norm over all
    candidates so that metres and radians weigh alike; and the design problem."""
    prob = design_problem(model, q, names, orientation, approach=approach)
    B = prob.pose_blocks(parameter_vector(model))
    col = np.linalg.norm(B, axis=(0, 1))
    col[col == 0] = 1.0
    return B / col, prob


def _check_cost(n: int, n_cand: int, rows: int, k: int, sweeps: int) -> None:
    """Refuse, before the work, a selection whose updates (each O(candidates x rows x k^2)) or whose
    candidate blocks would take minutes or gigabytes (MAX_SELECTION_WORK, MAX_SELECTION_BLOCKS)."""
    work = (1 + 2 * sweeps) * n * n_cand * rows * k * k
    if work > MAX_SELECTION_WORK or n_cand * rows * k > MAX_SELECTION_BLOCKS:
        raise InputError(f"choosing {n:,} poses among {n_cand:,} candidates for {k} parameters is about {work:.1e} "
                         f"operations on {n_cand * rows * k * 8 / 2 ** 20:,.0f} MB of candidate blocks; robocal "
                         f"selects up to {MAX_SELECTION_WORK:.0e} on {MAX_SELECTION_BLOCKS * 8 / 2 ** 20:,.0f} MB "
                         f"(about {MAX_SELECTION_WORK * SECONDS_PER_OPERATION:.0f} s): fewer poses or candidates",
                         where="n")


@accepts(model=is_a(RobotModel), n=whole(1, MAX_POSES), candidates=optional(readings_of()),
         n_candidates=whole(1, MAX_POSES), parameters=NAMES, known=NAMES, orientation=FLAG,
         criterion=one_of(POSE_CRITERIA), rng=SEED, sweeps=whole(0, 100))
@one_blas_thread
def select_poses(model: RobotModel, n: int, *, candidates=None, n_candidates: int = 2000, parameters=("geometric",),
                 known=(), orientation: bool = False, criterion: str = "I", rng=0, sweeps: int = 2) -> PoseSelection:
    """Pick ``n`` configurations for identifying the identifiable parameters.

    ``criterion="I"`` minimises the average prediction variance of the calibrated model over the
    candidate configurations, tr(W M^-1) with M = J^T J of the chosen poses and W = J^T J over
    all candidates / their count: what the held-out error after calibration depends on.
    ``criterion="D"`` maximises det(M). Columns are scaled to unit norm over the candidates, so
    metres and radians weigh alike. Greedy forward selection from a random start, then ``sweeps``
    passes of exchanges, every step a rank-``rows`` update of M^-1 evaluated over all candidates
    at once. ``candidates``: joint readings to choose from, default ``n_candidates`` drawn within
    the joint limits.

    Backlash needs both sides of each joint visited: under the gravity-sided model the side is the
    pose's (its load), so the criterion sees it; under the approach-sided model each candidate is
    given a random approach direction per joint, the criterion chooses among them, and the result
    says which direction to come from (``approach``).

    Parameters
    ----------
    {model}
    n : int
        Number of configurations to choose.
    {candidates, n_candidates, parameters, known}
    orientation : bool
        Whether orientations will be measured.
    {criterion, rng, sweeps}

    Returns
    -------
    PoseSelection
        The chosen configurations and what measuring there will give.
    """
    check_choice(criterion, CRITERIA, "criterion")
    rng = np.random.default_rng(rng)
    q = random_configurations(model, n_candidates, rng) if candidates is None else np.atleast_2d(candidates)
    if n > len(q):
        raise InputError(f"cannot choose {n} poses from {len(q)} candidates", where="n")
    names = identifiability(model, None, parameters=parameters, known=known, orientation=orientation,
                            rng=rng).identified
    _check_cost(n, len(q), len(model.markers) * (6 if orientation else 3), len(names), sweeps)
    approach = None
    if model.backlash_side == "approach" and has_backlash_parameters(model, names):
        approach = rng.choice([-1.0, 1.0], size=q.shape)
    B, prob = _scaled_blocks(model, q, names, orientation, approach)
    rows, k = B.shape[1], B.shape[2]
    if n * rows <= k:
        raise DegenerateDataError(f"{n} poses give {n * rows} equations for {k} identifiable parameters; at least "
                                  f"{k // rows + 1} poses are needed, and several times that for a useful estimate")
    W = np.einsum("pri,prj->ij", B, B) / len(q)
    chosen = [int(i) for i in rng.choice(len(q), size=min(n, max(1, k // rows + 1)), replace=False)]
    state = _Greedy(B, W, criterion, chosen)
    while len(chosen) < n:
        best = int(np.argmax(state.gains()))
        state.add(best)
        chosen.append(best)
    log.info("chose %d of %d poses (%s-optimal); exchanging", n, len(q), criterion)
    for _ in range(sweeps):
        state.reset(chosen)
        for pos in range(n):
            kept = state.state()
            state.remove(chosen[pos])
            best = int(np.argmax(state.gains()))   # the removed pose competes too: never worse
            if best == chosen[pos]:
                state.restore(kept)
            else:
                state.add(best)
                chosen[pos] = best
    chosen_arr = np.array(chosen)
    rand = rng.choice(len(q), size=n, replace=False)
    sides = prob.backlash_sides(parameter_vector(model))
    one_sided = tuple(nm for nm, sd in sides.items() if nm in names and
                      not (np.any(sd[chosen_arr] > ONE_SIDE) and np.any(sd[chosen_arr] < -ONE_SIDE)))
    return PoseSelection(q=q[chosen_arr], indices=chosen_arr, parameters=names, criterion=criterion,
                         approach=None if approach is None else approach[chosen_arr], one_sided=one_sided,
                         **_design_figures(B, W, chosen_arr, rand))


def _design_figures(B: np.ndarray, W: np.ndarray, chosen: np.ndarray, rand: np.ndarray) -> dict:
    k = B.shape[2]
    out = {}
    for label, idx in (("selected", chosen), ("random", rand)):
        A = B[idx].reshape(-1, k)
        M = A.T @ A + 1e-9 * np.eye(k)
        s = np.linalg.svd(A, compute_uv=False)
        out[f"log_det_{label}"] = float(np.linalg.slogdet(M)[1]) / len(idx)
        out[f"condition_{label}"] = float(s[0] / s[-1])
        out[f"prediction_{label}"] = float(np.trace(np.linalg.solve(M, W)))
    return out


@dataclass(frozen=True)
class CampaignPrediction:
    """What measuring at ``q`` will give, before anything is measured (SI).

    ``parameters``: the parameters identifiable from these poses, in preference order, with
    ``std`` their predicted standard deviations at position noise ``noise`` (m per axis);
    ``identifiability``: the analysis at these poses (what is eliminated, what absorbs it).
    ``error_rms``: the predicted RMS position error of the calibrated model over ``n_workspace``
    configurations within the joint limits (what parameter uncertainty leaves, the instrument's noise not counted);
    ``held_out_rms``: the RMS error a measurement at such a configuration would show against the
    calibrated model (the same plus the instrument's noise on that measurement). ``held``: the
    parameters these poses identify but cannot pin down at that noise, which the calibration holds
    at nominal (``weakly_identifiable``, its rule), each with its predicted standard deviation in
    words; they are not among ``parameters``, and the figures are those with them held. ``lost``:
    the parameters the robot's structure allows that these poses cannot separate (a joint that
    hardly moves among them), held at nominal: their errors are in no figure here."""

    q: np.ndarray
    parameters: tuple[str, ...]
    std: np.ndarray
    identifiability: object
    noise: float
    error_rms: float
    held_out_rms: float
    n_workspace: int
    held: tuple[tuple[str, str], ...] = ()
    lost: tuple[str, ...] = ()


@accepts(model=is_a(RobotModel), q=readings_of(), parameters=NAMES, known=NAMES, noise=POSITIVE,
         n_workspace=whole(1, MAX_POSES), tol=FRACTION, rng=SEED)
@one_blas_thread
def predict_campaign(model: RobotModel, q, *, parameters=("geometric",), known=(), noise: float = 2e-5,
                     n_workspace: int = 2000, tol: float = 1e-6, rng=0) -> CampaignPrediction:
    """Predicted standard deviations and post-calibration errors of a calibration at readings ``q``.

    The linearised model at the nominal values: the parameters identifiable at ``q`` get the
    covariance C = noise^2 (J^T J)^-1 of least squares with position noise ``noise`` (m, per
    axis), and a configuration p of the workspace the position error covariance J_p C J_p^T.

    Parameters
    ----------
    {model}
    q : array_like, shape (n_poses, n_joints)
        The configurations to measure at.
    {parameters, known}
    noise : float
        Position noise of the instrument, m per axis.
    {n_workspace}
    tol : float
        Rank tolerance relative to the largest singular value, in (0, 1).
    {rng}

    Returns
    -------
    CampaignPrediction
        The predicted standard deviations and errors of a campaign at ``q``.
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    if noise <= 0:
        raise InputError(f"noise must be positive, got {noise}", where="noise")
    ident = identifiability(model, q, parameters=parameters, known=known, tol=tol)
    names = ident.identified
    allowed = theoretical_identifiability(model, tuple(parameters), tuple(known), False, tol).identified
    lost = tuple(n for n in allowed if n not in set(names))
    p0 = parameter_vector(model)
    design = design_problem(model, q, names)
    J = design.jacobian(p0)
    held = _held_weak(model, design, J, names, noise, p0)
    if held:
        weak = {n for n, _ in held}
        keep = [k for k, n in enumerate(names) if n not in weak]
        names, J = tuple(names[k] for k in keep), J[:, keep]
    col = np.linalg.norm(J, axis=0)
    col[col == 0] = 1.0
    Ms = (J / col).T @ (J / col)
    cov = noise ** 2 * np.linalg.pinv(Ms, rcond=1e-15, hermitian=True) / np.outer(col, col)
    log.info("predicting %d parameters' uncertainty over %d configurations", len(names), n_workspace)
    work = random_configurations(model, n_workspace, np.random.default_rng(rng))
    Jw = design_problem(model, work, names).jacobian(p0)               # (n_workspace * markers * 3, k)
    per_point = np.einsum("ri,ij,rj->", Jw, cov, Jw) / (len(Jw) / 3)   # mean of tr(J_p C J_p^T)
    return CampaignPrediction(q=q, parameters=names, std=np.sqrt(np.diag(cov)), identifiability=ident,
                              noise=noise, error_rms=float(np.sqrt(per_point)),
                              held_out_rms=float(np.sqrt(per_point + 3 * noise ** 2)), n_workspace=n_workspace,
                              held=held, lost=lost)


def _held_weak(model: RobotModel, design, J: np.ndarray, names, noise: float, p0) -> tuple[tuple[str, str], ...]:
    """The identifiable ``names`` the calibration would hold at nominal at position noise ``noise``
    (its rule, ``weakly_identifiable``), in words; none when that would be every one."""
    lay = parameter_layout(model)
    quantities = [lay[n].quantity for n in names]
    moments = design.compliance_moments(p0) if "compliance" in quantities else None
    found = weakly_identifiable(J, names, quantities, noise, moments=moments)
    return weak_words(found, lay) if len(found) < len(names) else ()
