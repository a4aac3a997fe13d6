"""The banded complementarity solve of self-contact (``dynamics.contact._band_lcp``) against
the dense Schur complement with projected Gauss-Seidel, and against the conditions it
solves.

The scenes are rods folded in two layers, the upper arm pressed into the lower one, as in
a strip lying on itself: random sizes, fold positions, penetrations, edge residuals, old
and current edge directions (the position stage, ``f = 2``, and the velocity stage,
``f = 1`` with ``O = R``), masses, held nodes and multipliers to start from.  At these
contact counts the solver takes the banded path; it must give the update of the positions
the dense solve gives, and that update must satisfy the complementarity conditions:
multipliers ``nu >= 0``, gaps after the update ``>= 0``, zero where a contact pushes.
"""

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dynamics import contact

DATA = Path(__file__).parent / "data"


def _folded(seed, m, f, held):
    """Arguments of ``_bordered_solve`` for a rod of ``m`` edges folded at its middle, the
    upper arm 0-20 % of the thickness into the lower one."""
    rng = np.random.default_rng(seed)
    h, d = 0.1, 0.05
    a = m // 2
    n = m + 1
    x = np.zeros((n, 2))
    shift = rng.uniform(0.05, 0.95) * h
    for i in range(n):
        if i <= a:
            x[i] = (i * h, 0.0)
        else:
            x[i] = ((2 * a - i) * h + shift, d * (1.0 - 0.2 * rng.random()))
    O = np.diff(x, axis=0)
    R = O + (0.0 if f == 1.0 else 1e-3 * h) * rng.standard_normal(O.shape)
    if f == 1.0:
        O = R
    w = rng.uniform(0.5, 2.0, size=(n, 1)) * np.ones((n, 2))
    if held:
        w[: a // 2, 1] = 0.0  # the lower arm's far part held by the ground
    rows = []
    for i in range(a + 2, n):
        j = int(np.floor(x[i, 0] / h))
        if 0 <= j < a - 1:
            rows.append((i, j, x[i, 0] / h - j))
    na = len(rows)
    ci = np.array([r[:2] for r in rows], dtype=np.int64)
    cu = np.array([r[2] for r in rows])
    cn = np.tile([0.0, 1.0], (na, 1))
    rhs_c = d - x[ci[:, 0], 1] + 1e-3 * d * rng.standard_normal(na)
    rhs_e = 1e-4 * h * h * rng.standard_normal(m)
    mu0 = np.where(rng.random(na) < 0.5, 1e-3 * rng.random(na), 0.0)
    ck = contact.new_contact_work(np.full(m, h))
    return (R, O, w, f, rhs_e, na, ci, cu, cn, rhs_c, ck, mu0)


def _solve(args, band):
    R, O, w, f, rhs_e, na, ci, cu, cn, rhs_c, ck, mu0 = args
    m = R.shape[0]
    dl = np.zeros(m + 2)
    dm = np.zeros(na + 2)
    eq = np.zeros(na, dtype=np.int64)
    hint = np.zeros(na, dtype=np.int64)
    before = ck.meta.copy()
    ok = contact._bordered_solve(R, O, w, f, rhs_e, na, ci, cu, cn, rhs_c, ck, dl, dm, mu0,
                                 eq, hint, 1e-18, band)
    assert ok
    banded = ck.meta[contact._NBAND] - before[contact._NBAND]
    dq = np.zeros((m + 1, 2))
    contact._apply(dq, w, O, dl, na, ci, cu, cn, dm, 1.0)
    return dq, dm[:na] + mu0, banded


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31), m=st.integers(160, 400), f=st.sampled_from([1.0, 2.0]),
       held=st.booleans())
