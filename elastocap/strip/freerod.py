"""The free rod (``supp-fig5``: no gravity, no ground) as a discrete strip with self-contact.

The free rod is the :class:`~elastocap.strip.model.DiscreteStrip` with ``ground = False``
and q = 0 (:func:`~elastocap.strip.model.discrete_strip_for`): the same energy (bending,
capillarity; term for term the dynamics'), the same node-segment self-contact pairs with a
thickness, the same active-set Newton method
(:func:`~elastocap.strip.solve.solve_equilibrium`) and the same tracer in Delta
(:func:`~elastocap.strip.trace.trace_discrete_branch`). Its energy is invariant under
translations and rotations: the gauge holds z_0 = 0 (x_0 = 0 is built in) and the angle of
the edge holding the drop's centre at 0 (:attr:`~elastocap.strip.model.DiscreteStrip.gauge`).

This module adds what the free rod needs around them: seeds from the spectral statics of
the wet part (:mod:`elastocap.statics`, which knows no contact), carried to the edges
(:func:`wet_equilibrium`, :func:`discrete_from_wet`, :func:`encapsulated_state`), and the
contact events and stability of a traced branch as plain data (:func:`contact_summary`).
"""

from __future__ import annotations

import math

import numpy as np

from elastocap.geometry import encapsulation_measure
from elastocap.strip.model import DiscreteStrip, discrete_strip_for, fix_gauge
from elastocap.strip.solve import Equilibrium, minimize_energy

__all__ = [
    "contact_summary",
    "discrete_from_wet",
    "encapsulated_state",
    "wet_equilibrium",
]


def wet_equilibrium(scene, delta: float, turning: float, N: int | None = None):
    """An equilibrium of the spectral wet part (:mod:`elastocap.statics`) at ``delta``.

    Newton (:func:`elastocap.statics.branches.newton`) from the mirror-symmetric wet part
    bent uniformly by ``turning`` pi (the seed's encapsulation measure; 1.5 reaches the
    stable encapsulated branch of ``supp-fig5`` at A = 1, Delta = 3.15, M = 1.2301).

    Returns
    -------
    problem : elastocap.statics.wet_elastica.WetElasticaProblem
    u : ndarray
        Its unknowns at p = delta.

    Raises
    ------
    ValueError
        When Newton does not converge (naming ``turning``).
    """
    from elastocap.statics.branches import newton, problem_for

    prob = problem_for(scene, "drop.wetted_length", N)
    th = 0.5 * math.pi * float(turning) * prob.xi
    u = newton(prob, np.concatenate([th, [0.0]]), float(delta))
    if u is None:
        raise ValueError(f"turning: got {turning!r}; Newton on the wet part found no "
                         f"equilibrium from it at Delta = {delta}; try another turning")
    return prob, u


def discrete_from_wet(rod: DiscreteStrip, problem, u) -> np.ndarray:
    """The state u of the discrete rod closest to a spectral state of the wet part: each
    edge angle is the spectral theta at the edge's midpoint on the wet part, and theta(S1)
    or theta(S2) on the straight dry arms; then moved into the gauge
    (:func:`~elastocap.strip.model.fix_gauge`)."""
    s = (np.arange(rod.n) + 0.5) * rod.h
    xi = np.clip(2.0 * (s - rod.s1) / rod.delta - 1.0, -1.0, 1.0)
    th = problem.interp_matrix(xi) @ np.asarray(u)[: problem.N + 1]
    return fix_gauge(rod, np.concatenate([[0.0], th]))


def encapsulated_state(scene, n: int, turning: float = 1.5) -> Equilibrium:
    """A stable equilibrium of the discrete free rod at the scene's Delta, reached by
    descent (:func:`~elastocap.strip.solve.minimize_energy`) from the wet part bent
    uniformly by ``turning`` pi with straight dry arms (1.5 reaches the encapsulated
    branch of ``supp-fig5`` at A = 1, Delta = 3.15 and at A = 1.5, Delta = 3.6 and 4).

    With a thickness the descent runs without self-contact and its minimum is made a
    contact equilibrium by continuation in the thickness (as for the strip).
    """
    rod = discrete_strip_for(scene, n)
    s = (np.arange(rod.n) + 0.5) * rod.h
    th = math.pi * float(turning) * (np.clip((s - rod.s1) / rod.delta, 0.0, 1.0) - 0.5)
    return minimize_energy(rod, fix_gauge(rod, np.concatenate([[0.0], th])))


def contact_summary(rod: DiscreteStrip, branch) -> dict:
    """Contact events, stability and the contact force along a traced branch (plain data).

    Parameters
    ----------
    rod : DiscreteStrip
    branch : elastocap.strip.trace.DiscreteBranch

    Returns
    -------
    dict
        ``onset``: the first ``pair_touch_down`` (``delta``, ``node``, ``pair``) or None;
        ``events``: every self-contact event (``kind``, ``delta``, ``node``, ``pair``);
        ``turning_points``: the branch's contact folds; ``folds``: its smooth folds
        (``delta``, ``index``); ``index_changes``: where the stability index changes
        between two consecutive points of one segment without a fold (``delta`` bracket,
        ``index`` before and after); ``points``: per point ``delta``, ``index``,
        ``energy``, ``measure``, ``pairs`` and ``forces`` (lists); ``status``,
        ``message``.
    """
    ev = [{"kind": e.kind, "delta": float(e.delta), "node": int(e.node),
           "pair": [int(a) for a in e.pair] if getattr(e, "pair", None) else None}
          for e in branch.events if e.kind.startswith("pair_")]
    onset = next((e for e in ev if e["kind"] == "pair_touch_down"), None)
    pts, changes, folds = [], [], []
    for seg in branch.segments:
        for k, d in enumerate(seg.delta):
            pts.append({"delta": float(d), "index": int(seg.index_strong[k]),
                        "energy": float(seg.energy[k]),
                        "measure": encapsulation_measure(seg.u[k][1], seg.u[k][-1]),
                        "pairs": seg.pairs.tolist(),
                        "forces": seg.pair_forces[k].tolist() if seg.pair_forces.size else []})
        for k in range(1, seg.delta.size):
            a, b = int(seg.index_strong[k - 1]), int(seg.index_strong[k])
            if a != b and not any(min(seg.delta[k - 1], seg.delta[k]) <= f["delta"] <=
                                  max(seg.delta[k - 1], seg.delta[k]) for f in seg.folds):
                changes.append({"delta": [float(seg.delta[k - 1]), float(seg.delta[k])],
                                "index": [a, b]})
        folds += [{"delta": f["delta"], "index": list(f["index"]) if f["index"] else None}
                  for f in seg.folds]
    return {"onset": onset, "events": ev,
            "turning_points": [dict(t, index=list(t["index"])) for t in branch.turning_points],
            "folds": folds, "index_changes": changes, "points": pts,
            "status": branch.status, "message": branch.message}
