"""The interface's arc and the segment crossing test of elastocap.geometry, against closed
forms and against each other (scalar compiled and vectorised numpy forms)."""

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from elastocap.geometry import (
    arc_offsets,
    arc_points,
    count_crossings,
    proper_crossing,
    segments_cross,
)


@settings(max_examples=60, deadline=None)
@given(tau=st.floats(1e-6, 3.0), a=st.floats(-2.0, 2.0), b=st.floats(-2.0, 2.0),
       c=st.floats(0.1, 3.0), phi=st.floats(-math.pi, math.pi))
def test_arc_points_lie_on_the_circle_of_half_angle_tau(tau, a, b, c, phi):
    # chord x1 -> x2 of length c: the circle of radius R = c / (2 sin tau) whose centre
    # lies on the chord's normal at distance R cos tau, on the side away from the bulge
    x1 = np.array([a, b])
    x2 = x1 + c * np.array([math.cos(phi), math.sin(phi)])
    p = arc_points(x1, x2, tau, 50)
    r = c / (2.0 * math.sin(tau))
    nrm = np.array([-math.sin(phi), math.cos(phi)])
    centre = 0.5 * (x1 + x2) - r * math.cos(tau) * nrm
    assert np.allclose(np.hypot(*(p - centre).T), r, rtol=1e-10, atol=1e-12)
    assert np.allclose(p[0], x1, atol=1e-12) and np.allclose(p[-1], x2, atol=1e-12)
    # the middle point bulges by the sagitta r (1 - cos tau) on the +normal side
    sag = (p[25] + p[24]) / 2.0 - 0.5 * (x1 + x2)
    assert abs(sag @ nrm - r * (1.0 - math.cos(tau))) < 1e-3 * r * tau


def test_arc_offsets_keep_their_digits_for_nearly_flat_arcs():
    # the series of along = sin(tau v) / sin(tau) and across = (cos(tau v) - cos(tau)) /
    # sin(tau) to relative O(tau^4): v (1 + tau^2 (1 - v^2) / 6) and tau (1 - v^2) / 2
    # (1 + tau^2 (1 - v^2) / 12); on both sides of the flat switch (1e-8) and through the
    # range where the difference of cosines loses its digits (0 in floating point at 1e-8,
    # 1e-4 relative at 1e-6)
    v = np.linspace(-1.0, 1.0, 9)
    for tau in (1e-8 * (1 - 1e-6), 1e-8 * (1 + 1e-6), 1e-7, 1e-6, 1e-5, 1e-4, 1e-3):
        along, across = arc_offsets(tau, v)
        t2 = tau * tau
        ref_along = v * (1.0 + t2 * (1.0 - v * v) / 6.0)
        ref_across = 0.5 * tau * (1.0 - v * v) * (1.0 + t2 * (1.0 - v * v) / 12.0)
        tol = 4e-16 + t2 * t2
        assert np.allclose(along, ref_along, rtol=tol, atol=0), tau
        assert np.allclose(across, ref_across, rtol=tol, atol=0), tau


def test_arc_offsets_broadcast_over_frames_as_arc_points_draws_one():
    taus = np.array([-1.2, -1e-9, 0.0, 0.4, 2.9])
    x1, x2 = np.array([0.3, -0.1]), np.array([1.7, 0.5])
    along, across = arc_offsets(taus[:, None], np.linspace(-1.0, 1.0, 30))
    for k, tau in enumerate(taus):
        one_a, one_c = arc_offsets(float(tau), np.linspace(-1.0, 1.0, 30))
        assert np.array_equal(along[k], one_a) and np.array_equal(across[k], one_c)
        d = np.hypot(*(x2 - x1))
        c = (x2 - x1) / d
        p = 0.5 * (x1 + x2) + 0.5 * d * (np.outer(one_a, c) + np.outer(one_c, [-c[1], c[0]]))
        assert np.allclose(p, arc_points(x1, x2, tau, 30), rtol=0, atol=1e-15)


