"""The least-squares solve of a calibration problem, and the covariance of its estimates.

Calibration and the benchmarks call the same ``solve``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from .._base.arguments import (
    FRACTION,
    POSITIVE,
    accepts,
    is_a,
    one_of,
    optional,
    shaped,
    whole,
)
from .._base.errors import DegenerateDataError, InputError
from .._base.linalg import reduced, solve_upper
from .._base.options import LOSSES
from .._base.threads import one_blas_thread
from .._model.kinematics import LARGE_POSES
from .identifiability import singular_values
from .problem import Problem

# step, cost and gradient tolerances (ours and least_squares'): Gauss-Newton converges quadratically
# here, so the step that meets them leaves an error far below them (noise-free recovery is ~1e-16)
SOLVER_TOL = 1e-10
# a robust loss bends at this many robust standard deviations of the residuals
ROBUST_SCALE_SIGMAS = 3.0


@dataclass(frozen=True, eq=False)
class Solution:
    """Where the solver stopped: the full parameter vector ``p``, the weighted residuals and the
    weighted Jacobian there, (n_rows, n_free), or for a linear fit of one kind of row its R factor
    (n_free, n_free), which has the same Gram matrix; and the solver's own account (``status`` > 0
    is convergence, as in scipy). ``f_scale`` is where a robust loss bent (None for ``linear``).
    ``jacobian_at``: the full vector the Jacobian was taken at, when not ``p`` (Levenberg-Marquardt
    takes it at the start of its last step, within the tolerances of ``p``)."""

    p: np.ndarray
    residuals: np.ndarray
    jacobian: np.ndarray
    success: bool
    status: int
    message: str
    nfev: int
    loss: str
    f_scale: float | None
    row_kinds: np.ndarray | None = None
    linear_rows: np.ndarray | None = None
    jacobian_at: np.ndarray | None = None


@accepts(problem=is_a(Problem), p0=shaped(None), loss=one_of(LOSSES), f_scale=optional(POSITIVE),
         max_nfev=optional(whole(1)), lower=optional(shaped(None, finite=False)), tol=FRACTION,
         linear_rows=optional(shaped(None)))
@one_blas_thread
def solve(problem: Problem, p0: np.ndarray, *, loss: str = "linear", f_scale: float | None = None,
          max_nfev: int | None = None, lower: np.ndarray | None = None, tol: float = SOLVER_TOL,
          linear_rows: np.ndarray | None = None) -> Solution:
    """Minimise the problem's residuals over its free parameters, starting from ``p0`` (full vector).

    ``loss="linear"`` is Levenberg-Marquardt on the normal equations with the analytic Jacobian
    (``_levenberg_marquardt``). A robust loss runs scipy's trust-region solver; without ``f_scale``
    it bends at ``ROBUST_SCALE_SIGMAS`` robust standard deviations (median absolute deviation)
    of the residuals, re-estimated from the robust fit until it settles: the first, non-robust fit
    spreads outliers over every residual. ``lower`` (n_free,): lower bounds (-inf for none), which
    need the trust-region solver. ``tol``: the step, cost and gradient tolerances. ``linear_rows``
    (n_rows,): rows a robust loss leaves linear (``carried_alone``: rows that alone carry a
    quantity, which no other row can outvote).

    Parameters
    ----------
    {problem, p0}
    loss : str
        ``linear`` (Levenberg-Marquardt) or a robust loss (``soft_l1``, ``huber``, ``cauchy``,
        ``arctan``).
    {f_scale, max_nfev, lower}
    tol : float
        Step, cost and gradient tolerance, in (0, 1).
    linear_rows : array_like, optional
        (n_rows,) true for the rows a robust loss leaves linear.

    Returns
    -------
    Solution
        The estimate, residuals, cost and solver status.
    """
    bounded = lower is not None and bool(np.any(np.isfinite(lower)))
    if loss == "linear" and not bounded:
        return _levenberg_marquardt(problem, p0, max_nfev, tol)
    if problem.chunked:
        raise InputError(f"a campaign of over {LARGE_POSES} poses is solved in chunks, with the linear loss and "
                         "without bounds only")
    keep = None if linear_rows is None or loss == "linear" else np.asarray(linear_rows, dtype=float) > 0
    return _trust_region(problem, p0, loss, f_scale, max_nfev, lower if bounded else None, tol, keep)


def partly_robust(loss: str, keep: np.ndarray):
    """scipy's callable form of ``loss`` (rho(z), rho'(z), rho''(z) of z = r^2, scipy's
    definitions) with the rows ``keep`` left linear (rho(z) = z at every scale)."""
    def rho(z):
        out = np.vstack(_ROBUST_RHO[loss](z))
        out[0, keep], out[1, keep], out[2, keep] = z[keep], 1.0, 0.0
        return out
    return rho


def _huber(z):
    big = z > 1.0
    s = np.sqrt(np.where(big, z, 1.0))
    return np.where(big, 2.0 * s - 1.0, z), np.where(big, 1.0 / s, 1.0), np.where(big, -0.5 / s ** 3, 0.0)


_ROBUST_RHO = {"soft_l1": lambda z: (2.0 * (np.sqrt(1.0 + z) - 1.0), (1.0 + z) ** -0.5, -0.5 * (1.0 + z) ** -1.5),
               "huber": _huber,
               "cauchy": lambda z: (np.log1p(z), 1.0 / (1.0 + z), -1.0 / (1.0 + z) ** 2),
               "arctan": lambda z: (np.arctan(z), 1.0 / (1.0 + z ** 2), -2.0 * z / (1.0 + z ** 2) ** 2)}


def _trust_region(problem: Problem, p0: np.ndarray, loss: str, f_scale, max_nfev, lower, tol: float,
                  keep: np.ndarray | None = None) -> Solution:
    """scipy's solvers, for a robust loss or bounds; ``keep``: rows the robust loss leaves linear."""
    x0 = p0[problem.free_idx]
    robust = loss if keep is None or loss == "linear" else partly_robust(loss, keep)

    def fun(x):
        return problem.residuals(problem.full(x, p0))

    def jac(x):
        return problem.jacobian(problem.full(x, p0))

    kw = dict(jac=jac, x_scale="jac", xtol=tol, ftol=tol, gtol=tol, max_nfev=max_nfev)
    if lower is not None:
        x0 = np.maximum(x0, lower)
        kw["bounds"] = (lower, np.full(len(x0), np.inf))
    if loss == "linear" or f_scale is not None:
        sol = least_squares(fun, x0, method="trf", loss=robust, f_scale=f_scale or 1.0, **kw)
    else:
        sol = least_squares(fun, x0, method="trf" if lower is not None else "lm", **kw)
        for _ in range(6):
            mad = 1.4826 * float(np.median(np.abs(sol.fun - np.median(sol.fun))))
            new_scale = max(ROBUST_SCALE_SIGMAS * mad, 1e-12)
            if sol.status == 0:     # stopped at its evaluation limit: fitting again from there crawls on
                f_scale = new_scale if f_scale is None else f_scale
                break
            if f_scale is not None and abs(new_scale - f_scale) < 0.05 * f_scale:
                break
            f_scale = new_scale
            sol = least_squares(fun, sol.x, method="trf", loss=robust, f_scale=f_scale, **kw)
    p = problem.full(sol.x, p0)
    return Solution(p=p, residuals=problem.residuals(p), jacobian=problem.jacobian(p), success=bool(sol.status > 0),
                    status=int(sol.status), message=str(sol.message), nfev=int(sol.nfev), loss=loss,
                    f_scale=None if loss == "linear" else float(f_scale), row_kinds=problem.row_kinds(),
                    linear_rows=keep)


