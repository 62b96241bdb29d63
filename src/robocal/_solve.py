"""The least-squares solve of a calibration problem, and the covariance of its estimates.

Calibration and the benchmarks call the same ``solve``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from ._errors import DegenerateDataError, check_choice
from ._identifiability import singular_values
from ._options import LOSSES
from ._problem import Problem

# least_squares' step, cost and gradient tolerances: Gauss-Newton converges quadratically here, so
# the step that meets them leaves an error far below them (noise-free recovery is ~1e-16)
SOLVER_TOL = 1e-10
# a robust loss bends at this many robust standard deviations of the residuals
ROBUST_SCALE_SIGMAS = 3.0


@dataclass(frozen=True, eq=False)
class Solution:
    """Where the solver stopped: the full parameter vector ``p``, the weighted residuals and the
    weighted Jacobian (n_rows, n_free) there, and the solver's own account (``status`` > 0 is
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


def solve(problem: Problem, p0: np.ndarray, *, loss: str = "linear", f_scale: float | None = None,
          max_nfev: int | None = None) -> Solution:
    """Minimise the problem's residuals over its free parameters, starting from ``p0`` (full vector).

    ``loss="linear"`` is Levenberg-Marquardt (MINPACK) with the analytic Jacobian and Jacobian
    column scaling; a robust loss runs scipy's trust-region solver. Without ``f_scale`` a robust
    loss bends at ``ROBUST_SCALE_SIGMAS`` robust standard deviations (median absolute deviation)
    of the residuals, re-estimated from the robust fit until it settles: the first, non-robust fit
    spreads outliers over every residual.
    """
    check_choice(loss, LOSSES, "loss")
    x0 = p0[problem.free_idx]

    def fun(x):
        return problem.residuals(problem.full(x, p0))

    def jac(x):
        return problem.jacobian(problem.full(x, p0))

    kw = dict(jac=jac, x_scale="jac", xtol=SOLVER_TOL, ftol=SOLVER_TOL, gtol=SOLVER_TOL, max_nfev=max_nfev)
    if loss == "linear":
        sol = least_squares(fun, x0, method="lm", **kw)
    elif f_scale is not None:
        sol = least_squares(fun, x0, method="trf", loss=loss, f_scale=f_scale, **kw)
    else:
        sol = least_squares(fun, x0, method="lm", **kw)
        for _ in range(6):
            mad = 1.4826 * float(np.median(np.abs(sol.fun - np.median(sol.fun))))
            new_scale = max(ROBUST_SCALE_SIGMAS * mad, 1e-12)
            if f_scale is not None and abs(new_scale - f_scale) < 0.05 * f_scale:
                break
            f_scale = new_scale
            sol = least_squares(fun, sol.x, method="trf", loss=loss, f_scale=f_scale, **kw)
    p = problem.full(sol.x, p0)
    # method "lm" returns the Jacobian at the solution; the robust losses return a reweighted one
    residuals = sol.fun if loss == "linear" else problem.residuals(p)
    jacobian = sol.jac if loss == "linear" else problem.jacobian(p)
    return Solution(p=p, residuals=residuals, jacobian=jacobian, success=bool(sol.status > 0),
                    status=int(sol.status), message=str(sol.message), nfev=int(sol.nfev), loss=loss,
                    f_scale=None if loss == "linear" else float(f_scale))


@dataclass(frozen=True, eq=False)
class Covariance:
    """Covariance of the free parameters (SI), their standard deviations and correlations, and the
    residual variance factor ``s2`` (sum of squared weighted residuals over the degrees of freedom)."""

    covariance: np.ndarray
    std: np.ndarray
    correlation: np.ndarray
    s2: float
    dof: int


def covariance(solution: Solution) -> Covariance:
    """The estimates' covariance s2 (J^T J)^-1 at the solution.

    Columns mix metres, radians and rad/(N m): the normal matrix is inverted in unit-column scaling.
    """
    J, r = solution.jacobian, solution.residuals
    dof = J.shape[0] - J.shape[1]
    s2 = float(r @ r) / dof
    col = np.linalg.norm(J, axis=0)
    col[col == 0] = 1.0
    s, Vt = singular_values(J / col, vectors=True)
    if s[-1] <= s[0] * 1e-12:
        raise DegenerateDataError("the normal matrix is singular at the solution: the parameters "
                                  "identifiable at the nominal model are not at the estimate")
    cov = (Vt.T / s ** 2) @ Vt * s2 / np.outer(col, col)
    std = np.sqrt(np.diag(cov))
    return Covariance(covariance=cov, std=std, correlation=cov / np.outer(std, std), s2=s2, dof=dof)
