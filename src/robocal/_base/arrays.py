"""Read-only arrays and mappings: what a record or a cache hands out cannot be changed behind its back.

Records (measurements, contacts, layouts, results) and what an object keeps between calls (a
problem's evaluations, a model's layouts) hold their arrays read-only: writing into one raises
``ValueError: assignment destination is read-only`` instead of silently moving every later result.
Their mappings are read-only views (writing raises ``TypeError``), their lists tuples.

Also: reductions over many short vectors (norms, extents, spreads) taken along long rows, where
numpy is far faster than down a narrow column, with numpy's own figures.
"""

from __future__ import annotations

import types
from collections.abc import Mapping

import numpy as np


def read_only(a: np.ndarray) -> np.ndarray:
    """``a`` itself, marked read-only (for an array just made and owned by the caller).

    Parameters
    ----------
    a : numpy.ndarray
        An array nobody else holds a writeable reference to.

    Returns
    -------
    numpy.ndarray
        The same array, no longer writeable.
    """
    a.flags.writeable = False
    return a


def frozen(a, dtype=float) -> np.ndarray:
    """A read-only copy of ``a`` as ``dtype`` (no copy when ``a`` is already a read-only array of
    that type that owns its data, which nobody can change).

    Parameters
    ----------
    a : array_like
        The values, from a caller who may keep and change their own array.
    dtype : numpy dtype, optional
        The type to hold them as (float by default).

    Returns
    -------
    numpy.ndarray
        A read-only array with the values of ``a``.
    """
    if isinstance(a, np.ndarray) and a.dtype == dtype and not a.flags.writeable and a.base is None:
        return a
    return read_only(np.array(a, dtype=dtype))


def frozen_mapping(m: Mapping) -> Mapping:
    """A read-only copy of the mapping ``m``, and of what it holds: mappings inside are read-only
    too, lists and tuples become tuples, arrays read-only copies (:func:`frozen`, their type kept).

    Parameters
    ----------
    m : Mapping
        The mapping, from a caller who may keep and change it.

    Returns
    -------
    Mapping
        A read-only mapping (``types.MappingProxyType``) with the keys and values of ``m``.
    """
    return types.MappingProxyType({k: _frozen_value(v) for k, v in m.items()})


def _frozen_value(v):
    if isinstance(v, (str, int, float)) or v is None:   # most values; the Mapping check is slow
        return v
    if isinstance(v, Mapping):
        return frozen_mapping(v)
    if isinstance(v, (list, tuple)):
        # strings alone (a campaign's pose labels, up to millions) are immutable already
        return tuple(v) if set(map(type, v)) <= {str} else tuple(map(_frozen_value, v))
    if isinstance(v, np.ndarray):
        return frozen(v, v.dtype)
    return v


def point_spread(points) -> float:
    """The RMS distance (m) of the finite points among ``points`` (..., 3) from their centroid; 0 for
    fewer than two. Taken over coordinate rows (3, n): numpy reduces a long row far faster than
    down a narrow column."""
    p = np.ascontiguousarray(np.asarray(points, dtype=float).reshape(-1, 3).T)
    finite = np.isfinite(p).all(axis=0)
    if not finite.all():
        p = p[:, finite]
    if p.shape[1] < 2:
        return 0.0
    d = p - p.mean(axis=1)[:, None]
    return float(np.sqrt(np.mean(np.sum(d * d, axis=0))))


def vector_norms(v: np.ndarray) -> np.ndarray:
    """The norms of the vectors along the last axis of ``v``: ``np.linalg.norm(v, axis=-1)`` bit for
    bit; for 3-vectors, the squares summed in turn (a fifth of its time on so short an axis)."""
    if v.shape[-1] != 3:
        return np.linalg.norm(v, axis=-1)
    return np.sqrt(v[..., 0] ** 2 + v[..., 1] ** 2 + v[..., 2] ** 2)


def column_extent(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The smallest and largest value of each column of ``a`` (n, k), taken over rows of its
    transpose (numpy reduces a long row far faster than down a narrow column)."""
    rows = np.ascontiguousarray(np.asarray(a, dtype=float).T)
    return rows.min(axis=1), rows.max(axis=1)


def mean_and_error(d) -> tuple[float, float]:
    """The mean of the values ``d`` (0 for none) and its standard error, infinite below two values
    (one has none: nothing is established from it).

    >>> mean_and_error([1.0, 3.0]), mean_and_error([2.0])
    ((2.0, 1.0), (2.0, inf))
    """
    d = np.asarray(d, dtype=float).ravel()
    mean = float(d.mean()) if d.size else 0.0
    return mean, float(d.std(ddof=1) / np.sqrt(d.size)) if d.size > 1 else float("inf")
