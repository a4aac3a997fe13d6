"""Linear algebra kernels: bordered factorizations, determinant signs, inertia.

Pure array functions; they never print and never warn. A singular matrix is
reported by returning ``None`` (the orchestrator turns that into a status).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla


class BandedJacobian:
    """A banded Jacobian in the storage format of :func:`scipy.linalg.solve_banded`.

    Parameters
    ----------
    lower, upper : int
        Number of sub- and super-diagonals.
    ab : ndarray, shape (lower + upper + 1, n)
        ``ab[upper + i - j, j] == J[i, j]``.

    Notes
    -----
    Bordering destroys bandedness, so the library converts the band to
    ``scipy.sparse`` (CSC) and factorizes the bordered matrix with SuperLU,
    whose fill-in for a bordered band is one dense row and column.
    """

    __slots__ = ("lower", "upper", "ab")

    def __init__(self, lower: int, upper: int, ab):
        ab = np.asarray(ab, dtype=float)
        if ab.ndim != 2 or ab.shape[0] != lower + upper + 1:
            raise ValueError(
                f"BandedJacobian: `ab` must have shape (lower + upper + 1, n) = "
                f"({lower + upper + 1}, n); got {ab.shape}. Use the layout of "
                "scipy.linalg.solve_banded."
            )
        self.lower, self.upper, self.ab = int(lower), int(upper), ab

    def tosparse(self) -> sp.csc_matrix:
        n = self.ab.shape[1]
        offsets = np.arange(self.upper, -self.lower - 1, -1)
        # dia_matrix stores data[k, j] = A[j - offset_k, j]: the solve_banded layout.
        return sp.dia_matrix((self.ab, offsets), shape=(n, n)).tocsc()

    def toarray(self) -> np.ndarray:
        return self.tosparse().toarray()


def as_matrix(J):
    """Normalise a Jacobian to a dense ndarray or a CSC sparse matrix."""
    if isinstance(J, BandedJacobian):
        return J.tosparse()
    if sp.issparse(J):
        return J.tocsc()
    return np.asarray(J, dtype=float)


def matvec(J, v):
    return J @ v


def rmatvec(J, w):
    return J.T @ w


def _perm_parity(perm: np.ndarray) -> int:
    """Parity (0 even, 1 odd) of a permutation given as an index array."""
    n = perm.size
    seen = np.zeros(n, dtype=bool)
    cycles = 0
    for i in range(n):
        if not seen[i]:
            cycles += 1
            j = i
            while not seen[j]:
                seen[j] = True
                j = perm[j]
    return (n - cycles) % 2


class Factor:
    """LU factorization of a square dense or sparse matrix with determinant sign.

    Use :func:`factorize` to build one; it returns ``None`` for a singular or
    non-finite matrix instead of raising or warning.
    """

    __slots__ = ("_lu", "_sparse", "n")

    def __init__(self, lu, sparse: bool, n: int):
        self._lu, self._sparse, self.n = lu, sparse, n

    def solve(self, b: np.ndarray, trans: bool = False) -> np.ndarray:
        if self._sparse:
            return self._lu.solve(b, trans="T" if trans else "N")
        lu, piv = self._lu
        x, _ = _getrs(lu, piv, b, trans=1 if trans else 0)
        return x

    def det_sign(self) -> int:
        if self._sparse:
            d = self._lu.U.diagonal()
            par = _perm_parity(self._lu.perm_r) ^ _perm_parity(self._lu.perm_c)
        else:
            lu, piv = self._lu
            d = np.diag(lu)
            par = int(np.count_nonzero(piv != np.arange(piv.size)) % 2)
        neg = int(np.count_nonzero(d < 0) % 2)
        return -1 if (neg ^ par) else 1


def factorize(A) -> Factor | None:
    """Factorize ``A`` (dense ndarray or sparse); ``None`` if singular or non-finite."""
    if sp.issparse(A):
        A = A.tocsc()
        if not np.all(np.isfinite(A.data)):
            return None
        try:
            lu = spla.splu(A)
        except RuntimeError:  # SuperLU: "Factor is exactly singular"
            return None
        if not np.all(np.isfinite(lu.U.diagonal())) or np.any(lu.U.diagonal() == 0):
            return None
        return Factor(lu, True, A.shape[0])
    # A finite sum means finite entries (inf - inf gives nan): one pass, no temporary.
    if not np.isfinite(A.sum()):
        return None
    # LAPACK getrf/getrs directly: scipy.linalg.lu_factor/lu_solve add ~20 us
    # of argument checking per call, which is most of a step's cost for the
    # n ~ 20-300 problems this library targets (measured with cProfile).
    lu, piv, info = _getrf(A, overwrite_a=True)
    if info > 0:  # exact zero pivot: singular
        return None
    d = np.diagonal(lu)
    if not np.isfinite(d.sum()):
        return None
    return Factor((lu, piv), False, A.shape[0])


_getrf, _getrs = sla.get_lapack_funcs(("getrf", "getrs"), (np.empty((2, 2)),))


def bordered(J, col: np.ndarray, row: np.ndarray, corner: float):
    """The matrix ``[[J, col], [row, corner]]`` in J's storage (dense or sparse)."""
    n = col.shape[0]
    if sp.issparse(J):
        return sp.bmat(
            [[J, col.reshape(n, 1)], [row.reshape(1, n), np.array([[corner]])]],
            format="csc",
        )
    M = np.empty((n + 1, n + 1))
    M[:n, :n] = J
    M[:n, n] = col
    M[n, :n] = row
    M[n, n] = corner
    return M


