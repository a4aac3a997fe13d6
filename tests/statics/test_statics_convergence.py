"""Convergence of the fold of supp-fig5 with resolution: spectral for the LGL
(Ritz-Galerkin) discretization, algebraic for Chebyshev points with Clenshaw-Curtis
quadrature (the bending integral is then not exact: a variational crime)."""

import numpy as np
import pytest

from continuation import locate_fold
from elastocap.statics.branches import newton
from elastocap.statics.wet_elastica import WetElasticaProblem

# Fold of supp-fig5 on the encapsulated branch: LGL at N = 40, 48 and 64 agree to 2e-13.
FOLD_REF = 3.46979475156857


def _fold_at(N, nodes):
    """Locate the fold from a point next to it on the wrapped branch."""
    P = WetElasticaProblem(N, 3.48, 1.5, 1.0, 1.0, 4.6, 2.3, nodes=nodes)
    for t in (1.1, 1.05, 1.15, 1.2):
        u = newton(P, np.concatenate([0.5 * np.pi * t * P.xi, [0.0]]), 3.48, 1e-12)
        if u is not None and P.observables(u, 3.48)["measure"] > 1.06:
            break
    sp = locate_fold(P, u, 3.48)
    assert sp.located, sp.data.get("message")
    return sp.p


def test_lgl_fold_converges_spectrally():
    Ns = [6, 8, 10, 12, 14]
    errs = np.array([abs(_fold_at(N, "lgl") - FOLD_REF) for N in Ns])
    # spectral: log(error) falls linearly in N (geometric rate), not in log N
    rate = -np.polyfit(Ns, np.log(errs), 1)[0]
    algebraic = -np.polyfit(np.log(Ns), np.log(errs), 1)[0]
    assert rate > 1.0, f"geometric rate {rate:.2f} per point; errors {errs}"
    assert algebraic > 10.0, f"equivalent algebraic order {algebraic:.1f}; errors {errs}"
    # the default resolution (N = 24) reaches the round-off floor of the fold location
    assert abs(_fold_at(24, "lgl") - FOLD_REF) < 1e-11


def test_chebyshev_clenshaw_curtis_is_only_algebraic():
    Ns = [16, 24, 32, 48]
    errs = np.array([abs(_fold_at(N, "chebyshev") - FOLD_REF) for N in Ns])
    order = -np.polyfit(np.log(Ns), np.log(errs), 1)[0]
    # measured ~6: far from spectral, which is why LGL is the default
    assert 4.0 < order < 9.0, f"observed order {order:.2f}; errors {errs}"
    assert errs[-1] < 1e-9


@pytest.mark.parametrize("N", [16, 24, 40])
def test_fold_error_estimate_bounds_true_error(N):
    from elastocap.scene import load_scene
    from elastocap.statics.branches import trace_branches

    bs = trace_branches(load_scene("supp-fig5", {"numerics.cheb_points": N}))
    (fold,) = bs.folds
    true_err = abs(fold["value"] - FOLD_REF)
    # the estimate (difference to a finer resolution) is never below the true error by more
    # than the round-off floor of the fold location (~1e-13)
    assert true_err <= fold["error_estimate"] + 2e-13