def test_proper_crossing_on_arrays_equals_the_compiled_scalar_test():
    rng = np.random.default_rng(3)
    q = rng.uniform(-1.0, 1.0, (4000, 8))
    q[:50, 6:] = q[:50, 2:4]  # parallel pairs: never a crossing
    q[50:100, 4:6] = q[50:100, 0:2] + q[50:100, 2:4]  # b starts at a's end: touching
    with np.errstate(divide="ignore", invalid="ignore"):
        hit, u = proper_crossing(*q.T)
    for k in range(q.shape[0]):
        h1, u1 = segments_cross(*q[k])
        assert h1 == hit[k]
        if h1:
            assert u1 == u[k]
    assert not hit[:100].any()
    assert hit.sum() > 100
    # a closed form: the diagonals of the unit square cross at their midpoints
    h, uu = segments_cross(0.0, 0.0, 1.0, 1.0, 1.0, 0.0, -1.0, 1.0)
    assert h and uu == 0.5


def _crossings_pair_by_pair(a, b, same, skip_a0, skip_a1):
    """Every pair tested with the vectorised proper_crossing (no pruning)."""
    count = 0
    for i in range(max(skip_a0, 0), min(len(a) - 1, skip_a1)):
        j0 = i + 2 if same else 0
        if j0 >= len(b) - 1:
            continue
        bs, be = b[j0:-1], b[j0 + 1:]
        with np.errstate(divide="ignore", invalid="ignore"):
            hit, _u = proper_crossing(a[i, 0], a[i, 1], a[i + 1, 0] - a[i, 0],
                                      a[i + 1, 1] - a[i, 1], bs[:, 0], bs[:, 1],
                                      be[:, 0] - bs[:, 0], be[:, 1] - bs[:, 1])
        count += int(np.count_nonzero(hit))
    return count


@settings(max_examples=80, deadline=None)
@given(n=st.integers(1, 90), m=st.integers(1, 40), seed=st.integers(0, 2**31 - 1),
       flat=st.floats(0.0, 1.0), turn=st.floats(0.05, 2.0),
       skip0=st.integers(-2, 5), skip1=st.integers(0, 100))
def test_count_crossings_is_the_pair_by_pair_count(n, m, seed, flat, turn, skip0, skip1):
    # random walks of unit edges turning by up to `turn` per node (they fold over
    # themselves), a fraction `flat` of the nodes put on the line z = 0 (a strip on the
    # ground: boxes that touch everywhere)
    rng = np.random.default_rng(seed)

    def walk(k):
        th = np.cumsum(rng.uniform(-turn, turn, k))
        x = np.concatenate([[[0.0, 0.0]], np.cumsum(np.c_[np.cos(th), np.sin(th)], axis=0)])
        x[rng.random(k + 1) < flat, 1] = 0.0
        return x

    a, b = walk(n), walk(m)
    assert count_crossings(a, a, True, skip0, skip1) == \
        _crossings_pair_by_pair(a, a, True, skip0, skip1)
    assert count_crossings(a, b, False, skip0, skip1) == \
        _crossings_pair_by_pair(a, b, False, skip0, skip1)


def test_count_crossings_counts_a_known_figure():
    # a rectangle's outline crossed once by a vertical line, four times by a zig-zag
    box = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 2.0], [0.0, 2.0], [0.0, 0.0]])
    line = np.array([[2.0, -1.0], [2.0, 1.0]])
    zig = np.array([[1.0, -1.0], [1.5, 1.0], [2.5, -1.0], [3.0, 3.0]])
    assert count_crossings(line, box, False, 0, 10) == 1
    assert count_crossings(zig, box, False, 0, 10) == 4
    # a loop: the fourth edge crosses the first
    loop = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [1.0, 1.0], [1.0, -1.0]])
    assert count_crossings(loop, loop, True, 0, 10) == 1