@dataclass(frozen=True, eq=False)
class _Normal:
    """The normal equations at one point: the R factor of the weighted Jacobian (``R^T R = J^T J``),
    the gradient ``J^T r``, the sum of squares, and the Jacobian itself when it was formed whole."""

    R: np.ndarray
    g: np.ndarray
    cost: float
    J: np.ndarray | None
    r: np.ndarray | None


def _normal_equations(problem, p: np.ndarray, r: np.ndarray | None = None) -> _Normal:
    """At ``p`` (``r``: the residuals there, when known): chunk by chunk for a large campaign, else
    from the Jacobian formed whole (its R factor through the Gram matrix when well conditioned,
    ``r_factor``)."""
    if problem.chunked:
        R, g, cost = problem.normal_equations(p)
        return _Normal(R=R, g=g, cost=cost, J=None, r=r)
    J = problem.jacobian(p)
    r = problem.residuals(p) if r is None else r
    R = problem.jacobian_factor(p)
    return _Normal(R=R, g=J.T @ r, cost=float(r @ r), J=J, r=r)


def _step(R: np.ndarray, g: np.ndarray, D: np.ndarray, lam: float) -> np.ndarray:
    """The step solving ``(R^T R + lam D^2) dx = -g``; Gauss-Newton for ``lam = 0``."""
    A = R if lam == 0.0 else reduced(np.vstack([R, np.sqrt(lam) * np.diag(D)]))
    return -solve_upper(A, solve_upper(A, g, transposed=True))


_MESSAGES = {0: "the maximum number of function evaluations is exceeded",
             1: "the gradient is orthogonal to the residuals within gtol",
             2: "the relative reduction of the sum of squares is below ftol",
             3: "the relative step is below xtol",
             4: "the relative step is below xtol and the reduction of the sum of squares below ftol"}


