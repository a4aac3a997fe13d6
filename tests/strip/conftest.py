"""Shared fixtures of the strip tests."""

from __future__ import annotations

import pytest

from elastocap.strip._blas import blas_threads


@pytest.fixture(scope="module", autouse=True)
def one_blas_thread():
    """Small dense LAPACK calls (100 x 100) ran 19x slower with two OpenBLAS threads on the
    shared 2-core machine (barrier at n = 60: 33 s against 1.8 s); pin one thread for each
    module and restore the previous count afterwards (a no-op without OpenBLAS)."""
    with blas_threads(1):
        yield
