"""Hard cases of the statics: Delta = L and Delta = 0.02 L, two folds within one
continuation step near the cusp (A = 1.74), continuation started exactly at a fold and at a
branch point, and a high resolution (N = 64)."""

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "statics"))

from test_statics_convergence import FOLD_REF  # noqa: E402

from continuation import ContinuationSettings, continue_branch, locate_fold  # noqa: E402
from elastocap.scene import SceneError, load_scene  # noqa: E402
from elastocap.statics.branches import newton, problem_for, trace_branches  # noqa: E402
from elastocap.statics.wet_elastica import WetElasticaProblem  # noqa: E402


@pytest.fixture(scope="module")
def default_set():
    return trace_branches(load_scene("supp-fig5"))


def _end_states(bs, value):
    """(measure, stability) of every admissible branch end at parameter ``value`` (the
    inverted branch, stable but with the interface through the rod, is left out)."""
    out = []
    for br in bs.branches:
        for i in (0, len(br) - 1):
            if br.p[i] == value and br.observables["admissible"][i] == 1.0:
                out.append((float(br.observables["measure"][i]), int(br.stability[i])))
    return out


def test_delta_equal_to_rod_length(default_set):
    """Delta = L exactly (the range's end): the flat and the encapsulated branch both end
    there, stable, and agree with N = 40 to 1e-8 (spectral: the default is converged)."""
    L = 4.6
    ends = _end_states(default_set, L)
    fine = _end_states(
        trace_branches(
            load_scene("supp-fig5", {"numerics.cheb_points": 40}), error_estimates=False
        ),
        L,
    )
    stable = sorted(m for m, s in ends if s == 0)
    stable_fine = sorted(m for m, s in fine if s == 0)
    assert len(stable) == 2 and stable[0] < 0.59 and stable[1] > 1.05, ends
    assert np.allclose(stable, stable_fine, atol=1e-8), (stable, stable_fine)


def test_tiny_wetted_length():
    """Delta = 0.02 L: the drop is a nearly closed circle on a short chord (A/Delta^2 =
    177); the flat solution converges and is resolution-independent to 1e-12."""
    d = 0.02 * 4.6
    ms = []
    for N in (16, 24, 40):
        P = problem_for(load_scene("supp-fig5", {"drop.wetted_length": d}), N=N)
        u = newton(P, np.zeros(P.N + 2), d, 1e-12)
        assert u is not None
        obs = P.observables(u, d)
        assert 2 * np.pi - abs(obs["cap_angle"]) < 0.2  # nearly closed (measured 0.133)
        ms.append(obs["measure"])
    assert 0 < ms[-1] < 1e-4
    assert max(ms) - min(ms) < 1e-12, ms


def test_two_close_folds_near_the_cusp_are_both_located():
    """A = 1.74, just below the cusp (1.745): the Delta-branch turns twice within 1.3e-3, in
    one continuation step. Both folds are located, distinct, ordered, with the right
    stability changes (regression: the second was relocated onto the first and merged)."""
    bs = trace_branches(load_scene("supp-fig5", {"drop.area": 1.74}))
    folds = [f for f in bs.folds if f["located"]]
    assert len(folds) == 2, bs.folds
    lo, hi = folds
    assert lo["value"] < hi["value"]
    # measured: 3.5408030960017 (1->0, M = 0.9033) and 3.5421186851927 (0->1, M = 0.8546)
    assert hi["value"] - lo["value"] == pytest.approx(1.3156e-3, rel=1e-3)
    assert lo["stability_change"] == "1->0" and hi["stability_change"] == "0->1"
    assert lo["measure"] > hi["measure"]
    for f in folds:
        assert f["error_estimate"] < 1e-10
        assert f["error_estimate"] < 1e-6 * (hi["value"] - lo["value"])


def _fold_state(N=24):
    P = WetElasticaProblem(N, 3.48, 1.5, 1.0, 1.0, 4.6, 2.3)
    for t in (1.1, 1.05, 1.15, 1.2):
        u = newton(P, np.concatenate([0.5 * np.pi * t * P.xi, [0.0]]), 3.48, 1e-12)
        if u is not None and P.observables(u, 3.48)["measure"] > 1.06:
            break
    sp = locate_fold(P, u, 3.48)
    assert sp.located
    return P, sp


def _settings(lo, hi):
    return ContinuationSettings(
        ds0=0.01,
        ds_min=1e-9,
        ds_max=0.02,
        max_steps=400,
        p_min=lo,
        p_max=hi,
        direction=0,
        newton_tol=1e-11,
        max_turn=0.2,
        check_jacobian=False,
    )


def test_continuation_started_exactly_at_the_fold():
    """dF/du is singular at the start: the tangent comes from the null vector, both
    directions leave the fold to the bound, one stable, one unstable, and the fold is
    found again on the way at the same value."""
    P, sp = _fold_state()
    assert abs(sp.p - FOLD_REF) < 1e-11
    br = continue_branch(P, sp.u, sp.p, _settings(3.3, 3.7))
    assert br.p[0] == pytest.approx(3.7) and br.p[-1] == pytest.approx(3.7), br.message
    assert br.p.min() >= sp.p - 1e-12  # nothing on this branch lies left of its fold
    assert sorted({int(br.stability[0]), int(br.stability[-1])}) == [0, 1]
    (again,) = br.folds
    assert abs(again.p - sp.p) < 1e-12


def test_continuation_started_exactly_at_a_branch_point(default_set):
    bp = default_set.branch_points[0]
    br0 = default_set.branches[bp["branch"]]
    sp = next(s for s in br0.branch_points if abs(s.p - bp["value"]) < 1e-9)
    P = default_set.problem
    br = continue_branch(P, sp.u, sp.p, _settings(sp.p - 0.3, min(sp.p + 0.3, 4.6)))
    assert len(br) > 5 and np.all(np.isfinite(br.p)), br.message
    assert br.status in (0, 1) or "bound" in br.message or "contact" in br.message, br.message
    # the start solves F = 0 and the run moves away from it
    assert np.max(np.abs(br.p - sp.p)) > 0.05


def test_high_resolution_n64_is_stable():
    bs = trace_branches(load_scene("supp-fig5", {"numerics.cheb_points": 64}))
    assert len(bs.branches) == 5
    (fold,) = bs.folds
    assert abs(fold["value"] - FOLD_REF) < 1e-11
    assert fold["error_estimate"] < 1e-11


def test_too_coarse_resolution_is_refused_clearly():
    with pytest.raises(SceneError, match=r"^numerics.cheb_points: got 3; expected at least 4"):
        problem_for(load_scene("supp-fig5"), N=3)
