"""Statics of the strip with self-contact (a thickness d; elastocap.strip with
``rod.thickness``): node-segment pairs held like the ground's contacts.

Checked against independent sources: the dynamics' brute-force node-segment distance
(``dynamics.contact.segment_distances``), finite differences of the gaps, the statics of a
tail lying flat on the base (each lying node carries its weight), the active-set Newton
method at the located contact fold, the same trace without a thickness from the revision
before self-contact (bit for bit), and a damped impact run with the same thickness that
comes to rest on the hairpin (slow). Tolerances are written next to each assertion."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from continuation import ContinuationSettings
from dynamics.contact import segment_distances
from elastocap.geometry import count_crossings
from elastocap.scene import load_scene
from elastocap.strip.model import (
    DiscreteStrip,
    closest_segments,
    discrete_strip_for,
    pair_gaps,
    pair_hessian,
    pair_jacobian,
)
from elastocap.strip.solve import solve_equilibrium, wrapped_state
from elastocap.strip.trace import DEFAULTS, trace_contact_branches, trace_discrete_branch

#: The paper's strip thickness h = 55 um in l_eg = 3.4996 mm.
D = 0.0157


def _hairpin_scene(delta=1.2, **kw):
    return load_scene("fig3-strip", {"drop.distance_from_end": 3.0, "drop.wetted_length": delta,
                                     "rod.thickness": D, **kw})


@pytest.fixture(scope="module")
def hairpin100():
    """The encapsulated hairpin at x = 3, Delta = 1.2, n = 100, with contact."""
    st = discrete_strip_for(_hairpin_scene(), 100)
    return st, wrapped_state(st)


def _fd(f, u, eps=1e-6):
    E = np.eye(u.size)
    return np.array([(f(u + eps * E[k]) - f(u - eps * E[k])) / (2 * eps) for k in range(u.size)])


def test_pair_gaps_and_their_derivatives():
    st = DiscreteStrip(20, 3.0, 1.0, 0.5, 0.36, 0.0, thickness=0.05)
    u = np.random.default_rng(0).normal(size=st.size) * 0.5
    P = np.array([[15, 3, 1], [2, 12, -1], [19, 0, 0], [3, 17, 0]])
    X = st.positions(u)
    gap, region = pair_gaps(st, u, P)
    # line pair: the signed distance to the segment's line (cross product), point pair:
    # the distance between the nodes; to round-off
    for a, (i, j, sg) in enumerate(P):
        if sg:
            e = X[j + 1] - X[j]
            d = (e[0] * (X[i, 1] - X[j, 1]) - e[1] * (X[i, 0] - X[j, 0])) / np.hypot(*e)
            assert abs(sg * d - st.thickness - gap[a]) < 1e-14
        else:
            assert abs(np.hypot(*(X[i] - X[j])) - st.thickness - gap[a]) < 1e-14
    # exact Jacobian and Hessian against centred differences (eps = 1e-6: error ~1e-10)
    J = pair_jacobian(st, u, P)
    assert np.max(np.abs(J - _fd(lambda v: pair_gaps(st, v, P)[0], u).T)) < 1e-8
    mu = np.array([0.3, 1.2, -0.7, 0.4])
    H = pair_hessian(st, u, P, mu)
    assert np.max(np.abs(H - _fd(lambda v: pair_jacobian(st, v, P).T @ mu, u))) < 1e-8
    assert np.array_equal(H, H.T)


def test_closest_segments_match_the_dynamics_distance():
    # the strip's pair search against the dynamics' own brute-force kernel (same exclusion
    # of pairs closer than pi d / 2 along the rod): the same smallest distance
    st = DiscreteStrip(40, 6.0, 2.0, 0.5, 0.36, 0.0, thickness=0.2)
    th = np.concatenate([np.zeros(15), np.linspace(0, 2 * np.pi * 0.9, 25)])
    u = np.concatenate([[0.0], th])
    X = st.positions(u)
    _j, dist, _d, _w = closest_segments(st, u)
    dmin, _i, _s = segment_distances(X, st.thickness, np.full(st.n, st.h))
    assert abs(np.min(dist) - dmin) < 1e-14, (np.min(dist), dmin)


def test_hairpin_rests_on_the_base(hairpin100):
    st, eq = hairpin100
    assert eq.success and eq.index == 0, eq.message
    X = st.positions(eq.u)
    # the tip (node 100) rests on the base at exactly d, on the base's upper side, pushed
    # by a positive force; without contact it lies on the ground through the base
    assert eq.pairs.tolist() == [[100, 58, 1]]
    assert abs(X[-1, 1] - D) < 1e-12
    assert eq.pair_forces[0] > 0.5
    _j, dist, _d, _w = closest_segments(st, eq.u)
    assert np.min(dist) > D - 1e-12
    eq0 = wrapped_state(st.with_(thickness=0.0))
    assert abs(st.positions(eq0.u)[-1, 1]) < 1e-12
    # the contact force balances the ground's reaction on the tip without contact, to
    # the size of the change the thickness makes (d / tail length ~ 5e-3, measured 1.7e-3)
    assert abs(eq.pair_forces[0] - eq0.reactions[-1]) < 5e-3 * eq0.reactions[-1] + 1e-3


def test_tail_lying_on_the_base_carries_its_weight(hairpin100):
    # at Delta = 1.7 the tail lies flat on the flat base over its last nodes: each node of
    # the lying stretch presses on the base with its own weight q h and the end node with
    # q h / 2 (lumped masses, no moment in a straight stretch): a closed form
    st, eq = hairpin100
    for delta in np.arange(1.25, 1.7001, 0.05):
        s = st.with_(delta=float(delta))
        eq = solve_equilibrium(s, eq.u, active=eq.active, pairs=eq.pairs, max_turn=0.1)
        assert eq.success, (delta, eq.message)
    qh = s.q * s.h
    P, mu = eq.pairs, eq.pair_forces
    X = s.positions(eq.u)
    assert eq.index == 0
    assert np.allclose(X[P[:, 0], 1], D, atol=1e-12)
    lying = [k for k, i in enumerate(P[:, 0]) if i >= 97]  # nodes 97..100: a straight stretch
    assert P[lying, 0].tolist() == [97, 98, 99, 100]
    assert abs(mu[lying[-1]] - 0.5 * qh) < 1e-9 * qh, mu
    assert np.allclose(mu[lying[1:-1]], qh, rtol=0, atol=1e-9 * qh), mu


def test_thickness_zero_changes_nothing_bit_for_bit():
    # the trace at n = 60 without a thickness; reference: the same computation at the
    # revision before self-contact (9beab0d), whose sums this one meets to 1e-12 (the
    # compiled energy, gradient and Hessian kernels change the round-off, 5e-13 of the
    # Delta sum), and the sha256 of every segment's delta, u, reactions, energy and
    # indices at this revision's kernels and descent (its trust-region step solved on the
    # tridiagonal reduction), on the recording machine's numpy and BLAS.  Another CPU's
    # BLAS kernels round differently, and the trace carries that through its folds:
    # measured on an AMD EPYC, 1.9e-12 (Delta) and 7.1e-13 (energy) of the sums.  The sums
    # are held to 1e-11 everywhere; the hash where the sums are the recording's to 1e-14
    # (its arithmetic)
    sc = load_scene("fig3-strip", {"drop.distance_from_end": 3.0, "drop.wetted_length": 1.2})
    st = discrete_strip_for(sc, 60)
    assert st.thickness == 0.0
    eq = wrapped_state(st)
    b = trace_discrete_branch(st, eq, (0.1, 1.4), ContinuationSettings(**DEFAULTS).replace(
        direction=-1), restart=True, max_segments=200)
    h = hashlib.sha256()
    for s in b.segments:
        assert s.pairs.shape == (0, 3)
        for a in (s.delta, s.u, s.reactions, s.energy, s.index, s.index_strong):
            h.update(np.ascontiguousarray(a).tobytes())
    assert len(b.segments) == 7 and b.delta.size == 66
    dd = abs(float(np.sum(b.delta)) - 42.32421048537326) / 42.33
    de = abs(float(np.sum(b.energy)) - 4309.393531682155) / 4309.4
    assert dd < 1e-11 and de < 1e-11
    if dd < 1e-14 and de < 1e-14:
        assert h.hexdigest() == (
            "9a512067dca7cf9eaff25af8ecd39a7c9acf390e940ed413832bd461e903573d")


def test_pairs_need_a_thickness():
    st = DiscreteStrip(20, 3.0, 1.0, 0.5, 0.36, 0.0)
    with pytest.raises(ValueError, match="pairs: got 1 self-contact pairs; expected none"):
        solve_equilibrium(st, np.zeros(st.size), pairs=[[19, 2, 1]])


def test_branch_search_runs_without_the_thickness_and_says_so():
    """The search runs on a strip of thickness 0 and its metadata carries the note that
    the command line prints as a warning."""
    sc = _hairpin_scene(**{"numerics.accuracy": "draft"})
    assert sc.rod.thickness > 0
    bs = trace_contact_branches(sc, "drop.wetted_length", (1.0, 1.3), refine=False)
    assert bs.problem.strip.thickness == 0.0
    assert bs.metadata["contact_note"].startswith(
        f"rod.thickness = {sc.rod.thickness:g} is left out of the strip's branch search")


def test_hairpin_branch_ends_at_the_tip_lifting_off(hairpin100):
    """Traced down in Delta from 1.2, the hairpin slides its tip along the base (the tip's
    pair moves from segment to segment) and ends at a contact fold where the tip's contact
    force vanishes: index 0 -> 1, Delta turning back (~9 s)."""
    st, eq = hairpin100
    b = trace_discrete_branch(st, eq, (0.02, 1.4), ContinuationSettings(**DEFAULTS).replace(
        direction=-1), restart=True, max_segments=200)
    fold = b.turning_points[0]
    assert (fold["kind"], fold["node"], fold["index"]) == ("pair_lift_off", 100, (0, 1))
    # every traced point is a contact equilibrium: held gaps 0 and forces >= 0, no other
    # node inside a tube (to the graze allowance 1e-8 d), no node below the ground, the
    # strip not crossing itself. Round-off: the corrector's newton_tol / c ~ 3e-12 on a
    # held gap; an event's point is located to 1e-10 in arclength with a thickness, so the
    # switching value there is ~1e-10 (measured: the tip's ground touch-down on the open
    # side, z = -3e-11)
    for sg in b.segments:
        for u, r, mu, p in zip(sg.u, sg.reactions, sg.pair_forces, sg.delta, strict=True):
            s = st.with_(delta=float(p))
            X = s.positions(u)
            assert np.min(X[:, 1]) > -1e-9 and np.min(r) > -1e-9
            if len(sg.pairs):
                assert np.max(np.abs(pair_gaps(s, u, sg.pairs)[0])) < 1e-11
                assert np.min(mu) > -1e-9, (p, mu)
            _j, dist, _d, _w = closest_segments(s, u, X)
            assert np.min(dist) > D * (1 - 1e-8) - 1e-9, (p, np.min(dist))
            assert count_crossings(X, X, True, 0, s.size) == 0
    ev = next(e for e in b.events if e.kind == "pair_lift_off")
    assert ev.delta == fold["delta"] and abs(ev.value) < 1e-9  # the force at the event
    # every earlier event of the tip is a slide onto the next base segment, on the
    # stable stretch
    slides = [e for e in b.events if e.kind == "pair_switch" and e.delta > ev.delta]
    assert [e.pair[1] for e in slides] == list(range(58, 58 + len(slides)))
    d_f = fold["delta"]
    assert 0.20 < d_f < 0.21, d_f  # measured 0.2044135
    # independent: the active-set Newton method (it changes the contact set itself) finds
    # the stable hairpin 2e-3 above the fold and none with the tip in contact 2e-3 below
    seg = next(s for s in b.segments if s.event is ev)
    above = solve_equilibrium(st.with_(delta=d_f + 2e-3), seg.u[-2], active=seg.active,
                              pairs=seg.pairs)
    assert above.success and above.index == 0 and above.pair_forces[-1] > 0.0
    below = solve_equilibrium(st.with_(delta=d_f - 2e-3), seg.u[-1], active=seg.active,
                              pairs=seg.pairs)
    assert not (below.success and below.index == 0 and 100 in below.pairs[:, 0].tolist())
    # without contact the same branch ends the same way (the tip's ground reaction
    # vanishes) at a smaller Delta: contact shortens the stable encapsulated branch
    eq0 = wrapped_state(st.with_(thickness=0.0))
    b0 = trace_discrete_branch(st.with_(thickness=0.0), eq0, (0.02, 1.4),
                               ContinuationSettings(**DEFAULTS).replace(direction=-1),
                               restart=True, max_segments=200)
    f0 = b0.turning_points[0]
    assert (f0["kind"], f0["node"], f0["index"]) == ("lift_off", 100, (0, 1))
    assert 0.17 < f0["delta"] < d_f - 0.01, f0  # measured 0.1818049


# The damped run's rest: kinetic energy below K = gamma Delta rest_kinetic (48
# rest_kinetic here) for rest_time. The distance to the equilibrium falls as sqrt(K): at
# 100 edges, C = gap / sqrt(K) measured 0.38 (rest_kinetic 1e-6, rest_time 1), 0.19 (1e-9,
# 1), 0.23 (1e-10, 10), 0.15 (still moving at K = 9e-10): a bound C <= 0.5. rest_time 10
# spans the tail's slow swing, so the run does not stop at one of its turning points.
REST_K = 1e-10
GAMMA = 40.0  # the scene's line tension: the rest criterion's scale is gamma Delta


@pytest.mark.slow
@pytest.mark.parametrize("delta", [1.2, 1.5])
def test_damped_run_with_thickness_rests_on_the_hairpin(hairpin100, delta):
    """At Delta = 1.2 the tip rests on the base (one pair); at 1.5 the tail lies on the
    base over its last four nodes (four pairs, the lying ones carrying q h and q h / 2)."""
    from elastocap.impact import run_impact

    st, eq = hairpin100
    for d in np.arange(1.25, delta + 1e-9, 0.05):  # the static state, continued in Delta
        eq = solve_equilibrium(st.with_(delta=float(d)), eq.u, active=eq.active,
                               pairs=eq.pairs, max_turn=0.1)
        assert eq.success, eq.message
    st = st.with_(delta=delta)
    sc = _hairpin_scene(delta, **{"effects.damping": 0.1, "numerics.n_edges": 100,
                                  "numerics.rest_kinetic": REST_K, "numerics.rest_time": 10.0,
                                  "numerics.t_max": 400.0})
    res = run_impact(sc)
    assert res.status == "at_rest" and res.outcome == "encapsulated", res.message
    pos = res.simulation.positions[-1]
    X = st.positions(eq.u)
    gap = np.max(np.abs(pos - [pos[0, 0], 0.0] - X))  # the horizontal translation is free
    bound = 0.5 * np.sqrt(GAMMA * delta * REST_K)
    assert gap < bound, (gap, bound)  # measured 1.6e-5 (1.2), 6.1e-6 (1.5); bound 3.5e-5, 3.9e-5
    assert abs(res.final_measure - eq.u[-1] / np.pi) < bound
    # the contact forces: each pair's node pushed by its force along the normal (vertical
    # on the flat base), the base's nodes carrying the opposite (measured 3.1e-5 and
    # 1.1e-4 apart at this rest, 8e-3 at rest_kinetic 1e-6: the force of a state that far
    # off equilibrium)
    f = res.simulation.contact_forces
    nodes = eq.pairs[:, 0]
    assert np.max(np.abs(f[nodes, 1] - eq.pair_forces)) < 5e-4 * np.max(eq.pair_forces)
    assert abs(np.sum(f[:, 1])) < 1e-12 and np.max(np.abs(f[:, 0])) < 1e-12  # pairwise
    base = np.unique(np.concatenate([eq.pairs[:, 1], eq.pairs[:, 1] + 1]))
    others = np.setdiff1d(np.arange(st.size), np.concatenate([nodes, base]))
    assert np.max(np.abs(f[others])) == 0.0


@pytest.mark.slow
def test_hairpin_branch_end_converges_in_the_edges():
    """The end of the stable hairpin branch at x = 3 (the tip's lift-off) at n = 143, 286,
    429 (the drop's centre on a node or mid-edge): observed order and Richardson error
    (measured 0.15697, 0.13094, 0.12556: order 1.8, limit 0.1206, error 0.005; ~4 min)."""
    from scipy.optimize import brentq

    ns = (143, 286, 429)
    ends = []
    for n in ns:
        st = discrete_strip_for(_hairpin_scene(), n)
        b = trace_discrete_branch(st, wrapped_state(st), (0.02, 1.4),
                                  ContinuationSettings(**DEFAULTS).replace(direction=-1),
                                  restart=True, max_segments=1000)
        fold = b.turning_points[0]
        assert (fold["kind"], fold["node"], fold["index"]) == ("pair_lift_off", n, (0, 1))
        ends.append(fold["delta"])
    f1, f2, f3 = ends
    n1, n2, n3 = ns
    ratio = (f1 - f2) / (f2 - f3)
    p = brentq(lambda q: (n1**-q - n2**-q) / (n2**-q - n3**-q) - ratio, 0.1, 8.0)
    limit = f3 - (f2 - f3) / (n2**-p - n3**-p) * n3**-p
    assert f1 > f2 > f3, ends  # monotone
    assert 1.4 < p < 2.3, f"observed order {p:.2f}, ends {ends}"
    assert abs(f3 - limit) < 0.01, (limit, ends)
    assert 0.11 < limit < 0.13, limit
