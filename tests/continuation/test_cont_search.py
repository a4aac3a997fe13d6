"""The deflated multi-start search on problems whose solution sets are known in closed form."""

import math

import numpy as np
import pytest

import continuation as C


def _cubic(seeds):
    # u^3 - p u = 0: u = 0 for all p and the parabola u = +-sqrt(p) (a pitchfork at p = 0)
    prob = C.FunctionProblem(lambda u, p: u**3 - p * u,
                             jacobian=lambda u, p: np.diag(3 * u**2 - p),
                             dfdp=lambda u, p: -u, name="pitchfork")
    prob.seeds = seeds
    return prob


S = C.ContinuationSettings(p_min=-1.0, p_max=2.0, ds_max=0.05, check_jacobian=False)


def test_pitchfork_both_branches_from_seeds_and_switching():
    prob = _cubic(lambda p: [np.array([0.1]), np.array([2.0]), np.array([-2.0])])
    res = C.BranchSearch(prob, S, parameter="mu").run()
    assert len(res.branches) == 2
    assert all(br.parameter == "mu" for br in res.branches)
    # one branch is u = 0 over the whole range, the other u^2 = p on (0, 2]
    trivial = [br for br in res.branches if np.max(np.abs(br.u)) < 1e-12]
    (para,) = [br for br in res.branches if br is not trivial[0]]
    assert trivial[0].p.min() == -1.0 and trivial[0].p.max() == 2.0
    # on the parabola to 1e-9 away from its tip; at the tip (u -> 0, where the steps approach
    # the fold p = 0) the residual u (u^2 - p) <= newton_tol bounds u^2 - p by newton_tol/|u|
    u, p = para.u[:, 0], para.p
    far = np.abs(u) >= 0.1
    assert np.max(np.abs(u[far] ** 2 - p[far])) < 1e-9
    assert np.all(np.abs(u * (u**2 - p)) <= S.newton_tol)
    assert para.p.max() == 2.0 and para.u[:, 0].min() < -1.4 and para.u[:, 0].max() > 1.4
    # every sample value holds exactly the solutions that exist there
    for pk, known in zip(res.samples, res.known, strict=True):
        expected = 1 + (2 if pk > 0 else 0)
        assert len(known) == expected, (pk, known)


def test_the_parabola_is_found_by_switching_when_no_seed_reaches_it():
    prob = _cubic(lambda p: [np.array([0.0])])
    res = C.search_branches(prob, S)
    assert len(res.branches) == 2
    assert [o["how"] for o in res.origins].count("switch") == 1
    assert res.stats["switches_new"] == 1


def test_deflation_finds_every_root_of_a_polynomial_from_one_seed():
    # (u - 1)(u - 2)(u - 3) = p: three branches for p in (-0.38, 0.38), joined by folds
    roots = lambda p: np.sort(np.roots([1, -6, 11, -6 - p]).real)  # noqa: E731
    prob = C.FunctionProblem(lambda u, p: (u - 1) * (u - 2) * (u - 3) - p,
                             jacobian=lambda u, p: np.atleast_2d(3 * u**2 - 12 * u + 11),
                             dfdp=lambda u, p: -np.ones(1))
    # from a seed next to the root 1, deflated against it, Newton goes elsewhere
    plain = C.deflated_newton(prob, [0.9], 0.0, tol=1e-13)
    assert plain.converged and abs(plain.u[0] - 1.0) < 1e-12
    known = [plain.u]
    for seed in (0.0, 0.9):
        r = C.deflated_newton(prob, [seed], 0.0, known, tol=1e-13)
        assert r.converged, r
        assert min(abs(r.u[0] - k[0]) for k in known) > 0.5  # a new root, never a known one
        known.append(r.u)
    assert np.allclose(sorted(k[0] for k in known), [1, 2, 3], atol=1e-12)
    # the search: one S-shaped branch with two folds, located exactly
    res = C.search_branches(prob, C.ContinuationSettings(p_min=-1.0, p_max=1.0, ds_max=0.05,
                                                         check_jacobian=False),
                            seeds=lambda p: [np.zeros(1)])
    assert len(res.branches) == 1
    folds = sorted(sp.p for sp in res.branches[0].folds)
    pf = 2 / (3 * math.sqrt(3))  # extrema of (u-1)(u-2)(u-3) at u = 2 -+ 1/sqrt(3)
    assert folds == pytest.approx([-pf, pf], abs=1e-12)
    # the sample at p = 0 knows the three roots
    k0 = int(np.argmin(np.abs(res.samples)))
    if abs(res.samples[k0]) < 1e-15:
        assert np.allclose(sorted(k[0] for k in res.known[k0]), roots(0.0), atol=1e-10)


