"""Shared fixtures of the strip tests."""

from __future__ import annotations

import pytest
from threadpoolctl import threadpool_limits


@pytest.fixture(scope="module", autouse=True)
def one_blas_thread():
    """Small dense LAPACK calls (100-300 square) ran 10-17x slower with two OpenBLAS threads
    on the shared 2-core machine (see elastocap.strip.trace); the tests call the solvers
    below the drivers that limit the threads themselves, so each module runs with one BLAS
    thread, restored afterwards."""
    with threadpool_limits(limits=1, user_api="blas"):
        yield
