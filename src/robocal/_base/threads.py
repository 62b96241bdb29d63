"""BLAS on one thread inside robocal's own numerical calls.

robocal's matrices are tall and narrow (thousands of rows, tens of columns) or stacks of 3x3
blocks: a second BLAS thread gains little on them, and when another process keeps a core busy,
OpenBLAS's threads wait on each other and a call runs many times slower than on one thread. One
thread also makes results independent of the machine's thread count. The limit is taken when the
outermost robocal call starts and the previous setting is restored when it returns: the user's
own settings are untouched outside robocal. The bound is the BLAS library's, so it holds for the
whole process while a robocal call runs: BLAS called from another Python thread at that time runs
on one thread too.

Nothing else about the process changes: robocal leaves the C allocator and the rest of its
host's settings as it found them.
"""

from __future__ import annotations

import threading
from functools import lru_cache, wraps

_lock = threading.Lock()
_depth = 0
_restore = None


@lru_cache(maxsize=1)
def _blas():
    """The BLAS libraries loaded by numpy and scipy (looked up once, after scipy's is loaded)."""
    import scipy.linalg  # noqa: F401  (scipy ships its own BLAS: load it before looking)
    from threadpoolctl import ThreadpoolController

    return ThreadpoolController().select(user_api="blas")


def _enter() -> None:
    global _depth, _restore
    with _lock:
        if _depth == 0:
            _restore = _blas().limit(limits=1)
        _depth += 1


def _leave() -> None:
    global _depth, _restore
    with _lock:
        _depth -= 1
        if _depth == 0:
            if _restore is not None:
                _restore.restore_original_limits()
            _restore = None


def one_blas_thread(fn):
    """``fn`` with BLAS bounded to one thread while it runs (nested calls share the outer bound)."""
    @wraps(fn)
    def bounded(*args, **kwargs):
        _enter()
        try:
            return fn(*args, **kwargs)
        finally:
            _leave()
    return bounded
