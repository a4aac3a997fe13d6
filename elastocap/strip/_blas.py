"""Pin the OpenBLAS bundled with numpy and scipy to one thread for a block of code.

Small dense LAPACK calls (eigh / solve of ~100 x 100) ran 19-100x slower with two OpenBLAS
threads on the shared 2-core machine (barrier at n = 60: 33 s against 1.8 s; 101 x 101
eigh: 176 ms against 1.8 ms), and the strip statics makes thousands of them. The
environment variable OPENBLAS_NUM_THREADS only acts before numpy is imported; this sets the
count at run time through the library's own entry points and restores it afterwards.
"""

from __future__ import annotations

import ctypes
import glob
import os
from contextlib import contextmanager

__all__ = ["blas_threads", "openblas_handles"]

# Entry-point names of the OpenBLAS builds shipped in numpy / scipy wheels (64-bit-integer
# scipy-openblas, 32-bit scipy-openblas, plain OpenBLAS), tried in this order.
_NAMES = (
    ("scipy_openblas_get_num_threads64_", "scipy_openblas_set_num_threads64_"),
    ("scipy_openblas_get_num_threads", "scipy_openblas_set_num_threads"),
    ("openblas_get_num_threads", "openblas_set_num_threads"),
)


def openblas_handles() -> list[tuple]:
    """(get, set) ctypes functions of every OpenBLAS library bundled with numpy and scipy
    (in ``numpy.libs`` / ``scipy.libs`` next to the packages); empty when there is none
    (e.g. a build against a system BLAS), and then pinning is a no-op."""
    import numpy
    import scipy

    out = []
    for pkg in (numpy, scipy):
        d = os.path.join(os.path.dirname(pkg.__file__), "..", pkg.__name__ + ".libs")
        for lib in sorted(glob.glob(os.path.join(d, "*openblas*"))):
            try:
                c = ctypes.CDLL(lib)
            except OSError:
                continue
            for get, set_ in _NAMES:
                if hasattr(c, get) and hasattr(c, set_):
                    out.append((getattr(c, get), getattr(c, set_)))
                    break
    return out


@contextmanager
def blas_threads(n: int = 1):
    """Run the block with ``n`` OpenBLAS threads, then restore each library's previous count.

    Yields the list of previous counts (one per library found; empty: nothing pinned).
    """
    if int(n) != n or n < 1:
        raise ValueError(f"n: got {n!r}; expected a positive integer number of threads")
    handles = openblas_handles()
    before = [int(g()) for g, _s in handles]
    for _g, s in handles:
        s(int(n))
    try:
        yield before
    finally:
        for (_g, s), k in zip(handles, before, strict=True):
            s(k)
