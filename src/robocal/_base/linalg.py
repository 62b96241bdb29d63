"""R factors of tall matrices: a (k, k) matrix with the Gram matrix of a stacked (n_rows, k) one.

Everything robocal asks of stacked rows (column norms, inner products, singular values, least
squares on the columns, normal equations) depends on the Gram matrix alone, so it runs on k x k
numbers once the rows are reduced.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import lapack

# The Gram matrix of the column-scaled rows is factored directly (Cholesky) while its condition
# number stays below this: the factor then loses at most about 1e-8 relative (cond * eps); beyond
# it, or when it is singular, the rows themselves are factored (QR).
GRAM_COND_MAX = 1e8
# columns per block of the QR (LAPACK's dgeqrt)
QR_BLOCK = 8


def reduced(A: np.ndarray) -> np.ndarray:
    """The R factor of ``A`` (n_rows, k) by QR when it is tall, else ``A`` itself."""
    if A.shape[1] == 0:  # no column (nothing left to identify): LAPACK refuses a block of none
        return np.zeros((0, 0))
    if A.shape[0] > A.shape[1]:
        # LAPACK's blocked QR alone: numpy's wrapper spends more than the factorisation on copies,
        # and dgeqrf runs unblocked on a few tens of columns (dgeqrt in blocks of 8 is ~1.8x faster)
        k = A.shape[1]
        qr, _, info = lapack.dgeqrt(max(1, min(QR_BLOCK, k)), np.asfortranarray(A, dtype=float))
        if info != 0:
            raise ValueError(f"QR factorisation failed (LAPACK info {info})")
        return np.triu(qr[:k])
    return A


def r_factor(A: np.ndarray) -> np.ndarray:
    """An upper triangular R (k, k) with ``R^T R = A^T A`` for a tall ``A`` (n_rows, k) (``A`` itself
    when it is not tall).

    From the Cholesky factor of the column-scaled Gram matrix when it is well conditioned
    (``GRAM_COND_MAX``): one matrix product over the rows instead of a QR of them, several times
    cheaper. Otherwise the QR factor of ``A``.
    """
    if A.shape[0] <= A.shape[1]:
        return A
    R = gram_factor(A.T @ A)
    return reduced(A) if R is None else R


def gram_factor(G: np.ndarray) -> np.ndarray | None:
    """The upper triangular R with ``R^T R = G`` (a Gram matrix) from the Cholesky factor of its
    column-scaled form, or None when that is singular or its condition number exceeds
    ``GRAM_COND_MAX`` (the rows themselves must then be factored)."""
    col = np.sqrt(np.diag(G))
    if np.all(col > 0) and np.all(np.isfinite(G)):
        Gs = G / np.outer(col, col)
        U, info = lapack.dpotrf(Gs, lower=0, clean=1)
        if info == 0:
            rcond, info = lapack.dpocon(U, np.abs(Gs).sum(axis=0).max())
            if info == 0 and rcond * GRAM_COND_MAX >= 1.0:
                return U * col
    return None


def solve_upper(R: np.ndarray, b: np.ndarray, *, transposed: bool = False) -> np.ndarray:
    """``R^-1 b`` (or ``R^-T b``) for an upper triangular ``R`` by LAPACK's dtrtrs, NaN where ``R`` is
    singular (scipy's checking wrapper costs several times the solve at these sizes). An empty
    system has an empty solution, a factor with fewer rows than columns (of fewer equations than
    unknowns) is singular: LAPACK would refuse either's leading dimension, on the terminal."""
    if R.shape[0] == 0:
        return np.zeros(b.shape)
    if R.shape[0] < R.shape[1]:
        return np.full(b.shape, np.nan)
    x, info = lapack.dtrtrs(R, b if b.ndim == 2 else b[:, None], lower=0, trans=int(transposed))
    if info != 0:
        x = np.full(x.shape, np.nan)
    return x if b.ndim == 2 else x[:, 0]
