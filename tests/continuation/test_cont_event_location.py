"""Event location: the points on the arc are corrected by the chord iteration on the step's
own factorization (refactorized where it stops contracting), to the location tolerance;
the located event solves the augmented system that an independent Newton solves."""

import numpy as np
import pytest

import continuation as C
from continuation import _core
from continuation._problem import Evaluator
from continuation.examples import Bratu

S = C.ContinuationSettings(ds0=0.05, ds_max=0.5, max_steps=60, p_min=0.0, p_max=4.0)


def _newton(fun, jac, x, iters=8):
    """Plain Newton with numpy's dense solve (independent of the library's linear algebra)."""
    for _ in range(iters):
        x = x - np.linalg.solve(jac(x), fun(x))
    return x


def _on_arc_reference(prob, row, c, x0):
    """The solution of F(u, p) = 0, row . (u, p) = c near x0."""
    n = x0.size - 1

    def fun(x):
        return np.append(prob.residual(x[:n], x[n]), row @ x - c)

    def jac(x):
        J = np.asarray(prob.jacobian(x[:n], x[n]))
        return np.block([[J, prob.dfdp(x[:n], x[n])[:, None]], [row[None, :]]])

    return _newton(fun, jac, x0)


@pytest.fixture(scope="module")
def bratu_branch():
    prob = Bratu(16, "fd")
    return prob, C.continue_branch(prob, np.zeros(15), 0.0, S)


def _counting_factorize(monkeypatch):
    made = {"n": 0}
    real = _core.factorize

    def counted(A):
        made["n"] += 1
        return real(A)

    monkeypatch.setattr(_core, "factorize", counted)
    return made


def test_chord_point_is_the_newton_point_without_a_new_factorization(bratu_branch,
                                                                     monkeypatch):
    prob, br = bratu_branch
    core = _core._Core(Evaluator(prob), S, 15)
    k = 4
    xa = np.append(br.u[k - 1], br.p[k - 1])
    xb = np.append(br.u[k], br.p[k])
    ta = br.tangent[k - 1]
    row = core.wrow(ta)
    s = 0.5 * core.dot(xb - xa, ta)
    xp = xa + s * ta
    c = float(row @ xp)
    ref = _on_arc_reference(prob, row, c, xp)
    fac = _core.factorize(core.bmatrix(xb, row))  # the step's matrix, at its end
    made = _counting_factorize(monkeypatch)
    r = core.chord(xp, row, c, fac)
    assert r.ok and r.fac is fac and made["n"] == 0
    assert np.max(np.abs(r.x - ref)) <= 1e-13 * (1.0 + np.max(np.abs(ref)))
    assert np.max(np.abs(prob.residual(r.x[:15], r.x[15]))) < 1e-11


def test_chord_refactorizes_where_the_matrix_is_too_far_and_still_converges(bratu_branch,
                                                                            monkeypatch):
    prob, br = bratu_branch
    core = _core._Core(Evaluator(prob), S, 15)
    k = 3
    xa = np.append(br.u[k - 1], br.p[k - 1])
    ta = br.tangent[k - 1]
    row = core.wrow(ta)
    xp = xa + 0.02 * ta
    c = float(row @ xp)
    ref = _on_arc_reference(prob, row, c, xp)
    far = np.append(br.u[-1], br.p[-1])  # the end of the branch, on the upper part
    assert np.max(np.abs(far - xa)) > 1.0
    fac = _core.factorize(core.bmatrix(far, row))
    made = _counting_factorize(monkeypatch)
    r = core.chord(xp, row, c, fac)
    assert r.ok and made["n"] >= 1 and r.fac is not fac
    assert np.max(np.abs(r.x - ref)) <= 1e-13 * (1.0 + np.max(np.abs(ref)))


def test_chord_fails_on_a_non_finite_residual():
    prob = Bratu(16, "fd")
    core = _core._Core(Evaluator(prob), S, 15)
    x = np.append(np.full(15, 800.0), 1.0)  # exp overflows
    row = core.wrow(np.append(np.zeros(15), 1.0))
    fac = _core.factorize(core.bmatrix(np.append(np.zeros(15), 1.0), row))
    with np.errstate(all="ignore"):
        r = core.chord(x, row, float(row @ x), fac)
    assert not r.ok


def test_located_event_solves_the_augmented_system(bratu_branch):
    prob, _ = bratu_branch

    def umax_is_one(u, p):
        return float(u[7]) - 1.0  # the midpoint: the maximum of the symmetric solution

    br = C.continue_branch(prob, np.zeros(15), 0.0, S, events={"umax1": umax_is_one})
    (ev,) = br.points("event")
    assert ev.located

    def fun(x):
        return np.append(prob.residual(x[:15], x[15]), x[7] - 1.0)

    def jac(x):
        e = np.zeros(16)
        e[7] = 1.0
        J = np.asarray(prob.jacobian(x[:15], x[15]))
        return np.vstack([np.hstack([J, prob.dfdp(x[:15], x[15])[:, None]]), e])

    xs = np.linspace(0.0, 1.0, 17)[1:-1]
    ref = _newton(fun, jac, np.append(4.0 * xs * (1.0 - xs), 3.0), iters=20)
    assert np.max(np.abs(fun(ref))) < 1e-12
    # Brent's method to locate_tol = 1e-12 in arclength (dp/ds <= 1/sqrt(1 - theta))
    assert abs(ev.p - ref[15]) < 2e-12
    assert np.max(np.abs(ev.u - ref[:15])) < 2e-12


def test_event_location_leaves_the_branch_bit_identical(bratu_branch):
    prob, br = bratu_branch
    with_events = C.continue_branch(prob, np.zeros(15), 0.0, S, events={
        "umax1": lambda u, p: float(np.max(u)) - 1.0, "p2": lambda u, p: p - 2.0})
    evs = with_events.points("event")
    assert [sp.name for sp in evs] == ["p2", "umax1", "p2"]  # p = 2 up and down again
    assert all(sp.located for sp in evs)
    assert all(abs(sp.p - 2.0) < 2e-12 for sp in evs if sp.name == "p2")
    assert np.array_equal(with_events.p, br.p) and np.array_equal(with_events.u, br.u)
