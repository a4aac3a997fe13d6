"""A damped impact run on fig3-strip settles on the static equilibrium (the spectral oracle
and the discrete strip at the run's own resolution); the difference to the spectral one
shrinks with the dynamic resolution (DER: second order in the edge length)."""

from __future__ import annotations

import numpy as np
import pytest
from spectral_strip import seeds, shape_at, strip_problem_for

from elastocap.impact import run_impact
from elastocap.scene import load_scene
from elastocap.statics.branches import newton
from elastocap.strip.model import discrete_strip_for
from elastocap.strip.solve import solve_equilibrium

X, DELTA = 2.0, 1.16
# Largest node distance (length) between the damped run's resting state and the discrete
# equilibrium at the same 200 edges (measured 5.0e-6; against the spectral oracle 2.5e-2).
GAP_SAME_N = 2e-5


def static_state():
    sc = load_scene("fig3-strip", {"drop.distance_from_end": X, "drop.wetted_length": DELTA})
    P = strip_problem_for(sc, N=16)
    for s in seeds(P):
        u = newton(P, s, DELTA, 1e-11, max_iter=40)
        if u is not None and u[-1] < P.s1:
            return P, u
    raise AssertionError("no static equilibrium")


def dynamic_gap(P, u, n):
    # damping 2 (overdamped for the slow modes) and a strict rest criterion, so that the
    # run stops on the equilibrium and not on a slow transient
    sc = load_scene(
        "fig3-strip",
        {
            "drop.distance_from_end": X,
            "drop.wetted_length": DELTA,
            "effects.damping": 2.0,
            "numerics.t_max": 60.0,
            "numerics.n_edges": n,
            "numerics.rest_kinetic": 1e-12,
            "numerics.rest_time": 2.0,
        },
    )
    res = run_impact(sc)
    assert res.status == "at_rest" and res.outcome == "encapsulated"
    pos = res.simulation.positions[-1]
    S = np.linspace(0.0, sc.rod.length, n + 1)
    ref = shape_at(P, u, S)
    off = np.mean(pos[:, 0] - ref[:, 0])  # the horizontal translation is free
    shape = max(np.max(np.abs(pos[:, 1] - ref[:, 1])), np.max(np.abs(pos[:, 0] - off - ref[:, 0])))
    measure = abs(res.final_measure - P.observables(u, DELTA)["measure"])
    return shape, measure, sc, pos


def test_damped_run_settles_on_the_equilibrium():
    P, u = static_state()
    s200, m200, sc, pos = dynamic_gap(P, u, 200)
    s300, m300, _sc, _pos = dynamic_gap(P, u, 300)
    # measured: measure gap 5.5e-3 (200 edges), 2.3e-3 (300): order ~2 (factor 2.25 per
    # 1.5x edges expected; 1.8 allows for the rest criterion)
    assert m300 < m200 / 1.8, (m200, m300)
    assert s300 < s200 / 1.5, (s200, s300)
    assert m300 < 3e-3 and s300 < 2e-2, (m300, s300)
    # the discrete strip at the run's own resolution: its energy is the dynamics' energy, so
    # the state the damped run rests on is one of its equilibria (Newton from it converges
    # next to it, stable, the same contact topology: flat, then lifted)
    S = discrete_strip_for(sc, 200)
    d = np.diff(pos, axis=0)
    u0 = np.concatenate([[max(pos[0, 1], 0.0)], np.unwrap(np.arctan2(d[:, 1], d[:, 0]))])
    eq = solve_equilibrium(S, u0, active=pos[:, 1] <= 1e-6)
    assert eq.success and eq.index == 0, eq.message
    X = S.positions(eq.u)
    gap = np.max(np.abs(X - (pos - [pos[0, 0], 0.0])))  # the horizontal translation is free
    assert gap < GAP_SAME_N, gap


@pytest.mark.slow
def test_damped_run_observed_order():
    P, u = static_state()
    ns = np.array([200, 300, 400])
    gaps = np.array([dynamic_gap(P, u, int(n))[1] for n in ns])
    order = -np.polyfit(np.log(ns), np.log(gaps), 1)[0]
    assert 1.6 < order < 2.6, f"observed order {order:.2f}, gaps {gaps}"


