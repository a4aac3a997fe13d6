"""1D Bratu u'' + lam e^u = 0, u(0) = u(1) = 0: fold at lam* = 3.513830719125161.

The continuum fold solves lam = 8 z^2 / cosh(z)^2 with z tanh(z) = 1; it is
checked here independently with mpmath. Chebyshev collocation converges
spectrally (the solution is entire), finite differences at order 2.
"""

import mpmath
import numpy as np
import pytest
import scipy.sparse as sp

import continuation as C
from continuation.examples import BRATU_FOLD, Bratu

SET = C.ContinuationSettings(ds0=0.05, ds_max=0.5, max_steps=60, p_min=0.0, p_max=4.0)


def test_reference_value_independently():
    mpmath.mp.dps = 30
    z = mpmath.findroot(lambda z: z * mpmath.tanh(z) - 1, 1.2)
    lam = 8 * z**2 / mpmath.cosh(z) ** 2
    assert abs(float(lam) - BRATU_FOLD) < 1e-15


def test_chebyshev_fold_exact_and_spectral():
    # Chebyshev degree 24 already resolves the fold to rounding (spectral
    # convergence of an entire solution); degree 32 is the converged reference.
    br = C.continue_branch(Bratu(32, "chebyshev"), np.zeros(31), 0.0, SET)
    folds = br.folds
    assert len(folds) == 1 and folds[0].located
    assert abs(folds[0].p - BRATU_FOLD) < 1e-10  # spectral: observed ~3e-14
    assert folds[0].precision < 1e-10
    # Self-consistency: at the fold the state solves F = 0 and dF/du is singular.
    prob = Bratu(32, "chebyshev")
    f = folds[0]
    assert np.max(np.abs(prob.residual(f.u, f.p))) < 1e-9
    smin = np.linalg.svd(prob.jacobian(f.u, f.p), compute_uv=False)[-1]
    assert smin < 1e-9
    # Spectral convergence: each +4 in degree gains > 2 digits (observed
    # 6.9e-5, 1.9e-7, 1.3e-9, 1.0e-11 for N = 8, 12, 16, 20).
    errs = [abs(C.continue_branch(Bratu(N, "chebyshev"), np.zeros(N - 1), 0.0, SET).folds[0].p
                - BRATU_FOLD) for N in (8, 12, 16, 20)]
    print("Chebyshev fold errors N=8,12,16,20:", errs)
    assert errs[-1] < 1e-10, errs
    assert all(b < a / 50 for a, b in zip(errs, errs[1:], strict=False)), errs


def test_fd_observed_order_two():
    Ns = [10, 20, 40, 80]
    errs = []
    for N in Ns:
        br = C.continue_branch(Bratu(N, "fd"), np.zeros(N - 1), 0.0, SET)
        errs.append(abs(br.folds[0].p - BRATU_FOLD))
    slope = -np.polyfit(np.log(Ns), np.log(errs), 1)[0]
    print(f"observed FD order {slope:.4f}, errors {errs}")
    assert abs(slope - 2.0) < 0.05, f"observed order {slope:.4f}"  # h^2 truncation error
    assert errs[-1] < 3e-4  # error = 1.83 h^2 (observed constant), 2.86e-4 at N = 80
    # Richardson extrapolation of the two finest levels lands on the continuum value.
    rich = (4 * (BRATU_FOLD - errs[-1]) - (BRATU_FOLD - errs[-2])) / 3
    assert abs(rich - BRATU_FOLD) < 1e-6  # next term is O(h^4) ~ 1e-8


def test_fd_fold_dense_sparse_banded_agree_and_stability():
    N = 40
    dense = C.continue_branch(Bratu(N, "fd"), np.zeros(N - 1), 0.0, SET)
    sparse = C.continue_branch(Bratu(N, "fd", sparse=True), np.zeros(N - 1), 0.0, SET)

    class Banded(Bratu):
        def jacobian(self, u, p):
            h2 = self.N**2
            n = u.size
            ab = np.empty((3, n))
            ab[0] = h2
            ab[1] = -2 * h2 + p * np.exp(u)
            ab[2] = h2
            return C.BandedJacobian(1, 1, ab)

    banded = C.continue_branch(Banded(N, "fd"), np.zeros(N - 1), 0.0, SET)
    pf = dense.folds[0].p
    # The discrete fold is one number; three linear solvers agree to rounding.
    assert abs(sparse.folds[0].p - pf) < 1e-12
    assert abs(banded.folds[0].p - pf) < 1e-12
    assert sp.issparse(Bratu(N, "fd", sparse=True).jacobian(np.zeros(N - 1), 1.0))
    # Energy Hessian: lower branch stable (index 0), upper branch index 1.
    k = dense.folds[0].index
    assert set(dense.stability[:k]) == {0}
    assert set(dense.stability[k:]) == {1}
    stab = dense.points("stability")
    assert len(stab) == 1 and stab[0].data["stability"] == [0, 1]
    assert stab[0].data["at"] == "fold" and stab[0].located and stab[0].p == pf