def inertia_negative(H, C=None) -> int:
    """Number of negative eigenvalues of ``H`` restricted to ``null(C)``.

    Computed from the inertia of the KKT matrix ``K = [[H, C^T], [C, 0]]``: for
    ``C`` of full row rank m, ``n_-(K) = n_-(Z^T H Z) + m`` with ``Z`` a basis of
    ``null(C)`` (Gould 1985; Nocedal & Wright, Thm 16.3), so the index is
    ``n_-(K) - m``. Inertia by symmetric indefinite LDL^T (Bunch-Kaufman,
    Sylvester's law), O(n^3/3); sparse inputs are densified (meant for n <~ 2000).
    """
    H = H.toarray() if sp.issparse(H) else np.asarray(H, dtype=float)
    if C is None:
        K = H
        m = 0
    else:
        C = C.toarray() if sp.issparse(C) else np.atleast_2d(np.asarray(C, dtype=float))
        m, n = C.shape
        K = np.zeros((n + m, n + m))
        K[:n, :n] = H
        K[n:, :n] = C
        K[:n, n:] = C.T
    if not np.isfinite(K.sum()):
        return -1
    return _negative_pivots(K) - m


def _negative_pivots(K: np.ndarray) -> int:
    """Negative eigenvalues of the symmetric ``K``: those of D in its Bunch-Kaufman
    factorization ``K = L D L^T`` (LAPACK ``sytrf``, the factorization behind
    ``scipy.linalg.ldl``), counted block by block; -1 if LAPACK fails."""
    ldu, piv, info = _sytrf(K, lower=1)
    if info < 0:
        return -1
    d = np.diagonal(ldu)
    # a 2x2 block of D at rows (k, k+1) has ipiv[k] = ipiv[k+1] < 0 (lower storage)
    two = piv < 0
    neg = int(np.count_nonzero(d[~two] < 0.0))
    ks = np.flatnonzero(two)
    for k in ks[0::2]:
        a, b, c = ldu[k, k], ldu[k + 1, k], ldu[k + 1, k + 1]
        det = a * c - b * b
        if det < 0.0:  # one negative, one positive eigenvalue
            neg += 1
        elif det > 0.0:  # both of the sign of the trace
            neg += 2 if a + c < 0.0 else 0
        else:  # one zero eigenvalue; the other is the trace
            neg += int(a + c < 0.0)
    return neg


_sytrf = sla.get_lapack_funcs("sytrf", (np.empty((2, 2)),))
