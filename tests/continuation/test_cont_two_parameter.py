"""Fold curve of Bratu on [0, L]: lam*(L) = lam*_h / L^2 exactly, also for the discrete problem.

Scaling x -> x / L maps u'' + lam e^u = 0 on [0, L] to (1 / L^2) u'' + lam e^u = 0 on
[0, 1], so the discrete fold of any discretization scales exactly as 1 / L^2.
"""

import doctest

import numpy as np

import continuation as C
from continuation.examples import Bratu


class BratuL(Bratu):
    def __init__(self, L, N=16):
        super().__init__(N, "chebyshev")
        self.L = L
        self.name = f"bratu-L={L:g}"

    def residual(self, u, p):
        return self._L @ u / self.L**2 + p * np.exp(u)

    def jacobian(self, u, p):
        return self._L / self.L**2 + np.diag(p * np.exp(u))


def test_fold_curve_scales_exactly_and_matches_one_parameter_runs():
    S = C.ContinuationSettings(ds0=0.05, ds_max=0.5, max_steps=60, p_min=0.0, p_max=4.0)
    fold = C.continue_branch(BratuL(1.0), np.zeros(15), 0.0, S).folds[0]
    lam_h = fold.p  # the discrete fold at L = 1
    fc = C.continue_fold(BratuL, fold, 1.0,
                         C.ContinuationSettings(ds0=0.05, ds_max=0.2, p_min=0.5, p_max=2.0,
                                                direction=0, max_steps=200),
                         parameter="L", events={"L=1.7": lambda U, q: q - 1.7})
    L, lam = fc.p, fc.observables["p"]
    assert fc.status == C.PARAMETER_BOUND and L.min() == 0.5 and L.max() == 2.0
    # Exact scaling of the discrete problem; limited by the Newton tolerance 1e-10.
    assert np.max(np.abs(lam * L**2 - lam_h)) < 1e-9
    assert fc.u.shape[1] == 16 and np.allclose(fc.u[:, -1], lam)  # states carry p last
    # Self-consistency: a one-parameter run at L = 1.7 finds the fold the event
    # located on the fold curve at L = 1.7.
    f17 = C.continue_branch(BratuL(1.7), np.zeros(15), 0.0, S).folds[0]
    assert abs(f17.p * 1.7**2 - lam_h) < 1e-10
    ev = fc.points("event")
    assert len(ev) == 1 and abs(ev[0].p - 1.7) < 1e-10
    assert abs(ev[0].u[-1] - f17.p) < 1e-9  # p at the event = the one-parameter fold


def test_package_docstring_examples_run():
    res = doctest.testmod(C, optionflags=doctest.ELLIPSIS)
    assert res.attempted >= 5 and res.failed == 0
    res = doctest.testmod(C._problem)
    assert res.failed == 0
