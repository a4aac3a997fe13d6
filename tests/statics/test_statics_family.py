"""Completeness across the free-rod family: the one-parameter search in Delta finds every
fold that the (Delta, A) fold curve crosses at the scene's area, and every fold it finds
lies on that curve (to 1e-8). The reference curves are continued once from the folds of
a reference scene (tests/statics/family.py).

The ten fixed scenes and the unsteered random test run the search without its fold-curve
starts (``fold_curve_seeds=False``: seeds, neighbour seeds and switching only), so the two
computations are independent. The scenes drawn around their folds run the search as it
runs by default (with the fold-curve starts of the folds it found, continued from this
scene, not from the reference): at A = 1.7045, Delta in [3.19, 6.42], the seed-only search
misses the segment of the open state that starts at its fold Delta = 4.893 (the gap that
the BranchSearch docstring names: a segment between samples outside every deflated
basin); the fold-curve starts find it.

The fixed scenes and two drawn scenes run by default; the 60 draws and the unsteered
random test (A 0.5..1.9, L 3..8, the drop anywhere it fits, any Delta range inside the
admissible one) are marked slow.
"""

import math

import numpy as np
import pytest
from family import curve_folds
from hypothesis import HealthCheck, assume, given, settings, target
from hypothesis import strategies as st

from elastocap.scene import load_scene
from elastocap.statics.branches import trace_branches

TOL = 1e-8


def _scene(A, L, c, lo):
    return load_scene("supp-fig5", {"drop.area": A, "rod.length": L, "drop.center": c,
                                    "drop.wetted_length": lo})


def check_scene(A, L, c, lo, hi, fold_curve_seeds=False):
    """Search at one scene; compare with the fold curve.

    Returns (number of folds in range, largest |search - curve| over them)."""
    sc = _scene(A, L, c, lo)
    bs = trace_branches(sc, "drop.wetted_length", (lo, hi), error_estimates=False,
                        fold_curve_seeds=fold_curve_seeds)
    a, b = bs.prange
    span = b - a
    # a fold within 1e-6 of a range end may end the branch before it turns: not asserted
    inner = (a + 1e-6 * span, b - 1e-6 * span)
    on_curve = curve_folds(A, a, b)
    expected = [v for v in on_curve if inner[0] <= v <= inner[1]]
    found = [f["value"] for f in bs.folds if inner[0] <= f["value"] <= inner[1]]
    scene = f"A={A:.17g}, L={L:.17g}, centre={c:.17g}, Delta in [{a:.17g}, {b:.17g}]"
    worst = 0.0
    for v in expected:
        d = min((abs(v - w) for w in found), default=math.inf)
        assert d <= TOL, (
            f"{scene}: the fold curve crosses at Delta={v:.12g}; search found {found}; "
            f"unlocated {bs.unlocated}")
        worst = max(worst, d)
    for w in found:
        d = min((abs(v - w) for v in on_curve), default=math.inf)
        assert d <= TOL, f"{scene}: the search's fold {w:.12g} is not on the fold curve {expected}"
        worst = max(worst, d)
    distinct = [w for i, w in enumerate(found) if all(abs(w - x) > TOL for x in found[:i])]
    assert len(distinct) == len(expected), f"{scene}: search {found}, fold curve {expected}"
    assert bs.unlocated == [] or all(
        u["kind"] != "fold" or not inner[0] <= u["value"] <= inner[1] for u in bs.unlocated
    ), f"{scene}: unlocated {bs.unlocated}"
    return len(expected), worst


# (A, L, centre as a fraction of the room the drop has, Delta range as fractions of the
# admissible maximum): spread over the family, not tuned on any scene
FIXED = [
    (0.5, 3.0, 0.5, 0.05, 1.0),
    (0.8, 5.0, 0.3, 0.1, 1.0),
    (1.0, 4.6, 0.5, 0.02, 1.0),
    (1.2, 6.0, 0.7, 0.3, 0.9),
    (1.5, 8.0, 0.5, 0.2, 0.8),
    (1.65, 4.0, 0.45, 0.05, 1.0),
    (1.74, 4.6, 0.5, 0.7, 0.85),
    (1.9, 7.0, 0.6, 0.1, 1.0),
    (0.6, 8.0, 0.25, 0.3, 1.0),
    (1.3, 3.5, 0.5, 0.5, 1.0),
]


def _geometry(A, L, cfrac, f_lo, f_hi):
    # the centre sits in [0.1 L, 0.9 L]; the largest admissible Delta there is 2 min(c, L-c)
    c = L * (0.1 + 0.8 * cfrac)
    dmax = 2.0 * min(c, L - c)
    return c, max(f_lo * dmax, 0.02 * L), f_hi * dmax


@pytest.mark.parametrize(("A", "L", "cfrac", "f_lo", "f_hi"), FIXED)
def test_search_agrees_with_the_fold_curve(A, L, cfrac, f_lo, f_hi):
    c, lo, hi = _geometry(A, L, cfrac, f_lo, f_hi)
    if not lo < hi:
        pytest.skip("empty range")
    check_scene(A, L, c, lo, hi)


