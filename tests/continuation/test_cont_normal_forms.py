"""Normal forms with closed-form answers: pitchfork, transcritical, cusp (two parameters)."""

import numpy as np

import continuation as C
from continuation.examples import Pitchfork, cusp_family, cusp_fold_p

S = C.ContinuationSettings(ds0=0.01, ds_max=0.1, max_steps=200, p_min=-1.0, p_max=1.0)


def test_pitchfork_branch_point_and_switch_lands_on_parabola():
    br = C.continue_branch(Pitchfork(), [0.0], -1.0, S)
    assert br.status == C.PARAMETER_BOUND and br.p[-1] == 1.0  # ends exactly on p_max
    bps = br.branch_points
    assert len(bps) == 1 and bps[0].located
    assert abs(bps[0].p) < 1e-12  # brentq to locate_tol = 1e-12 in arclength
    # Stability of the trivial branch: E'' = -p, index 0 before, 1 after.
    assert set(br.stability[br.p < -1e-9]) == {0}
    assert set(br.stability[br.p > 1e-9]) == {1}
    nb = C.switch_branch(Pitchfork(), bps[0], S)
    x = nb.observables["x"]
    # Both halves of x^2 = p, to the Newton tolerance 1e-10 on F = x (p - x^2).
    assert np.max(np.abs(x**2 - nb.p)) < 1e-9
    assert x.min() < -0.99 and x.max() > 0.99  # x = -1 ... +1 (p_max = 1 reached twice)
    dx = np.diff(x)
    assert np.all(dx > 0) or np.all(dx < 0)  # one monotone curve through the branch point
    assert set(nb.stability[np.abs(x) > 1e-6]) == {0}  # supercritical: stable, E'' = 2p
    sw = nb.points("branch_point")
    assert len(sw) == 1 and abs(nb.p[sw[0].index]) < 1e-12


def test_transcritical_switch_is_not_orthogonal():
    # F = x (p - x): branches x = 0 and x = p cross at 45 degrees, so the new
    # direction is NOT the kernel vector orthogonal to the old tangent; the
    # algebraic bifurcation equation must give it.
    prob = C.FunctionProblem(lambda u, p: u * (p - u),
                             jacobian=lambda u, p: np.atleast_2d(p - 2 * u),
                             dfdp=lambda u, p: u.copy(), name="transcritical")
    br = C.continue_branch(prob, [0.0], -0.5, S.replace(p_min=-0.5, p_max=0.5))
    bp = br.branch_points[0]
    nb = C.switch_branch(prob, bp, S.replace(p_min=-0.5, p_max=0.5))
    x = nb.u[:, 0]
    assert np.max(np.abs(x - nb.p)) < 1e-10  # the branch x = p, not x = 0
    assert nb.p.min() == -0.5 and nb.p.max() == 0.5


def test_cusp_folds_and_fold_curve_against_closed_form():
    br = C.continue_branch(cusp_family(1.0), [-2.0], -6.0,
                           S.replace(ds_max=0.2, p_min=-7.0, p_max=7.0))
    folds = br.folds
    assert len(folds) == 2
    pstar = cusp_fold_p(1.0)  # 2 / 3^{3/2}
    assert sorted(f.p for f in folds) == [-pstar, pstar] or np.allclose(
        sorted(f.p for f in folds), [-pstar, pstar], rtol=0, atol=1e-13)
    # Fold curve in q, through the cusp and back along the other fold.
    fc = C.continue_fold(cusp_family, folds[0], 1.0,
                         S.replace(ds_max=0.1, p_min=-0.5, p_max=2.0, direction=0))
    q = fc.p
    pf = fc.observables["p"]
    x = fc.observables["x"]
    assert fc.parameter == "q"
    assert np.max(np.abs(np.abs(pf) - cusp_fold_p(q))) < 1e-9  # Newton tol 1e-10 on F, g
    assert np.max(np.abs(3 * x**2 - q)) < 1e-9  # dF/dx = 0 on the fold curve
    assert q.min() < 0.01 and np.sum(q > 1.99) == 2  # passed the cusp, both ends at q = 2
    cusps = fc.folds  # q turns back at the cusp: a fold of the fold curve in q
    assert len(cusps) == 1 and abs(cusps[0].p) < 1e-8
    assert np.all(np.sign(pf[q > 0.01]) == -np.sign(x[q > 0.01]))  # p = -2 x^3 on the curve


def test_isola_closes_with_two_exact_folds():
    # u^2 + p^2 = 1: a closed branch with folds at p = +-1 (u = 0).
    prob = C.FunctionProblem(lambda u, p: u**2 + p**2 - 1.0,
                             jacobian=lambda u, p: np.atleast_2d(2 * u),
                             dfdp=lambda u, p: np.atleast_1d(2 * p), name="circle")
    br = C.continue_branch(prob, [1.0], 0.0, S.replace(p_min=-2.0, p_max=2.0))
    assert br.status == C.LOOP_CLOSED
    folds = sorted(f.p for f in br.folds)
    assert np.allclose(folds, [-1.0, 1.0], rtol=0, atol=1e-14)  # quadratic Newton, exact
    assert np.max(np.abs(br.u[:, 0] ** 2 + br.p**2 - 1)) < 1e-10