def test_both_directions_moore_penrose_and_observables():
    prob = Bratu(24, "chebyshev")
    s = SET.replace(direction=0, corrector="moore-penrose")
    br = C.continue_branch(prob, np.zeros(23), 1.0, s)
    # Backward end at p_min = 0 exactly (the trivial solution), forward runs past the fold.
    assert br.p[0] == 0.0 and np.max(np.abs(br.u[0])) < 1e-9
    assert abs(br.folds[0].p - BRATU_FOLD) < 1e-11
    assert br.metadata["end_status"][0] == "parameter_bound"
    # Observables recorded at every point and consistent with the states.
    assert np.allclose(br.observables["u_max"], br.u.max(axis=1), rtol=0, atol=1e-14)
    # No jumps between halves: |dp| <= ds_max / sqrt(1 - theta) = 0.707 per step.
    assert np.max(np.abs(np.diff(br.p))) <= 0.5 / np.sqrt(0.5) + 1e-12
    assert br.branch_points == []  # none on Bratu (a spurious one at the join was a bug)


def test_start_at_the_fold_and_locate_from_crude_guess():
    prob = Bratu(20, "chebyshev")
    # A crude guess: the exact lower-branch shape at lam = 3 with a 5% wrong amplitude.
    br = C.continue_branch(prob, np.zeros(19), 0.0, SET.replace(p_max=3.0))
    u3 = br.u[-1]
    f = C.locate_fold(prob, 1.05 * u3, 3.0)
    assert f.located and abs(f.p - BRATU_FOLD) < 1e-10  # N=20 Chebyshev: error ~1e-12
    # Starting exactly at the fold, where dF/du is singular, still works.
    b2 = C.continue_branch(prob, f.u, f.p, SET.replace(direction=0, max_steps=5))
    assert b2.status == C.MAX_STEPS and len(b2) == 11
    assert np.all(b2.p <= f.p + 1e-12)  # both halves go down in lam from the fold


def test_fd_fallback_warns_once_and_stays_exact():
    base = Bratu(16, "chebyshev")
    prob = C.FunctionProblem(base.residual, name="bratu-no-derivatives")
    with pytest.warns(C.FiniteDifferenceWarning, match="jacobian .dF/du. and dfdp"):
        br = C.continue_branch(prob, np.zeros(15), 0.0, SET)
    # The fold's defining system is solved exactly; finite differences only
    # enter Newton's matrix, so the fold agrees with the analytic run.
    ref = C.continue_branch(base, np.zeros(15), 0.0, SET).folds[0].p
    assert abs(br.folds[0].p - ref) < 1e-10
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a second run on the same object does not warn
        br2 = C.continue_branch(prob, np.zeros(15), 0.0, SET.replace(max_steps=3))
    assert len(br2) == 4


def test_tangent_det_sign_is_the_bordered_determinants_sign():
    # the sign continue_branch takes for a given tangent t = a (w, 1), dF/du w = -dF/dp:
    # sign(det dF/du) sign(dp/ds), against numpy's slogdet of the bordered matrix on both
    # sides of the fold (where both factors flip); and the branch with it given is the
    # branch with it computed, bit for bit
    prob = Bratu(24, "chebyshev")
    br = C.continue_branch(prob, np.zeros(23), 0.0, SET)
    assert len(br.folds) == 1
    k_fold = int(np.argmin(np.abs(br.p - br.folds[0].p)))
    for k in (3, k_fold - 4, k_fold + 4, len(br.p) - 3):
        u, p = br.u[k], float(br.p[k])
        J, fp = prob.jacobian(u, p), prob.dfdp(u, p)
        fac = C.factorize(J.copy())
        w = fac.solve(-fp)
        for a in (1.0, -1.0):
            t = a * np.append(w, 1.0) / np.linalg.norm(np.append(w, 1.0))
            sign = fac.det_sign() * (1 if t[-1] > 0 else -1)
            ref = np.linalg.slogdet(np.block([[J, fp[:, None]], [t[None, :]]]))[0]
            assert sign == ref
    st = SET.replace(direction=1, max_steps=15)
    u, p = br.u[5], float(br.p[5])
    J, fp = prob.jacobian(u, p), prob.dfdp(u, p)
    fac = C.factorize(J.copy())
    t = np.append(fac.solve(-fp), 1.0)
    a = C.continue_branch(prob, u, p, st, tangent=t)
    b = C.continue_branch(prob, u, p, st, tangent=t, tangent_det_sign=fac.det_sign())
    assert np.array_equal(a.p, b.p) and np.array_equal(a.u, b.u)
    assert np.array_equal(a.stability, b.stability)
    with pytest.raises(ValueError, match="tangent_det_sign: got 0"):
        C.continue_branch(prob, u, p, st, tangent=t, tangent_det_sign=0)