@pytest.mark.slow
@settings(max_examples=60, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(A=st.floats(0.5, 1.9), L=st.floats(3.0, 8.0), cfrac=st.floats(0.0, 1.0),
       f_lo=st.floats(0.02, 0.7), width=st.floats(0.2, 1.0))
def test_random_admissible_scenes_agree_with_the_fold_curve(A, L, cfrac, f_lo, width):
    c, lo, _ = _geometry(A, L, cfrac, f_lo, 1.0)
    dmax = 2.0 * min(c, L - c)
    hi = min(dmax, lo + width * (dmax - lo))
    if not hi - lo > 1e-3 * L or not math.isfinite(hi):
        return
    n, _ = check_scene(A, L, c, lo, hi)
    # steer the generation towards scenes with folds (where agreement says most)
    target(float(n), label="folds in range")
    # one line per agreeing scene (visible with pytest -s): the count the docs quote
    print(f"agree: A={A:.6g} L={L:.6g} centre={c:.6g} Delta=[{lo:.6g}, {hi:.6g}] "
          f"folds={n}")


# ---------------------------------------------------------------- scenes with folds
#: The cusp region of the fold curve: above A = 1.648 the curve turns back (a scene there
#: has two folds close together, 1.3e-3 apart at A = 1.74 and 6e-5 apart at A = 1.7449, the
#: cusp being at A = 1.744911; or four on a long rod).
CUSP_REGION = (1.6, 1.7449)


@st.composite
def scenes_with_folds(draw):
    """(A, L, centre, lo, hi) of an admissible scene whose Delta range contains one fold or
    two consecutive folds of the fold curve, each at least 2% of the range from its ends.

    The area is drawn over the family (0.5..1.9) or, one time in three, in the cusp region;
    the fold curve (a second computation, in the area) gives the folds at that area; a
    fold (or a consecutive pair) is drawn, then a centre where it is admissible, then the
    range around it. An area whose folds do not fit on the rod is rejected. The numbers
    are drawn uniformly from a generator seeded by hypothesis (hypothesis' own floats
    favour the interval ends and repeat them, which would check the same few scenes)."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    A = rng.uniform(*CUSP_REGION) if rng.integers(3) == 0 else rng.uniform(0.5, 1.9)
    L = rng.uniform(3.0, 8.0)
    margin = 0.02 * L  # room beyond the outer fold, for the range end
    folds = curve_folds(A, 0.05 * L, L - 2.0 * margin)
    assume(folds)
    j = int(rng.integers(len(folds)))
    m = int(rng.integers(1, 3)) if j + 1 < len(folds) else 1
    f_a, f_b = folds[j], folds[j + m - 1]
    # the centre: the outer fold (plus the margin) is admissible, 2 min(c, L - c) >= it
    half = 0.5 * (f_b + 2.0 * margin)
    c = half + rng.uniform() * (L - 2.0 * half)
    dmax = 2.0 * min(c, L - c)
    lo_min = 0.02 * L
    # the range ends: anywhere between the admissible ends and the target folds, at least
    # 2% of the span (and 1e-3) from each target fold
    lo = lo_min + rng.uniform() * (f_a - lo_min)
    hi = f_b + rng.uniform() * (dmax - f_b)
    gap = 0.02 * (hi - lo) + 1e-3
    lo, hi = min(lo, f_a - gap), max(hi, f_b + gap)
    assume(lo >= lo_min and hi <= dmax)
    return float(A), float(L), float(c), float(lo), float(hi)


def _check_family(max_examples, min_scenes):
    """Check ``max_examples`` draws of scenes with folds (at least ``min_scenes``
    distinct); return one row (scene, folds, largest disagreement) per scene."""
    rows = []

    @settings(max_examples=max_examples, deadline=None, derandomize=True, database=None,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
    @given(scenes_with_folds())
    def one(scene):
        # the search as it runs by default: seeds and the fold-curve starts of its own folds
        n, worst = check_scene(*scene, fold_curve_seeds=True)
        rows.append((scene, n, worst))

    one()
    # hypothesis may draw a scene twice: count each once
    rows = list({r[0]: r for r in rows}.values())
    with_folds = [r for r in rows if r[1] >= 1]
    two = [r for r in rows if r[1] >= 2]
    turning = [r for r in two if r[0][0] > CUSP_REGION[0]]
    worst = max(r[2] for r in rows)
    summary = (f"{len(rows)} distinct scenes, {len(with_folds)} with >= 1 fold in range, "
               f"{len(two)} with >= 2 ({len(turning)} of them in the cusp region, where the "
               f"fold curve turns back), {sum(r[1] for r in rows)} folds; largest "
               f"|search - fold curve| = {worst:.1e}")
    print(summary)
    for (A, L, c, lo, hi), n, w in rows:
        print(f"agree: A={A:.6g} L={L:.6g} centre={c:.6g} Delta=[{lo:.6g}, {hi:.6g}] "
              f"folds={n} max diff={w:.1e}")
    # every scene drawn has a fold inside its range, and the family was covered
    assert len(with_folds) == len(rows) >= min_scenes, summary
    return rows


def test_scenes_with_folds_agree_with_the_fold_curve():
    """Default run: a few scenes drawn around their folds (the slow test draws 60)."""
    _check_family(2, 2)


@pytest.mark.slow
def test_sixty_scenes_with_folds_agree_with_the_fold_curve():
    rows = _check_family(60, 50)
    # some with two folds where the fold curve turns back (near the cusp A = 1.745)
    assert sum(r[1] >= 2 and r[0][0] > CUSP_REGION[0] for r in rows) >= 3
