"""Kernels: constrained inertia against an explicit null-space projection; determinant signs."""

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from hypothesis import given
from hypothesis import strategies as st

from continuation import inertia_negative
from continuation._linalg import bordered, factorize


@given(st.integers(2, 12), st.integers(0, 3), st.integers(0, 2**31 - 1))
def test_kkt_inertia_equals_projected_hessian_index(n, m, seed):
    m = min(m, n - 1)
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    H = A + A.T
    C = rng.standard_normal((m, n)) if m else None
    if m:
        Z = sla.null_space(C)
        ref = int(np.sum(np.linalg.eigvalsh(Z.T @ H @ Z) < 0))
    else:
        ref = int(np.sum(np.linalg.eigvalsh(H) < 0))
    assert inertia_negative(H, C) == ref
    assert inertia_negative(sp.csr_matrix(H), C) == ref  # sparse input densified


@given(st.integers(1, 10), st.integers(0, 2**31 - 1))
def test_det_sign_dense_and_sparse(n, seed):
    rng = np.random.default_rng(seed)
    J = rng.standard_normal((n, n))
    col, row = rng.standard_normal(n), rng.standard_normal(n)
    M = bordered(J, col, row, 0.3)
    ref = int(np.sign(np.linalg.det(M)))
    assert factorize(M.copy()).det_sign() == ref
    Ms = bordered(sp.csc_matrix(J), col, row, 0.3)
    assert factorize(Ms).det_sign() == ref
    # Solves agree with numpy, both orientations.
    b = rng.standard_normal(n + 1)
    f = factorize(M.copy())
    assert np.allclose(f.solve(b), np.linalg.solve(M, b), atol=1e-8 * np.linalg.cond(M))
    assert np.allclose(f.solve(b, trans=True), np.linalg.solve(M.T, b),
                       atol=1e-8 * np.linalg.cond(M))


def test_singular_matrix_is_none_not_warning():
    assert factorize(np.zeros((3, 3))) is None
    assert factorize(sp.csc_matrix((3, 3))) is None
    assert factorize(np.full((2, 2), np.nan)) is None


def _pin_rows(rng, A, s):
    """A with s rows holding a single nonzero each, in distinct random columns."""
    n = A.shape[0]
    rows, cols = rng.choice(n, s, replace=False), rng.choice(n, s, replace=False)
    for r, c in zip(rows, cols, strict=True):
        A[r] = 0.0
        A[r, c] = rng.choice([-1.0, 1.0]) * rng.uniform(0.5, 2.0)
    return A


@given(st.integers(1, 12), st.integers(0, 12), st.integers(0, 2**31 - 1))
def test_dense_factor_with_single_nonzero_rows(n, s, seed):
    # rows with one nonzero are pivoted on before LAPACK: determinant sign and both solves
    # against numpy on the whole matrix
    rng = np.random.default_rng(seed)
    A = _pin_rows(rng, rng.standard_normal((n, n)), min(s, n))
    f = factorize(A.copy())
    assert f is not None
    assert f.det_sign() == int(np.sign(np.linalg.det(A)))
    b = rng.standard_normal(n)
    tol = 1e-9 * np.linalg.cond(A)
    assert np.allclose(f.solve(b), np.linalg.solve(A, b), atol=tol)
    assert np.allclose(f.solve(b, trans=True), np.linalg.solve(A.T, b), atol=tol)


def test_dense_factor_two_single_rows_in_one_column_is_singular():
    A = np.eye(3)
    A[2] = [2.0, 0.0, 0.0]
    assert factorize(A) is None


@given(st.integers(2, 12), st.integers(0, 4), st.integers(0, 4), st.integers(0, 2**31 - 1))
def test_inertia_with_single_nonzero_constraint_rows(n, m, s, seed):
    # constraints pinning one unknown each are eliminated before the LDL^T: the index
    # against the eigenvalues of the Hessian projected on the null space (scipy null_space)
    rng = np.random.default_rng(seed)
    m = min(m + s, n - 1)
    A = rng.standard_normal((n, n))
    H = A + A.T
    if not m:
        return
    C = _pin_rows(rng, rng.standard_normal((m, n)), min(s, m))
    Z = sla.null_space(C)
    ev = np.linalg.eigvalsh(Z.T @ H @ Z)
    if np.min(np.abs(ev)) < 1e-8:
        return  # a zero eigenvalue: the index is not defined to round-off
    assert inertia_negative(H, C) == int(np.sum(ev < 0))