@pytest.mark.parametrize("integrator", ["rattle", "implicit"])
def test_the_ground_never_pulls_the_strip_down(integrator):
    # x = 2, Delta = 0.96 (above the largest Delta of a stable open state at 100 edges,
    # 0.9034): overdamped from the flat strip, the strip must lift off under the drop
    # and wrap it. RATTLE's ground used to hold the node under the drop's centre once
    # the drift took it to the ground, pulling it down with -5.0 (force; q h = 0.143):
    # the run came to rest open on no equilibrium. Independent of the dynamics: the
    # static contact equilibrium the run rests on (the discrete strip's energy is the
    # dynamics' energy), with every ground reaction compressive.
    n = 100
    sc = load_scene("fig3-strip", {
        "drop.distance_from_end": 2.0, "drop.wetted_length": 0.96, "effects.damping": 2.0,
        "numerics.t_max": 200.0, "numerics.n_edges": n, "numerics.rest_kinetic": 1e-12,
        "numerics.rest_time": 2.0, "numerics.integrator": integrator})
    res = run_impact(sc)
    assert res.status == "at_rest" and res.outcome == "encapsulated", (res.outcome,
                                                                         res.final_measure)
    # force balance with the ground's reactions (measured residual 6e-7 of |g| = 14.3):
    # all compressive, the smallest the end node's half-edge weight q h / 2 = 0.0715
    assert_rests_on_a_contact_equilibrium(sc, res, n)


def assert_rests_on_a_contact_equilibrium(sc, res, n, tol=1e-5):
    """The run's last state balances the discrete strip's forces with compressive ground
    reactions alone, and the static solver, started there, stays there (a stable state)."""
    pos = res.simulation.positions[-1]
    S = discrete_strip_for(sc, n)
    d = np.diff(pos, axis=0)
    u0 = np.concatenate([[max(pos[0, 1], 0.0)], np.unwrap(np.arctan2(d[:, 1], d[:, 0]))])
    held = S.heights(u0) <= 1e-9
    g, G = S.gradient(u0), S.constraint_jacobian(u0)[held]
    r, *_ = np.linalg.lstsq(G.T, g, rcond=None)
    assert np.max(np.abs(g - G.T @ r)) < tol
    assert np.min(r) > 0.0, np.flatnonzero(held)[r <= 0.0]
    eq = solve_equilibrium(S, u0, active=held)
    assert eq.success and eq.index == 0 and np.max(np.abs(eq.u - u0)) < tol


def test_a_node_released_at_a_lift_off_point_does_not_keep_its_kick():
    # x = 4, Delta = 1.5, damping 0.1, draft resolution (RATTLE). When the ground releases
    # a node it would pull, the drift is projected again with that node free; projecting
    # from the held solution (where the node sits on the ground and every edge has its
    # length) left it on the ground with the velocity of its kick, lifted by nothing: the
    # run never came to rest (still moving at t_max = 200 under the draft rest test).
    # Measured with the re-projection: at rest at t = 90.2 under the draft rest test, and
    # at t = 229.5 under the strict one here, on a stable contact equilibrium of the
    # discrete strip (residual 6.3e-6, 1.1e-6 from the static solution).  The rod crossed
    # itself at t = 1.40, so the outcome is undecided; without contact in the model, the
    # resting state is an equilibrium of the same energy all the same.
    sc = load_scene("fig3-strip", {
        "drop.distance_from_end": 4.0, "drop.wetted_length": 1.5, "effects.damping": 0.1,
        "numerics.accuracy": "draft", "numerics.rest_kinetic": 1e-12,
        "numerics.rest_time": 2.0, "numerics.t_max": 400.0})
    res = run_impact(sc)
    assert res.status == "at_rest", (res.status, res.t_end)
    assert_rests_on_a_contact_equilibrium(sc, res, res.settings["n_edges"])