def _levenberg_marquardt(problem, p0: np.ndarray, max_nfev: int | None, tol: float = SOLVER_TOL) -> Solution:
    """Levenberg-Marquardt on the normal equations (``_Normal``), chunk by chunk for a large campaign.

    Each step solves ``(R^T R + lam D^2) dx = -J^T r``, D the largest column norms of the Jacobian
    met so far (MINPACK's scaling, scipy's ``x_scale="jac"``); ``lam`` starts at 0 (Gauss-Newton)
    and grows tenfold while a step fails to reduce the sum of squares. MINPACK's tests at ``tol``:
    the fit has converged when the gradient is orthogonal to the residuals, or with the step that
    is below xtol relative to the parameters, promises (linear model) or gives less than ftol of
    the sum of squares. That last step is taken and its residuals evaluated, but no Jacobian at its
    end: ``jacobian`` of the solution (the R factor, or the Jacobian itself when rows of several
    kinds need it, see ``covariance``) is taken at its start, which differs from the solution by
    less than the tolerances.
    """
    x = p0[problem.free_idx].astype(float)
    k = len(x)
    max_nfev = 100 * (k + 1) if max_nfev is None else max_nfev
    ne = _normal_equations(problem, p0)
    nfev, lam, status, r_end = 1, 0.0, 0, None
    D = np.zeros(k)
    while True:
        D = np.maximum(D, np.linalg.norm(ne.R, axis=0))
        scale = np.where(D > 0, D, 1.0)
        if ne.cost == 0.0 or np.max(np.abs(ne.g) / (scale * np.sqrt(ne.cost))) <= tol:
            status = 1
            break
        if nfev >= max_nfev:
            break
        dx = _step(ne.R, ne.g, scale, lam)
        if not np.all(np.isfinite(dx)):      # a singular factor: damp until the step exists
            lam = max(10.0 * lam, 1e-3)
            continue
        r_new = problem.residuals(problem.full(x + dx, p0))
        nfev += 1
        cost_new = float(r_new @ r_new)
        status = _last_step(ne, x, dx, scale, cost_new, tol)
        if status:
            at = problem.full(x, p0)     # where ne was taken
            if cost_new <= ne.cost:      # else x is the minimum to round-off
                x, r_end = x + dx, r_new
            return _lm_solution(problem, problem.full(x, p0), ne, r_end, status, nfev, at)
        if not cost_new <= ne.cost:
            lam = max(10.0 * lam, 1e-3)
            continue
        x, ne = x + dx, _normal_equations(problem, problem.full(x + dx, p0), r_new)
        lam = lam / 10.0 if lam > 1e-12 else 0.0
    return _lm_solution(problem, problem.full(x, p0), ne, r_end, status, nfev)


def _last_step(ne: _Normal, x: np.ndarray, dx: np.ndarray, scale: np.ndarray, cost_new: float, tol: float) -> int:
    """The status (``_MESSAGES``) when the step ``dx`` from ``x``, giving the sum of squares
    ``cost_new``, ends the fit (MINPACK's xtol and ftol tests); 0 when the fit goes on."""
    small_step = np.linalg.norm(scale * dx) <= tol * (tol + np.linalg.norm(scale * x))
    little_promised = -(2.0 * float(ne.g @ dx) + float(np.sum((ne.R @ dx) ** 2))) <= tol * ne.cost
    if small_step or little_promised or (cost_new <= ne.cost and ne.cost - cost_new <= tol * ne.cost):
        return 4 if small_step and little_promised else (3 if small_step else 2)
    return 0


def _lm_solution(problem, p: np.ndarray, ne: _Normal, r_end: np.ndarray | None, status: int, nfev: int,
                 at: np.ndarray | None = None) -> Solution:
    """The solution at ``p``: its residuals ``r_end`` when the last step evaluated them, else those
    of ``ne`` (the normal equations there, at ``at`` when not ``p``), and the Jacobian (or its R
    factor) of ``ne``."""
    kinds = problem.row_kinds()
    several = kinds is not None and len(kinds) > 0 and kinds.min() != kinds.max()
    r = r_end if r_end is not None else (ne.r if ne.r is not None else problem.residuals(p))
    return Solution(p=p, residuals=r, jacobian=ne.J if several and ne.J is not None else ne.R,
                    success=status > 0, status=status, message=_MESSAGES[status], nfev=nfev, loss="linear",
                    f_scale=None, row_kinds=kinds if several else None,
                    jacobian_at=None if at is None or np.array_equal(at, p) else at)


# a row whose leverage exceeds this carries a direction of the parameters (almost) alone: the other
# rows determine less than 1 % of its fitted value, so they cannot outvote it
CARRIED_ALONE = 0.99


