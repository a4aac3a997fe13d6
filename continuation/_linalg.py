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


def _inversions_parity(perm: np.ndarray) -> int:
    """Parity (0 even, 1 odd) of the permutation ``perm`` (an index array), by counting
    its inversions (vectorized; for the short arrays of :func:`_split_parity`)."""
    perm = np.asarray(perm)
    if np.all(perm[1:] > perm[:-1]):  # ascending (as np.flatnonzero makes the rows): none
        return 0
    return int(np.count_nonzero(np.triu(perm[:, None] > perm[None, :], 1)) % 2)


def _split_parity(rest: np.ndarray, tail: np.ndarray) -> int:
    """Parity of the permutation ``concatenate([rest, tail])`` of ``range(n)``, with
    ``rest`` ascending: the inversions within ``tail`` plus, for each entry of ``tail``,
    the entries of ``rest`` above it."""
    above = rest.size - np.searchsorted(rest, tail, side="right")
    return (_inversions_parity(tail) + int(np.sum(above))) % 2


class Factor:
    """LU factorization of a square dense or sparse matrix with determinant sign.

    Use :func:`factorize` to build one; it returns ``None`` for a singular or
    non-finite matrix instead of raising or warning.

    A dense matrix with rows holding a single nonzero (row r_i, column c_i, value
    d_i; e.g. a constraint that fixes one unknown) is factorized as
    ``P A Q = [[A11, A12], [0, diag(d)]]`` (P moves the rows r_i, Q the columns c_i
    last, pairwise): only A11 goes to LAPACK, and ``det A = sign(P) sign(Q)
    det(A11) prod(d)``.
    """

    __slots__ = ("_lu", "_sparse", "n", "_single")

    def __init__(self, lu, sparse: bool, n: int, single=None):
        self._lu, self._sparse, self.n = lu, sparse, n
        # (rows r_i, columns c_i, values d_i, other rows, other columns, A12) or None
        self._single = single

    def solve(self, b: np.ndarray, trans: bool = False) -> np.ndarray:
        if self._sparse:
            return self._lu.solve(b, trans="T" if trans else "N")
        lu, piv = self._lu
        if self._single is None:
            x, _ = _getrs(lu, piv, b, trans=1 if trans else 0)
            return x
        # lu factorizes A11^T (see factorize): A11 solves are its transposed solves
        rows, cols, d, rrest, crest, A12 = self._single
        x = np.empty(self.n)
        if not trans:
            xs = b[rows] / d
            x[cols] = xs
            if rrest.size:
                x[crest], _ = _getrs(lu, piv, b[rrest] - A12 @ xs, trans=1)
            return x
        # A^T y = b: the columns crest give A11^T y[rrest] = b[crest]; then the rows r_i
        y_rest = _getrs(lu, piv, b[crest], trans=0)[0] if rrest.size else np.empty(0)
        x[rrest] = y_rest
        x[rows] = (b[cols] - A12.T @ y_rest) / d
        return x

    def det_sign(self) -> int:
        if self._sparse:
            d = self._lu.U.diagonal()
            par = _perm_parity(self._lu.perm_r) ^ _perm_parity(self._lu.perm_c)
        else:
            lu, piv = self._lu
            d = np.diag(lu)
            par = int(np.count_nonzero(piv != np.arange(piv.size)) % 2)
            if self._single is not None:
                rows, cols, ds, rrest, crest, _a12 = self._single
                d = np.concatenate([d, ds])
                par ^= _split_parity(rrest, rows) ^ _split_parity(crest, cols)
        neg = int(np.count_nonzero(d < 0) % 2)
        return -1 if (neg ^ par) else 1


#: Dense matrices from this size on are scanned for rows with a single nonzero: the scan
#: is O(n^2) against the LU's O(n^3) (at n = 455, 0.14 ms against 2.9 ms), below it the
#: LU costs little more than the scan.
SINGLE_ROW_SCAN = 64