def test_isola_found_only_with_a_sample_through_it():
    # u^2 + (p - 1)^2 = 0.04 is a circle (an isola) of radius 0.2 around p = 1
    prob = C.FunctionProblem(lambda u, p: u**2 + (p - 1.0) ** 2 - 0.04,
                             jacobian=lambda u, p: np.atleast_2d(2 * u),
                             dfdp=lambda u, p: np.atleast_1d(2 * (p - 1.0)))
    prob.seeds = lambda p: [np.array([0.5]), np.array([-0.5])]
    S2 = C.ContinuationSettings(p_min=0.0, p_max=3.0, ds_max=0.05, check_jacobian=False)
    # samples 0, 1.5, 3 miss the isola: nothing is found, and the result says so
    miss = C.search_branches(prob, S2, C.SearchSettings(samples=1))
    assert not miss.success and miss.branches == []
    # a sample at p = 1 finds it, closed on itself, with its two folds at p = 0.8 and 1.2
    hit = C.search_branches(prob, S2, C.SearchSettings(samples=1, sample_values=(1.0,)))
    (br,) = hit.branches
    assert br.status == C.LOOP_CLOSED
    # (both directions go round the loop: each fold is passed twice)
    assert sorted({round(sp.p, 10) for sp in br.folds}) == [0.8, 1.2]


def test_problem_is_not_modified_and_settings_are_validated():
    prob = _cubic(lambda p: [np.array([1.0])])
    before = dict(vars(prob))
    C.search_branches(prob, S)
    assert set(vars(prob)) == set(before)
    with pytest.raises(ValueError, match=r"SearchSettings.samples=-1: expected an integer >= 0"):
        C.SearchSettings(samples=-1)
    with pytest.raises(ValueError, match="a search needs a finite range"):
        C.BranchSearch(prob, C.ContinuationSettings())
    with pytest.raises(ValueError, match="outside the range"):
        C.BranchSearch(prob, S, C.SearchSettings(sample_values=(5.0,)))


def test_fold_crossings_of_a_cusp_family():
    # u^3 - q u - p = 0: folds at p = -+2 (q/3)^(3/2), the cusp at q = 0
    from continuation.examples import Cusp, cusp_family  # noqa: F401

    def family(q):
        return C.FunctionProblem(lambda u, p: u**3 - q * u - p,
                                 jacobian=lambda u, p: np.atleast_2d(3 * u**2 - q),
                                 dfdp=lambda u, p: -np.ones(1))

    q0 = 1.0
    br = C.continue_branch(family(q0), np.array([-2.0]), -6.0,
                           C.ContinuationSettings(p_min=-6.0, p_max=6.0, ds_max=0.1,
                                                  check_jacobian=False))
    f0 = br.folds[0]
    pts, fc = C.fold_crossings(family, f0, q0, 2.0,
                               C.ContinuationSettings(p_min=0.5, p_max=3.0, ds_max=0.05,
                                                      direction=0, check_jacobian=False))
    (u, p), = pts
    expected = 2 * (2.0 / 3) ** 1.5
    assert abs(abs(p) - expected) < 1e-10 and np.sign(p) == np.sign(f0.p)


def test_a_continuer_makes_the_branches_and_the_search_records_them():
    # min(u, u - p) = 0 has the one solution u = max(p, 0), with a corner at p = 0 where
    # the active piece changes; a continuer that knows the pieces returns it whole
    calls = []

    def continuer(problem, u, p, settings, events=None, stop_on=()):
        calls.append((settings.direction, settings.p_min, settings.p_max))
        ps = np.linspace(settings.p_min, settings.p_max, 31)
        m = ps.size
        return C.Branch(p=ps, u=np.maximum(ps, 0.0)[:, None], tangent=None, ds=np.zeros(m),
                        newton_iterations=np.zeros(m, dtype=int),
                        stability=np.zeros(m, dtype=int), observables={}, special_points=[],
                        status=C.PARAMETER_BOUND, message="two pieces joined at p = 0")

    prob = C.FunctionProblem(lambda u, p: np.minimum(u, u - p),
                             jacobian=lambda u, p: np.eye(1),
                             dfdp=lambda u, p: -(u - p < u).astype(float))
    prob.seeds = lambda p: [np.array([p + 0.3]), np.array([max(p, 0.0) + 0.2])]
    res = C.BranchSearch(prob, S, C.SearchSettings(samples=3, switch=False,
                                                   neighbour_seeds=False),
                         continuer=continuer).run()
    # one branch, made once by the continuer (both ways: direction 0, the whole range)
    assert len(res.branches) == 1 and calls == [(0, -1.0, 2.0)]
    assert res.branches[0].metadata["origin"]["how"] == "seed"
    # its crossings of every sample were recorded and Newton-corrected: max(p, 0) there,
    # so every later seed was deflated against it and none made a second branch
    for pk, known in zip(res.samples, res.known, strict=True):
        assert len(known) == 1 and abs(known[0][0] - max(pk, 0.0)) < 1e-12