def carried_alone(jacobian: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
    """Whether each row of the weighted Jacobian (n_rows, n_free) carries some direction of the
    parameters alone: its leverage (the diagonal of the hat matrix ``J (J^T J)^-1 J^T``, taken in
    unit-column scaling over the directions the rows determine) exceeds ``CARRIED_ALONE``. The only
    known distance fixing the scale, the only rows fixing a plane's offset: a robust loss must not
    set them aside, for nothing else would fix what they fix. ``rows`` (n_rows,) bool: only those
    rows are judged (the result has one entry per row judged)."""
    J = np.asarray(jacobian, dtype=float)
    col = np.linalg.norm(J, axis=0)
    col[col == 0] = 1.0
    A = J / col
    w, V = np.linalg.eigh(A.T @ A)
    keep = w > max(float(w.max()), 0.0) * 1e-20 if w.size else np.zeros(0, dtype=bool)
    B = (A if rows is None else A[rows]) @ V[:, keep]
    return np.sum(B ** 2 / w[keep], axis=1) > CARRIED_ALONE


@dataclass(frozen=True, eq=False)
class Covariance:
    """Covariance of the free parameters (SI), their standard deviations and correlations, and the
    residual variance factor ``s2`` (sum of squared weighted residuals over the degrees of freedom)."""

    covariance: np.ndarray
    std: np.ndarray
    correlation: np.ndarray
    s2: float
    dof: float


def robust_weights(residuals: np.ndarray, loss: str, f_scale: float) -> np.ndarray:
    """Each residual's weight rho'(z), z = (r / f_scale)^2, in the loss' own normalisation
    (scipy's definitions): 1 for small residuals, falling for outliers."""
    z = (np.asarray(residuals) / f_scale) ** 2
    if loss == "soft_l1":
        return 1.0 / np.sqrt(1.0 + z)
    if loss == "huber":
        return np.where(z <= 1.0, 1.0, 1.0 / np.sqrt(np.maximum(z, 1.0)))
    if loss == "cauchy":
        return 1.0 / (1.0 + z)
    if loss == "arctan":
        return 1.0 / (1.0 + z ** 2)
    return np.ones_like(z)


@accepts(solution=is_a(Solution))
@one_blas_thread
def covariance(solution: Solution) -> Covariance:
    """The estimates' covariance at the solution.

    One kind of row: s2 (J^T W J)^-1, s2 the weighted residual variance. Position and rotation rows
    (6D data) each get their own variance factor, whatever weights the fit gave them, and the
    covariance is the sandwich M^-1 (sum_k s2_k J_k^T W J_k) M^-1 with M = J^T W J: honest when the
    stated (or default) noise of one kind is off. With a robust loss W holds each residual's weight
    (``robust_weights``), so outliers neither move nor widen it. Columns mix metres, radians and
    rad/(N m): the normal matrix is inverted in unit-column scaling.

    Parameters
    ----------
    {solution}

    Returns
    -------
    Covariance
        Covariance, standard deviations and correlations of the estimate.
    """
    J, r = solution.jacobian, solution.residuals
    w = robust_weights(r, solution.loss, solution.f_scale) if solution.f_scale else np.ones_like(r)
    if solution.linear_rows is not None:
        w = np.where(solution.linear_rows, 1.0, w)
    if len(J) == len(r):          # else the R factor of a campaign solved in chunks: linear, one kind of row
        J = J * np.sqrt(w)[:, None]
    k = J.shape[1]
    dof = float(w.sum()) - k
    s2 = float(w @ (r * r)) / dof
    col = np.linalg.norm(J, axis=0)
    col[col == 0] = 1.0
    A = J / col
    s, Vt = singular_values(A, vectors=True)
    if s[-1] <= s[0] * 1e-12:
        raise DegenerateDataError("the normal matrix is singular at the solution: the parameters "
                                  "identifiable at the nominal model are not at the estimate")
    Minv = (Vt.T / s ** 2) @ Vt
    kinds = solution.row_kinds
    if kinds is None or len(np.unique(kinds)) < 2:
        cov = Minv * s2 / np.outer(col, col)
    else:
        B = np.zeros((k, k))
        for kind in np.unique(kinds):
            rows = kinds == kind
            share = float(w[rows].sum())
            s2_kind = float(w[rows] @ (r[rows] ** 2)) / max(share - k * share / float(w.sum()), 1.0)
            B += s2_kind * (A[rows].T @ A[rows])
        cov = Minv @ B @ Minv / np.outer(col, col)
    std = np.sqrt(np.diag(cov))
    return Covariance(covariance=cov, std=std, correlation=cov / np.outer(std, std), s2=s2, dof=dof)
