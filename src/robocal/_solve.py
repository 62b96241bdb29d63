"""The least-squares solve of a calibration problem, and the covariance of its estimates.

Calibration and the benchmarks call the same ``solve``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_triangular
from scipy.optimize import least_squares

from ._errors import DegenerateDataError, InputError, check_choice
from ._identifiability import singular_values
from ._options import LOSSES
from ._problem import LARGE_POSES, Problem
from ._threads import one_blas_thread

# least_squares' step, cost and gradient tolerances: Gauss-Newton converges quadratically here, so
# the step that meets them leaves an error far below them (noise-free recovery is ~1e-16)
SOLVER_TOL = 1e-10
# a robust loss bends at this many robust standard deviations of the residuals
ROBUST_SCALE_SIGMAS = 3.0


@dataclass(frozen=True, eq=False)
class Solution:
    """Where the solver stopped: the full parameter vector ``p``, the weighted residuals and the
    weighted Jacobian (n_rows, n_free) there (for a campaign solved in chunks its R factor, (n_free,
    n_free)), and the solver's own account (``status`` > 0 is
    convergence, as in scipy). ``f_scale`` is where a robust loss bent (None for ``linear``)."""

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


@one_blas_thread
def solve(problem: Problem, p0: np.ndarray, *, loss: str = "linear", f_scale: float | None = None,
          max_nfev: int | None = None, lower: np.ndarray | None = None) -> Solution:
    """Minimise the problem's residuals over its free parameters, starting from ``p0`` (full vector).

    ``loss="linear"`` is Levenberg-Marquardt (MINPACK) with the analytic Jacobian and Jacobian
    column scaling; a robust loss runs scipy's trust-region solver. Without ``f_scale`` a robust
    loss bends at ``ROBUST_SCALE_SIGMAS`` robust standard deviations (median absolute deviation)
    of the residuals, re-estimated from the robust fit until it settles: the first, non-robust fit
    spreads outliers over every residual. ``lower`` (n_free,): lower bounds (-inf for none), which
    need the trust-region solver.
    """
    check_choice(loss, LOSSES, "loss")
    x0 = p0[problem.free_idx]
    bounded = lower is not None and bool(np.any(np.isfinite(lower)))
    if problem.chunked:
        if loss != "linear" or bounded:
            raise InputError(f"a campaign of over {LARGE_POSES} poses is solved in chunks, with the linear loss and "
                             "without bounds only")
        return _solve_normal(problem, p0, max_nfev)

    def fun(x):
        return problem.residuals(problem.full(x, p0))

    def jac(x):
        return problem.jacobian(problem.full(x, p0))

    kw = dict(jac=jac, x_scale="jac", xtol=SOLVER_TOL, ftol=SOLVER_TOL, gtol=SOLVER_TOL, max_nfev=max_nfev)
    if bounded:
        x0 = np.maximum(x0, lower)
        kw["bounds"] = (lower, np.full(len(x0), np.inf))
    if loss == "linear" and bounded:
        sol = least_squares(fun, x0, method="trf", **kw)
    elif loss == "linear":
        sol = least_squares(fun, x0, method="lm", **kw)
    elif f_scale is not None:
        sol = least_squares(fun, x0, method="trf", loss=loss, f_scale=f_scale, **kw)
    else:
        sol = least_squares(fun, x0, method="trf" if bounded else "lm", **kw)
        for _ in range(6):
            mad = 1.4826 * float(np.median(np.abs(sol.fun - np.median(sol.fun))))
            new_scale = max(ROBUST_SCALE_SIGMAS * mad, 1e-12)
            if f_scale is not None and abs(new_scale - f_scale) < 0.05 * f_scale:
                break
            f_scale = new_scale
            sol = least_squares(fun, sol.x, method="trf", loss=loss, f_scale=f_scale, **kw)
    p = problem.full(sol.x, p0)
    # least_squares returns the Jacobian at the solution, reweighted by a robust loss
    residuals = sol.fun if loss == "linear" else problem.residuals(p)
    jacobian = sol.jac if loss == "linear" and not bounded else problem.jacobian(p)
    return Solution(p=p, residuals=residuals, jacobian=jacobian, success=bool(sol.status > 0),
                    status=int(sol.status), message=str(sol.message), nfev=int(sol.nfev), loss=loss,
                    f_scale=None if loss == "linear" else float(f_scale), row_kinds=problem.row_kinds())


def _solve_normal(problem: Problem, p0: np.ndarray, max_nfev: int | None) -> Solution:
    """Levenberg-Marquardt on the normal equations, accumulated chunk by chunk (``problem.chunked``).

    Each step solves ``(R^T R + lam D^2) dx = -J^T r`` through the QR factor of ``[R; sqrt(lam) D]``,
    D the Jacobian's column norms (scipy's ``x_scale="jac"``); the stopping tests are MINPACK's
    with ``SOLVER_TOL``. The returned ``jacobian`` is the R factor at the solution.
    """
    free = problem.free_idx
    x = p0[free].astype(float)
    R, g, cost = problem.normal_equations(p0)
    nfev, lam, k = 1, 0.0, len(x)
    max_nfev = 100 * (k + 1) if max_nfev is None else max_nfev
    D = np.maximum(np.linalg.norm(R, axis=0), np.finfo(float).tiny)
    status, message = 0, "the maximum number of function evaluations is exceeded"
    while nfev < max_nfev:
        A = R if lam == 0.0 else np.linalg.qr(np.vstack([R, np.sqrt(lam) * np.diag(D)]), mode="r")
        dx = -solve_triangular(A, solve_triangular(A, g, trans="T"))
        x_new = x + dx
        R_new, g_new, cost_new = problem.normal_equations(problem.full(x_new, p0))
        nfev += 1
        if cost_new <= cost:
            reduction = (cost - cost_new) / cost if cost > 0 else 0.0
            small_step = np.linalg.norm(D * dx) <= SOLVER_TOL * (SOLVER_TOL + np.linalg.norm(D * x_new))
            x, R, g, cost, lam = x_new, R_new, g_new, cost_new, lam / 10.0 if lam > 1e-12 else 0.0
            if small_step or reduction <= SOLVER_TOL:
                status = 2 if small_step else 1
                message = ("the relative step is below xtol" if small_step else
                           "the relative reduction of the sum of squares is below ftol")
                break
        else:
            lam = max(10.0 * lam, 1e-3)
    p = problem.full(x, p0)
    return Solution(p=p, residuals=problem.residuals(p), jacobian=R, success=status > 0, status=status,
                    message=message, nfev=nfev, loss="linear", f_scale=None, row_kinds=None)


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


@one_blas_thread
def covariance(solution: Solution) -> Covariance:
    """The estimates' covariance at the solution.

    One kind of row: s2 (J^T W J)^-1, s2 the weighted residual variance. Position and rotation rows
    (6D data) each get their own variance factor, whatever weights the fit gave them, and the
    covariance is the sandwich M^-1 (sum_k s2_k J_k^T W J_k) M^-1 with M = J^T W J: honest when the
    stated (or default) noise of one kind is off. With a robust loss W holds each residual's weight
    (``robust_weights``), so outliers neither move nor widen it. Columns mix metres, radians and
    rad/(N m): the normal matrix is inverted in unit-column scaling.
    """
    J, r = solution.jacobian, solution.residuals
    w = robust_weights(r, solution.loss, solution.f_scale) if solution.f_scale else np.ones_like(r)
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