def test_banded_solve_agrees_with_the_dense_one(seed, m, f, held):
    args = _folded(seed, m, f, held)
    R, O, w, f, rhs_e, na, ci, cu, cn, rhs_c, ck, mu0 = args
    assert na >= contact.BAND_MIN
    dq_b, nu_b, banded = _solve(args, True)
    dq_d, _nu_d, dense_banded = _solve(args, False)
    assert banded == 1 and dense_banded == 0
    scale = np.abs(dq_d).max()
    # the same update of the positions, to the dense solve's own accuracy: its projected
    # Gauss-Seidel stops at changes of 1e-6 of the complementarity residual it starts from
    # (the Newton iteration around it refines the rest); measured <= 2.0e-7 over 200 rods
    assert np.abs(dq_b - dq_d).max() <= 1e-6 * scale
    # complementarity, to round-off of the update's size
    gaps = (cn[:, 0] * (dq_b[ci[:, 0], 0] - (1 - cu) * dq_b[ci[:, 1], 0]
                        - cu * dq_b[ci[:, 1] + 1, 0])
            + cn[:, 1] * (dq_b[ci[:, 0], 1] - (1 - cu) * dq_b[ci[:, 1], 1]
                          - cu * dq_b[ci[:, 1] + 1, 1])) - rhs_c
    tol = 1e-13 * scale
    assert nu_b.min() >= 0.0
    assert gaps.min() >= -tol
    assert np.abs(gaps[nu_b > 0]).max() <= tol
    assert (nu_b > 0).sum() >= na // 2
    # the edge rows: f R_e . (dq_{e+1} - dq_e) = rhs_e (identities where held)
    rows = f * np.einsum("ij,ij->i", R, dq_b[1:] - dq_b[:-1]) - rhs_e
    free = (w[:-1].sum(axis=1) + w[1:].sum(axis=1)) > 0
    assert np.abs(rows[free]).max() <= 1e-13 * scale * np.abs(R).max()


def test_few_contacts_take_the_dense_solve():
    """Below ``BAND_MIN`` contacts the dense Schur complement is the cheaper solve, and the
    one taken."""
    R, O, w, f, rhs_e, na, ci, cu, cn, rhs_c, ck, mu0 = _folded(3, 200, 2.0, False)
    k = contact.BAND_MIN - 1
    args = (R, O, w, f, rhs_e, k, ci[:k], cu[:k], cn[:k], rhs_c[:k], ck, mu0[:k])
    _dq, _nu, banded = _solve(args, True)
    assert banded == 0 and ck.meta[contact._NDENSE] == 1


def test_an_unsettled_active_set_is_handed_to_the_dense_solve():
    """Two contacts on the same point with opposite normals (a node pressed from both
    sides: no solution as equations) make the active set cycle: the banded solve refuses
    them (returns False) and ``_bordered_solve`` hands them to the dense one."""
    R, O, w, f, rhs_e, na, ci, cu, cn, rhs_c, ck, mu0 = _folded(5, 200, 2.0, False)
    ci2 = np.concatenate([ci, ci[:1]])
    cu2 = np.concatenate([cu, cu[:1]])
    cn2 = np.concatenate([cn, -cn[:1]])
    rhs2 = np.concatenate([rhs_c, [-rhs_c[0] + 0.01]])
    mu2 = np.concatenate([mu0, [1.0]])
    mu2[0] = 1.0
    m = R.shape[0]
    k = na + 1
    zeros = np.zeros(k, dtype=np.int64)
    assert not contact._band_lcp(R, O, w, f, rhs_e, k, ci2, cu2, cn2, rhs2, ck,
                                 np.zeros(m + 2), np.zeros(k + 2), mu2, zeros, zeros, 1e-18)
    before = ck.meta.copy()
    contact._bordered_solve(R, O, w, f, rhs_e, k, ci2, cu2, cn2, rhs2, ck, np.zeros(m + 2),
                            np.zeros(k + 2), mu2, zeros, zeros, 1e-18)
    assert ck.meta[contact._NBAND] == before[contact._NBAND]
    assert ck.meta[contact._NDENSE] == before[contact._NDENSE] + 1


def _recorded():
    """Three complementarity problems recorded from a strip folded flat on the ground
    (fig3-strip, x = 6, 300 edges, thickness 0.0157; the first from the velocity stage,
    the others from the position stage): 121-139 contacts both ways between the layers,
    the lower layer's normal coordinates held by the ground, so about half the contact
    rows are combinations of the others (in the first, 57 singular values of the
    capacitance matrix below 1e-10 of the largest).  Block pivoting alone cycled on all
    three (the banded solve refused them)."""
    data = np.load(DATA / "redundant_stack_lcp.npz")
    return [pytest.param({key[3:]: data[key] for key in data.files
                          if key.startswith(f"p{k}_")}, id=f"recorded{k}")
            for k in range(3)]


def _kkt(p, dl, dm):
    """The update of the positions and the complementarity conditions' residuals: the
    least multiplier, the least gap after the update, the largest gap of a pushing
    contact, the largest edge-row residual relative to the rows' size for this update."""
    R, O, w, ci, cu, cn = p["R"], p["O"], p["w"], p["ci"], p["cu"], p["cn"]
    na = ci.shape[0]
    dq = np.zeros((R.shape[0] + 1, 2))
    contact._apply(dq, w, O, dl, na, ci, cu, cn, dm, 1.0)
    nu = dm[:na] + p["mu0"]
    rel = dq[ci[:, 0]] - (1 - cu)[:, None] * dq[ci[:, 1]] - cu[:, None] * dq[ci[:, 1] + 1]
    gaps = np.einsum("ij,ij->i", cn, rel) - p["rhs_c"]
    rows = p["f"] * np.einsum("ij,ij->i", R, dq[1:] - dq[:-1]) - p["rhs_e"]
    free = (w[:-1].sum(axis=1) + w[1:].sum(axis=1)) > 0
    size = p["f"] * np.abs(R).max() * np.abs(dq).max()
    return nu.min(), gaps.min(), np.abs(gaps[nu > 0]).max(), np.abs(rows[free]).max() / size


