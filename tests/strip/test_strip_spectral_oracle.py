"""The spectral one-topology strip (the test oracle in spectral_strip.py) against closed
forms, shooting and its own spectral convergence. Tolerances are written next to each
assertion."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq
from spectral_strip import StripProblem, refine_state, seeds, strip_problem_for

from continuation import inertia_negative
from elastocap.scene import SceneError, load_scene
from elastocap.statics.branches import newton

L = 14.3


def fd_jacobian(f, v, h=1e-6):
    """Central-difference Jacobian of f at v (columns)."""
    cols = []
    for j in range(v.size):
        e = np.zeros(v.size)
        e[j] = h * max(1.0, abs(v[j]))
        cols.append((f(v + e) - f(v - e)) / (2.0 * e[j]))
    return np.column_stack(cols)


# ------------------------------------------------------------------ analytic references
def lifted_strip(F, N=12, q=1.0, B=1.0):
    """A heavy strip on a table lifted by a vertical force F at its free end (no drop:
    gamma = 0; the 'drop' segment is an ordinary one)."""
    P = StripProblem(N, L, 0.3, 0.2, 0.36, 0.0, B=B, q=q, F=F, parameter="end_force")
    u0 = np.zeros(P.n)
    u0[-1] = L - 2.0 * F / q
    u = newton(P, u0, F, tol=1e-11, max_iter=60)
    assert u is not None
    return P, u


def shooting_lift_off(F, q=1.0, B=1.0):
    """Reference by shooting the strong form: B theta'' = -cos(theta) (F - q (l - t)),
    theta(0) = theta'(0) = 0 at lift-off, theta'(l) = 0 at the free end."""

    def end(ell):
        def f(t, y):
            return [y[1], -math.cos(y[0]) * (F - q * (ell - t)) / B, math.sin(y[0])]

        s = solve_ivp(f, (0.0, ell), [0.0, 0.0, 0.0], rtol=1e-12, atol=1e-13)
        return s.y[1, -1], s.y[2, -1]

    ell = brentq(lambda v: end(v)[0], 0.5 * F / q, 2.4 * F / q, xtol=1e-14)
    return ell, end(ell)[1]


def test_point_force_linear_closed_form():
    # Linear beam theory (B w'''' = -q, w = w' = w'' = 0 at lift-off, w'' = 0 and
    # B w''' = -F at the end): lifted length l = 2F/q, end height q l^4 / (24 B), end
    # slope q l^3 / (12 B). Nonlinear corrections are O(slope^2).
    for F in (0.22, 0.25, 0.3):
        P, u = lifted_strip(F)
        ell = L - u[-1]
        slope2 = (ell**3 / 12.0) ** 2
        assert abs(ell / (2.0 * F) - 1.0) <= 0.2 * slope2, (F, ell)
        zL = P.state(u).z[-1]
        assert abs(zL / (ell**4 / 24.0) - 1.0) <= 0.5 * slope2, (F, zL)


@pytest.mark.parametrize("F", [0.25, 1.0])
def test_point_force_matches_shooting(F):
    # the nonlinear elastica (slope up to 0.9 rad at F = 1): spectral vs ODE shooting
    P, u = lifted_strip(F, N=16)
    ell, zL = shooting_lift_off(F)
    assert abs((L - u[-1]) - ell) < 1e-9
    assert abs(P.state(u).z[-1] - zL) < 1e-9
    # the lift-off point is stable (a strip lifted by its end does not peel further)
    assert inertia_negative(P.hessian(u, F)) == 0


def test_transversality_is_zero_curvature():
    # At fixed s_c, solve the theta equations only (theta'(s_c) free) and form the reduced
    # energy E(s_c). The derivation gives dE/ds_c = (B/2) theta'(s_c)^2.
    P, u = lifted_strip(0.5, N=14)
    M = P.M

    def fixed(sc, guess):
        v = guess.copy()
        v[-1] = sc
        for _ in range(30):
            r = P.residual(v, 0.5)[:M]
            if np.max(np.abs(r)) < 1e-13:
                break
            v[:M] -= np.linalg.solve(P.jacobian(v, 0.5)[:M, :M], r)
        return v

    for dsc in (0.05, -0.03):
        sc = u[-1] + dsc
        h = 1e-5
        ep = P.energy(fixed(sc + h, u), 0.5)
        em = P.energy(fixed(sc - h, u), 0.5)
        v = fixed(sc, u)
        kappa = P._lift_curvature(v)[0]
        assert abs((ep - em) / (2 * h) - 0.5 * kappa**2) < 1e-7 * max(1.0, kappa**2)
        assert abs(kappa) > 1e-3  # off the equilibrium the curvature at s_c is not zero


def wrapped(N=14, x=2.0, delta=1.16):
    sc = load_scene("fig3-strip", {"drop.distance_from_end": x, "drop.wetted_length": delta})
    P = strip_problem_for(sc, N=N)
    for s in seeds(P):
        u = newton(P, s, delta, 1e-10, max_iter=40)
        if u is not None and u[-1] < P.s1:
            return P, u
    raise AssertionError("no wrapped equilibrium found")


def test_jacobian_matches_finite_differences():
    P, u = wrapped(N=10)
    v = u + 1e-3 * np.random.default_rng(1).standard_normal(u.size)
    J = P.jacobian(v, 1.16)
    Jfd = fd_jacobian(lambda w: P.residual(w, 1.16), v)
    # central differences: relative error ~1e-8 of the largest entry (gamma ~ 40)
    assert np.max(np.abs(J - Jfd)) < 1e-6 * np.max(np.abs(J))
    # the prescribed-tip-angle variant (couple as a multiplier)
    C = StripProblem(P.Ns, L, 2.0, 1.16, 0.36, 40.0, parameter="tip_angle", tip_angle=3.0)
    w = np.concatenate([v[:-1], [0.1], v[-1:]])
    Jc = C.jacobian(w, 3.0)
    Jcfd = fd_jacobian(lambda y: C.residual(y, 3.0), w)
    assert np.max(np.abs(Jc - Jcfd)) < 1e-6 * np.max(np.abs(Jc))
    # dF/dDelta (central differences inside) against a wider central difference
    d = P.dfdp(u, 1.16)
    h = 1e-4
    d2 = (P.residual(u, 1.16 + h) - P.residual(u, 1.16 - h)) / (2 * h)
    P.set("drop.wetted_length", 1.16)
    assert np.max(np.abs(d - d2)) < 1e-5 * np.max(np.abs(d))


def test_wrapped_equilibrium_numbers():
    P, u = wrapped(N=16)
    ob = P.observables(u, 1.16)
    # reference values at N = 16 (converged to round-off, see the convergence test)
    assert abs(u[-1] - 11.471459107221) < 1e-9
    assert abs(ob["energy"] - 44.2211322722) < 1e-8
    assert abs(ob["measure"] - 1.11565) < 1e-5
    assert ob["encapsulation"] > 0
    assert inertia_negative(P.hessian(u, 1.16)) == 0
    # equilibrium of the lifted part: the lift-off reaction carries its whole weight
    assert abs(ob["reaction"] - (L - u[-1])) < 1e-12
    # torque balance about s_c: the lifted part's centre of mass is above the lift-off point
    s, x, _z = P.interp(u, 400)
    st = P.state(u)
    xc = sum(
        0.5 * ell * float(P.w[k] @ st.x[sl])
        for k, (sl, (_a, ell)) in enumerate(zip(P._slices(), P.segments(u), strict=True))
    )
    assert abs(xc) < 1e-9 * (L - u[-1])


def test_lift_off_converges_spectrally():
    # s_c of the wrapped state at x = 2, Delta = 1.16 against N = 28 per segment. Measured:
    # 7.6e-3 (N=4), 9.8e-5 (6), 1.4e-8 (10), 1.7e-10 (12), 6e-14 (14): exponential decay,
    # about one decade per added interval (with a lucky sign change near N = 8).
    sc = load_scene("fig3-strip", {"drop.distance_from_end": 2.0, "drop.wetted_length": 1.16})
    P16, u16 = wrapped(N=16)

    def lift_off(N):
        P = strip_problem_for(sc, N=N)
        _, v = refine_state(P16, u16, (N, N, N))
        u = newton(P, v, 1.16, 1e-12, max_iter=40)
        return u[-1]

    ref = lift_off(28)
    Ns = np.arange(4, 14)
    errs = np.array([abs(lift_off(int(N)) - ref) for N in Ns])
    slope = np.polyfit(Ns, np.log10(errs), 1)[0]
    # spectral: the log-error falls linearly in N; an algebraic order p would flatten
    assert slope < -0.7, f"observed rate {slope:.2f} decades per interval; errors {errs}"
    assert errs[-1] < 1e-10, errs
    assert abs(lift_off(16) - ref) < 1e-11


def test_errors_name_the_key():
    with pytest.raises(SceneError, match="gravity"):
        strip_problem_for(load_scene("supp-fig5"))
    with pytest.raises(ValueError, match="distance_from_end"):
        StripProblem(8, L, 0.4, 1.0, 0.36, 40.0)
    with pytest.raises(ValueError, match="parameter"):
        StripProblem(8, L, 2.0, 1.0, 0.36, 40.0, parameter="rod.length")

