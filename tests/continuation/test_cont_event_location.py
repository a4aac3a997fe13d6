"""Event location: the points on the arc are corrected by the chord iteration on the step's
own factorization (refactorized where it stops contracting), to the location tolerance;
the located event solves the augmented system that an independent Newton solves."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

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


@pytest.mark.parametrize("steps", [False, True])
def test_event_location_leaves_the_branch_bit_identical(bratu_branch, steps):
    # without the approach step control (event_steps) the events change nothing of the
    # branch; with it, the steps approaching each event, not the curve
    prob, br = bratu_branch
    with_events = C.continue_branch(prob, np.zeros(15), 0.0, S.replace(event_steps=steps),
                                    events={"umax1": lambda u, p: float(np.max(u)) - 1.0,
                                            "p2": lambda u, p: p - 2.0})
    evs = with_events.points("event")
    assert [sp.name for sp in evs] == ["p2", "umax1", "p2"]  # p = 2 up and down again
    assert all(sp.located for sp in evs)
    assert all(abs(sp.p - 2.0) < 2e-12 for sp in evs if sp.name == "p2")
    if not steps:
        assert np.array_equal(with_events.p, br.p) and np.array_equal(with_events.u, br.u)
        return
    assert not np.array_equal(with_events.p[:len(br.p)], br.p)
    res = max(float(np.max(np.abs(prob.residual(u, p))))
              for u, p in zip(with_events.u, with_events.p, strict=True))
    assert res <= S.newton_tol
    # the fold is the same point of the curve (measured: 9e-16 apart)
    f0, f1 = br.points("fold"), with_events.points("fold")
    assert len(f0) == len(f1) and all(abs(a.p - b.p) < 1e-12 for a, b in zip(f0, f1, strict=True))


# ---------------------------------------------------------------- vector events
# On u = p (one unknown) an event's entries are functions of p alone, so the first root of
# their minimum is known in closed form.
LINE = C.FunctionProblem(lambda u, p: u - p, jacobian=lambda u, p: np.eye(1),
                         dfdp=lambda u, p: -np.ones(1), name="line")
LS = C.ContinuationSettings(ds0=0.05, ds_max=0.4, max_steps=40, p_min=0.0, p_max=3.0)


def _counting_bisect(monkeypatch):
    calls = {"bisect": 0}
    real = _core._bisect_on_arc

    def counted(*a, **k):
        calls["bisect"] += 1
        return real(*a, **k)

    monkeypatch.setattr(_core, "_bisect_on_arc", counted)
    return calls


def _located(events, monkeypatch=None):
    calls = _counting_bisect(monkeypatch) if monkeypatch is not None else {}
    br = C.continue_branch(LINE, np.zeros(1), 0.0, LS, events=events)
    return list(br.points("event")), calls


@settings(max_examples=25, deadline=None)
@given(a=st.lists(st.floats(0.3, 2.7), min_size=1, max_size=6),
       b=st.lists(st.floats(0.0, 0.3), min_size=6, max_size=6))
def test_a_vector_event_is_located_at_its_smallest_entrys_first_root(a, b):
    # entries a_i - p - b_i p^2 (b_i >= 0): each falls through one root in (0, 3); the
    # minimum's first root is the smallest of them (the quadratic formula, in its form
    # without cancellation)
    a, b = np.array(a), np.array(b[:len(a)])

    def entries(u, p):
        return a - p - b * p * p

    first = float(np.min(2.0 * a / (1.0 + np.sqrt(1.0 + 4.0 * a * b))))
    evs, _ = _located({"vec": entries})
    assert evs and evs[0].located
    assert abs(evs[0].p - first) < 2e-12
    # the same root as the scalar event of their minimum (Brent's method on its kinks)
    scalar, _ = _located({"min": lambda u, p: float(np.min(entries(u, p)))})
    assert abs(scalar[0].p - evs[0].p) < 2e-12


def test_a_rising_vector_event_is_located_where_its_last_negative_entry_turns(monkeypatch):
    a = np.array([0.7, 1.3, 1.1])
    evs, calls = _located({"vec": lambda u, p: p - a}, monkeypatch)
    (ev,) = evs
    assert ev.located and abs(ev.p - 1.3) < 2e-12
    assert calls["bisect"] == 1  # on the entry, accepted


def test_an_entry_crossing_first_against_the_linear_guess_falls_back(monkeypatch):
    # the second entry is convex: over a step from above 0.8 to past 1 it turns negative
    # first (at 0.8 + ln 3 / 20) while the linear interpolation of the step's ends puts the
    # first entry's crossing (p = 1) earlier; the entry is then located on the minimum
    def entries(u, p):
        return np.array([1.0 - p, 0.15 * np.exp(-20.0 * (p - 0.8)) - 0.05])

    calls = _counting_bisect(monkeypatch)
    st_ = LS.replace(ds0=0.4, ds_max=0.4)
    br = C.continue_branch(LINE, np.array([0.8]), 0.8, st_, events={"vec": entries})
    ev = br.points("event")[0]
    assert br.p[1] > 1.0  # one step over both roots
    assert calls["bisect"] == 2  # the entry's root refused, then the minimum's
    assert ev.located and abs(ev.p - (0.8 + np.log(3.0) / 20.0)) < 2e-12


def test_an_event_returning_a_matrix_is_refused():
    with pytest.raises(ValueError, match=r"shape \(1, 2\).*1-D array"):
        C.continue_branch(LINE, np.zeros(1), 0.0, LS,
                          events={"m": lambda u, p: np.ones((1, 2))})


@pytest.mark.parametrize("vector", [False, True])
def test_an_event_crossing_and_back_inside_a_step_cut_by_a_terminal_event_is_located(vector):
    # on the line u = p, one step from 0.8 to past 1.1: "dip" is negative on (0.9, 1.0)
    # only (both of its roots in the step, its value positive at both ends), "corner"
    # (terminal) has its root at 0.95, inside that interval. The run ends at the corner,
    # where "dip" is negative: its root at 0.9, between the step's start and the corner,
    # is located (before, the run stopped at the corner with "dip" unseen).
    def dip(u, p):
        d = (p - 0.9) * (p - 1.0)
        return np.array([d, 1.0]) if vector else d

    def corner(u, p):
        return 0.95 - p

    st_ = LS.replace(ds0=0.4, ds_max=0.4)
    br = C.continue_branch(LINE, np.array([0.8]), 0.8, st_,
                           events={"dip": dip, "corner": corner},
                           stop_on=("corner",))
    assert br.p[1] > 1.1 and br.status == C.STOPPED  # one step over both roots
    evs = {sp.name: sp for sp in br.points("event")}
    assert set(evs) == {"dip", "corner"}
    assert evs["corner"].located and abs(evs["corner"].p - 0.95) < 2e-12
    assert evs["dip"].located and evs["dip"].index == 1 and abs(evs["dip"].p - 0.9) < 2e-12
    # the dip's second root (1.0) lies past the corner, where the run ends
    assert [sp.name for sp in br.points("event")].count("dip") == 1
    # without the terminal event both of the dip's roots are located (_event_dip) ...
    free = C.continue_branch(LINE, np.array([0.8]), 0.8, st_.replace(p_max=1.2),
                             events={"dip": dip})
    assert free.p[1] > 1.1
    roots = sorted(sp.p for sp in free.points("event") if sp.located)
    assert len(roots) == 2 and abs(roots[0] - 0.9) < 2e-12 and abs(roots[1] - 1.0) < 2e-12
    # ... which the step's ends alone do not see: no sign change there, no event
    ends = C.continue_branch(LINE, np.array([0.8]), 0.8,
                             st_.replace(p_max=1.2, event_dips=False), events={"dip": dip})
    assert np.array_equal(ends.p, free.p) and not ends.points("event")


# ---------------------------------------------------------------- dips inside one step
# On the line u = p, one step of 0.4 from 0.8 to 1.2: g = cosh(6 (p - 1)) - cosh(0.9) is
# 0.378 at both ends and negative on (0.85, 1.15) only, down to -0.433 at p = 1: both roots
# inside the step, 0.3 apart. Not a cubic, so the interpolant only points at the dip.
DIP_C = np.cosh(0.9)


def _cosh_dip(vector):
    def g(u, p):
        d = np.cosh(6.0 * (p - 1.0)) - DIP_C
        return np.array([2.0, d, 1.0]) if vector else float(d)

    return g


@pytest.mark.parametrize("vector", [False, True])
def test_an_event_crossing_and_back_inside_one_step_is_located_at_both_roots(vector):
    st_ = LS.replace(ds0=0.4, ds_max=0.4, p_max=1.2)
    br = C.continue_branch(LINE, np.array([0.8]), 0.8, st_, events={"dip": _cosh_dip(vector)})
    assert list(br.p) == pytest.approx([0.8, 1.2], abs=1e-14)  # one step over the dip
    evs = br.points("event")
    assert [sp.index for sp in evs] == [1, 1] and all(sp.located for sp in evs)
    roots = sorted(sp.p for sp in evs)
    assert abs(roots[0] - 0.85) < 2e-12 and abs(roots[1] - 1.15) < 2e-12
    # compared at the step's ends only, the event is not seen
    ends = C.continue_branch(LINE, np.array([0.8]), 0.8, st_.replace(event_dips=False),
                             events={"dip": _cosh_dip(vector)})
    assert np.array_equal(ends.p, br.p) and not ends.points("event")


@pytest.mark.parametrize("vector", [False, True])
def test_a_terminal_event_dipping_inside_a_step_stops_the_run_at_its_first_root(vector):
    st_ = LS.replace(ds0=0.4, ds_max=0.4)
    br = C.continue_branch(LINE, np.array([0.8]), 0.8, st_, events={"dip": _cosh_dip(vector)},
                           stop_on=("dip",))
    assert br.status == C.STOPPED and len(br.p) == 2
    (ev,) = br.points("event")
    assert ev.located and abs(ev.p - 0.85) < 2e-12


def test_an_event_that_comes_near_zero_without_crossing_gives_none():
    # cosh(6 (p - 1)) - 0.95: 0.05 at p = 1, its least value; the cubic through the ends'
    # values (0.861) and slopes (-+9.06) dips to -0.045 there, the corrected point says 0.05
    def near(u, p):
        return float(np.cosh(6.0 * (p - 1.0)) - 0.95)

    calls = {"n": 0}
    real = _core._point_at

    def counted(*a, **k):
        calls["n"] += 1
        return real(*a, **k)

    st_ = LS.replace(ds0=0.4, ds_max=0.4, p_max=1.2)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(_core, "_point_at", counted)
        br = C.continue_branch(LINE, np.array([0.8]), 0.8, st_, events={"near": near})
    assert len(br.p) == 2 and not br.points("event")
    assert 1 <= calls["n"] <= _core._DIP_POINTS
