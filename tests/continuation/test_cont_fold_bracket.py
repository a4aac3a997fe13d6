"""A located fold must be the extremum of p on its bracketing step: when Newton from one end
lands on the neighbouring fold (two folds within one step, near a cusp), the other end is
tried, and if neither works the fold is reported bracketed, never as a copy of the other."""

import numpy as np

import continuation as C
from continuation import _core
from continuation.examples import cusp_family, cusp_fold_p

S = C.ContinuationSettings(ds0=0.01, ds_max=0.2, max_steps=400, p_min=-7.0, p_max=7.0)


def _trace(monkeypatch, wrong_calls):
    """Trace the cusp branch with the first ``wrong_calls`` fold locations of each fold
    landing on the mirror fold (-p), as a Newton that went to the neighbour would."""
    real = _core._locate_fold
    calls = {"n": 0}

    def fake(ev, u, p, v0, tol, **kw):
        uf, pf, kern, ok, prec, its, msg = real(ev, u, p, v0, tol, **kw)
        calls["n"] += 1
        if calls["n"] % 2 == 1 or wrong_calls == 2:
            return -uf, -pf, kern, ok, prec, its, msg
        return uf, pf, kern, ok, prec, its, msg

    if wrong_calls:
        monkeypatch.setattr(_core, "_locate_fold", fake)
    return C.continue_branch(cusp_family(1.0), [-2.0], -6.0, S)


def test_bracket_predicate():
    # a maximum (dp/ds > 0 before it) lies at or beyond both bracketing values
    assert _core._fold_in_bracket(1.0, +1.0, 0.9, 0.95)
    assert not _core._fold_in_bracket(-1.0, +1.0, 0.9, 0.95)
    assert not _core._fold_in_bracket(0.92, +1.0, 0.9, 0.95)
    assert _core._fold_in_bracket(-1.0, -1.0, -0.9, -0.95)
    assert not _core._fold_in_bracket(1.0, -1.0, -0.9, -0.95)
    assert not _core._fold_in_bracket(0.95 + 11 * 0.05, +1.0, 0.9, 0.95)  # too far out


def test_wrong_first_newton_is_retried_from_the_other_end(monkeypatch):
    pstar = cusp_fold_p(1.0)
    br = _trace(monkeypatch, wrong_calls=1)
    ps = sorted(f.p for f in br.folds)
    assert all(f.located for f in br.folds)
    assert np.allclose(ps, [-pstar, pstar], rtol=0, atol=1e-12)


def test_fold_that_cannot_be_located_in_its_bracket_says_so(monkeypatch):
    br = _trace(monkeypatch, wrong_calls=2)
    assert len(br.folds) == 2
    for f in br.folds:
        k = f.index
        lo, hi = sorted((br.p[k - 1], br.p[k]))
        assert not f.located
        assert lo <= f.p <= hi  # the bracket, not the neighbour
        assert "converged to another fold" in f.data["message"]
        assert "reduce the continuation step" in f.data["message"]
