"""Self-contact at long steps of the midpoint method: a contact projection that cannot
converge is refused (the step is rejected and retried with substeps) before a non-finite
value reaches the state, a step whose contacts turn too far for their linearisation is
retried with substeps, and the reason is recorded in ``stats``.

The recorded state (``data/deep_projection_state.npz``, 201 nodes, thickness 0.0157) is
the start and the implicit solve's end of a step that once made the position stage return
a NaN state as converged: a free end sliding over another layer of a folded rod, 3
thicknesses a step (0.65 of an edge), its contacts a thickness deep in their linearised
gaps (fig3-strip at 200 edges, the midpoint method at 8x the explicit bound, t = 5.466).
The projection's edge residual then grew 3e-14, 88, 520, 8e3, ... to NaN at its 12th
iteration, and a maximum that skipped the NaN let it pass."""

from pathlib import Path

import numpy as np
import pytest

from dynamics import Damping, Gravity, Ground, Rod, SelfContact, simulate, stable_dt
from dynamics.contact import (
    contact_positions,
    contact_stats,
    new_contact_work,
    segment_distances,
)

STATE = Path(__file__).parent / "data" / "deep_projection_state.npz"


def _state():
    z = np.load(STATE)
    return (z["x0"], z["x"].copy(), z["w"], z["edge_len"], float(z["thickness"]))


def _project(max_depth):
    x0, x, w, edge_len, d = _state()
    ck = new_contact_work(edge_len)
    lam = np.zeros(edge_len.size + 2)
    st = contact_positions(x0, x, w, edge_len, lam, d, max_depth, ck)
    return st, x, ck, d


def test_diverging_projection_is_refused_with_a_finite_state():
    st, x, ck, _ = _project(np.inf)
    assert st == -1  # before the fix: 1 (converged) with NaN positions
    assert np.isfinite(x).all()
    s = contact_stats(ck, 0)
    assert s["self_contact_failures"] == 1
    assert "diverged" in s["self_contact_failure"]


def test_too_deep_a_step_is_refused_before_projecting():
    x0, x_in, *_ = _state()
    st, x, ck, d = _project(0.5 * 0.0157)
    assert st == -1
    assert np.array_equal(x, x_in)  # refused before any change
    s = contact_stats(ck, 0)
    assert s["self_contact_failures"] == 1
    assert "deeper" in s["self_contact_failure"]
    # the state is one a smaller step would not have produced: its deepest linearised
    # gap is a thickness below contact
    assert s["self_contact_penetration"] == 0.0  # nothing projected


@pytest.mark.parametrize("depth", [2.0, 4.0])
def test_shallower_limits_than_the_state_let_it_through_to_the_divergence_check(depth):
    st, x, ck, d = _project(depth * 0.0157)
    assert st == -1 and np.isfinite(x).all()
    assert "diverged" in contact_stats(ck, 0)["self_contact_failure"]


def test_hairpin_thrown_at_a_long_step_keeps_its_thickness_and_loses_energy():
    """The colliding arms of ``test_dyn_contact`` (a free hairpin, bending stiffness 0.01)
    thrown 3 times faster, the midpoint method at 8x the explicit bound (twice the step of
    those tests).  Before the step control of the contacts' linearisation the true gap fell
    to 0.80 of the thickness and the energy rose by 1.3e-2 of its initial value; measured
    with it: 0.9909 and 2.1e-4."""
    from test_dyn_contact import _hairpin, pull

    n = 60
    x, h = _hairpin(n, 3.0, 0.2)
    v = np.zeros_like(x)
    zc = 0.5 * (x[:, 1].max() + x[:, 1].min())
    tip = x[:, 0].max()
    v[:, 1] = np.where(x[:, 1] > zc, -1.0, 1.0) * np.minimum(1.0, np.abs(x[:, 0] - tip))
    v[:, 0] = 0.1
    rod = Rod(x, v, np.full(n, h), 1.0, 0.01)
    d = 0.05
    dt = 8 * 0.5 * stable_dt(rod.edge_len, 1.0, 0.01)
    # no gravity, no damping, no load and the ground far below: the colliding arms'
    # stepper (the same trajectory bit for bit as with SelfContact alone)
    eff = (Gravity(0.0), Ground(-100.0), SelfContact(d), Damping(0.0), *pull(0, n, 30, 0.0))
    res = simulate(rod, eff, method="midpoint", dt=dt, t_end=3.0,
                   frames=np.arange(0.0, 3.0, dt))
    assert res.success, res.message
    assert np.isfinite(res.positions).all() and np.isfinite(res.velocities).all()
    assert res.stats["self_contact_steps"] > 10
    # steps retried with substeps for their contacts, the reason recorded
    assert res.stats["self_contact_failures"] >= 1
    assert res.stats["rejected_steps"] >= res.stats["self_contact_failures"]
    assert "turned too far" in res.stats["self_contact_failure"]
    # never crossing, never closer than the thickness beyond the accepted shortfall
    dmin = min(segment_distances(p, d, rod.edge_len)[0] for p in res.positions)
    assert dmin >= d * (1 - 1e-2)
    # no energy source: the total energy never rises above its running minimum by more
    # than the integrator's O(dt**2) error (1e-3 of the initial energy; 1.3e-2 before)
    E = res.energies["total"]
    assert np.max(E - np.minimum.accumulate(E)) <= 1e-3 * E[0]
    assert E[-1] < E[0]
