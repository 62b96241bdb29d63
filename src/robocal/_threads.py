"""BLAS on one thread inside robocal's own numerical calls.

robocal's matrices are tall and narrow (thousands of rows, tens of columns) or stacks of 3x3
blocks: a second BLAS thread gains little on them, and when another process keeps a core busy,
OpenBLAS's threads wait on each other and a call runs many times slower than on one thread. One
thread also makes results independent of the machine's thread count. The limit is taken when the
outermost robocal call starts and the previous setting is restored when it returns: the user's
own settings are untouched outside robocal. The bound is the BLAS library's, so it holds for the
whole process while a robocal call runs: BLAS called from another Python thread at that time runs
on one thread too.

The first call also lets the C allocator keep memory robocal frees for its next arrays. glibc hands
blocks over 128 kB straight back to the system and trims the heap as soon as a few of them are free,
so each kinematic pass and Jacobian of a thousand poses touches fresh pages: at 1,000 poses about
1,800 page faults a calibration, a third of its time. glibc raises both bounds itself once a
program frees a large block (any numpy program freeing a large array does); robocal frees one
block of ``HEAP_PRIMER_BYTES``, never touched, at its first call, so that a fresh process behaves as
a warm one. Nothing else changes: memory is still freed, and kept for reuse by the process.
"""

from __future__ import annotations

import threading
from functools import lru_cache, wraps

_lock = threading.Lock()
_depth = 0
_restore = None
# freed at the first call: glibc then serves blocks under this size from its heap and keeps up to
# twice it free there (its largest dynamic bound is 32 MB)
HEAP_PRIMER_BYTES = 31 << 20
_primed = False


@lru_cache(maxsize=1)
def _blas():
    """The BLAS libraries loaded by numpy and scipy (looked up once, after scipy's is loaded)."""
    import scipy.linalg  # noqa: F401  (scipy ships its own BLAS: load it before looking)
    from threadpoolctl import ThreadpoolController

    return ThreadpoolController().select(user_api="blas")


def _prime_heap() -> None:
    """Allocate and free one untouched block of ``HEAP_PRIMER_BYTES`` (see the module's docstring)."""
    global _primed
    import numpy as np

    np.empty(HEAP_PRIMER_BYTES, dtype=np.uint8)
    _primed = True


def _enter() -> None:
    global _depth, _restore
    with _lock:
        if _depth == 0:
            if not _primed:
                _prime_heap()
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