def factorize(A) -> Factor | None:
    """Factorize ``A`` (dense ndarray or sparse); ``None`` if singular or non-finite.

    Dense rows with a single nonzero are pivoted on first (:class:`Factor`; matrices of
    size ``SINGLE_ROW_SCAN`` and up): a matrix of size n with s such rows costs one LAPACK
    LU of size n - s and a few copies (measured: n = 455, s = 154, 2.0-2.2 ms against
    3.0-4.1 ms for the LU of the whole matrix).
    """
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
    n = A.shape[0]
    rows = np.flatnonzero((A != 0.0).sum(axis=1, dtype=np.int32) == 1) \
        if n >= SINGLE_ROW_SCAN else ()
    if len(rows):
        sub = A[rows]
        cols = np.argmax(sub != 0.0, axis=1)
        ckeep = np.ones(n, dtype=bool)
        ckeep[cols] = False
        if np.count_nonzero(ckeep) != n - rows.size:
            return None  # two rows with their one nonzero in the same column: singular
        rkeep = np.ones(n, dtype=bool)
        rkeep[rows] = False
        rrest, crest = np.flatnonzero(rkeep), np.flatnonzero(ckeep)
        # the blocks from one gather of the other rows, then of its columns: the entries
        # of np.ix_ gathers, a factorization 0.8x the time (0.69 ms against 0.87 ms on
        # 120 strip matrices of size 287-491 with their LU); A12 Fortran-ordered, as a
        # column gather makes it (Factor.solve's products with it take the same BLAS path)
        rows_rest = A.take(rrest, axis=0)
        single = (rows, cols, sub[np.arange(rows.size), cols], rrest, crest,
                  np.asfortranarray(rows_rest[:, cols]))
        if rows.size == n:
            return Factor((np.empty((0, 0)), np.empty(0, dtype=np.int32)), False, n, single)
        # A11^T is Fortran-ordered: LAPACK factorizes it in place, without the copy it
        # makes of a C-ordered matrix (Factor.solve swaps the transposes)
        lu, piv, info = _getrf(rows_rest.take(crest, axis=1).T, overwrite_a=True)
        if info > 0:
            return None
        if not np.isfinite(np.diagonal(lu).sum()):
            return None
        return Factor((lu, piv), False, n, single)
    # LAPACK getrf/getrs directly: scipy.linalg.lu_factor/lu_solve add ~20 us
    # of argument checking per call, which is most of a step's cost for the
    # n ~ 20-300 problems this library targets (measured with cProfile).
    lu, piv, info = _getrf(A, overwrite_a=True)
    if info > 0:  # exact zero pivot: singular
        return None
    d = np.diagonal(lu)
    if not np.isfinite(d.sum()):
        return None
    return Factor((lu, piv), False, n)


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

    A row of ``C`` with a single nonzero entry, in column j, fixes x_j = 0 on
    ``null(C)``: that row and unknown j are removed before the factorization (the
    restriction is then the same matrix on the remaining unknowns, and the other
    rows keep full rank), so constraints that pin unknowns one by one (a contact
    holding a node) cost nothing. Removed only when no two such rows share a
    column (otherwise ``C`` is rank deficient and the KKT matrix is used as it is).
    """
    H = H.toarray() if sp.issparse(H) else np.asarray(H, dtype=float)
    if not np.isfinite(H.sum()):
        return -1
    if C is None:
        K = H
        m = 0
    else:
        C = C.toarray() if sp.issparse(C) else np.atleast_2d(np.asarray(C, dtype=float))
        if not np.isfinite(C.sum()):
            return -1
        nz = C != 0.0
        single = np.flatnonzero(np.count_nonzero(nz, axis=1) == 1)
        if single.size:
            cols = np.argmax(nz[single], axis=1)
            if np.unique(cols).size == cols.size:
                keep = np.ones(C.shape[1], dtype=bool)
                keep[cols] = False
                rows = np.ones(C.shape[0], dtype=bool)
                rows[single] = False
                # two takes each (rows, then columns): the entries of one np.ix_ gather
                kp = np.flatnonzero(keep)
                H = H.take(kp, axis=0).take(kp, axis=1)
                C = C.take(np.flatnonzero(rows), axis=0).take(kp, axis=1)
        m, n = C.shape
        K = np.zeros((n + m, n + m))
        K[:n, :n] = H
        K[n:, :n] = C
        K[:n, n:] = C.T
    if K.shape[0] == 0:
        return 0
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