@pytest.mark.parametrize("p", _recorded())
def test_redundant_contacts_of_a_strip_lying_on_itself_are_solved_banded(p):
    """On the recorded problems the banded pivoting ends on the active set (it does not
    hand them to the dense solve), and its solution satisfies the complementarity
    conditions to the solve's tolerance (about 1e-14 of the 0.0157 thickness)."""
    m, na, tol = p["R"].shape[0], p["ci"].shape[0], float(p["tol"])
    ck = contact.new_contact_work(np.linalg.norm(p["O"], axis=1))
    dl = np.zeros(m + 2)
    dm = np.zeros(na + 2)
    assert contact._bordered_solve(p["R"], p["O"], p["w"], float(p["f"]), p["rhs_e"], na,
                                   p["ci"], p["cu"], p["cn"], p["rhs_c"], ck, dl, dm,
                                   p["mu0"], p["eq"], p["hint"], tol)
    assert ck.meta[contact._NBAND] == 1 and ck.meta[contact._NDENSE] == 0
    nu_min, gap_min, gap_push, edge_res = _kkt(p, dl, dm)
    assert nu_min >= 0.0
    assert gap_min >= -tol
    assert gap_push <= tol
    assert edge_res <= 1e-13


def _schur(p):
    """The contacts' complementarity problem ``w = S nu + q`` (``nu`` the total
    multipliers) of a recorded problem, built densely here from its definition: the
    update ``dq = W (G_O^T dl + C^T dm)``, the edge rows ``f R_e . (dq_{e+1} - dq_e) =
    rhs_e`` solved for ``dl``, the gaps ``C dq - rhs_c``."""
    R, O, w, ci, cu, cn, f = p["R"], p["O"], p["w"], p["ci"], p["cu"], p["cn"], p["f"]
    m, na = R.shape[0], ci.shape[0]
    Go = np.zeros((m, 2 * m + 2))
    Gr = np.zeros((m, 2 * m + 2))
    for e in range(m):
        Go[e, 2 * e:2 * e + 4] = np.r_[-O[e], O[e]]
        Gr[e, 2 * e:2 * e + 4] = f * np.r_[-R[e], R[e]]
    C = np.zeros((na, 2 * m + 2))
    for k, ((i, j), u, nk) in enumerate(zip(ci, cu, cn, strict=True)):
        C[k, 2 * i:2 * i + 2] += nk
        C[k, 2 * j:2 * j + 2] -= (1 - u) * nk
        C[k, 2 * j + 2:2 * j + 4] -= u * nk
    W = np.diag(w.reshape(-1))
    T = Gr @ W @ Go.T
    held = np.abs(np.diag(T)) == 0.0
    T[held] = 0.0
    T[held, held] = 1.0
    B = Gr @ W @ C.T
    B[held] = 0.0
    rhs_e = np.where(held, 0.0, p["rhs_e"])
    CWG = C @ W @ Go.T
    S = C @ W @ C.T - CWG @ np.linalg.solve(T, B)
    q = CWG @ np.linalg.solve(T, rhs_e) - p["rhs_c"] - S @ p["mu0"]
    return S, q


@pytest.mark.parametrize("p", _recorded())
def test_redundant_contacts_are_pivoted_to_the_start_of_the_dense_solve(p):
    """The dense solve's pivoting (``_lcp_guess``, which starts projected Gauss-Seidel) ends
    on the recorded problems too: it returns the solution of the shifted problem, to the
    tolerance plus the shift's own error (``shift * nu``)."""
    S, q = _schur(p)
    na, tol = p["ci"].shape[0], float(p["tol"])
    shift = contact.REGULARISATION * np.diag(S).max()
    ck = contact.new_contact_work(np.linalg.norm(p["O"], axis=1))
    nu = p["mu0"].copy()
    assert contact._lcp_guess(S, q, nu, na, p["mu0"], p["eq"], p["hint"], shift, tol, ck)
    w = S @ nu + q
    slack = tol + shift * nu.max()
    assert nu.min() >= 0.0
    assert w.min() >= -slack
    assert np.abs(w[nu > 0]).max() <= slack
