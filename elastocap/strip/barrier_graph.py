"""The lowest energy barrier from each open state to encapsulation, over every traced branch.

At one Delta, the branches traced by :func:`~elastocap.strip.contact_branches.
trace_contact_branches` cross it at every equilibrium they reach: minima (index 0) and
saddles (index 1). Each saddle is joined to the two minima its descents end on
(:func:`~elastocap.strip.mep.descend_from_saddle`, pushed both ways along its unstable
mode); minima found only by a descent are added. On that graph, the barrier of an open
minimum m is the minimax of the saddle energies over paths from m to any encapsulated
minimum, minus E(m): the least energy the strip must be given to leave m for encapsulation
through the saddles found (Kruskal's order with a union-find: saddles are added by
increasing energy until m's component holds an encapsulated minimum).

What it does not prove: that the traced branches hold every saddle (saddles on branches not
reached from the seeds are missed); a string method (:func:`~elastocap.strip.mep.barrier`)
finds one path, this the lowest over the saddles found.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from elastocap.strip.contact_branches import solved_crossings
from elastocap.strip.discrete import DiscreteStrip, Equilibrium, stability
from elastocap.strip.mep import descend_from_saddle, is_encapsulated

__all__ = ["BarrierGraph", "barrier_graph", "equilibria_at", "lowest_barriers"]

# Two states are the same equilibrium when their u differ by less than this (max norm;
# Newton converges to ~1e-12, distinct equilibria differ by >~ 1e-4 in the cases seen).
_SAME = 1e-7


def equilibria_at(bs, delta: float) -> list[tuple[int, Equilibrium]]:
    """Every distinct equilibrium the traced branches of ``bs`` cross at ``delta``.

    Each crossing is solved exactly at ``delta`` by Newton at its segment's contact set from
    the nearer traced point. Returns (stability index, Equilibrium) pairs, by energy.
    """
    lo, hi = bs.prange
    if not lo <= delta <= hi:
        raise ValueError(f"delta: got {delta}; expected it inside the traced range "
                         f"[{lo}, {hi}]")
    from elastocap.strip.discrete import discrete_strip_for

    strip = discrete_strip_for(bs.scene, bs.n).with_(delta=float(delta))
    found: list[tuple[int, Equilibrium]] = []
    for seg, j, eq in solved_crossings(strip, bs.branches):
        if eq.success and not any(np.max(np.abs(eq.u - e.u)) < _SAME for _, e in found):
            # the index of the solved state itself: Newton from a point next to a fold can
            # land on the other side of it (measured at x = 4, Delta = 1.1: the saddle,
            # found from a point of the open branch); with a contact of zero reaction the
            # fixed-set index of the segment is kept
            idx, weak = stability(strip, eq)
            found.append((int(seg.index[j]) if weak else idx, eq))
    return sorted(found, key=lambda t: t[1].energy)


@dataclass
class BarrierGraph:
    """Minima and saddles at one Delta, the saddles' connections, the lowest barriers.

    Attributes
    ----------
    delta : float
    minima : list of dict
        ``energy``, ``encapsulated`` (the paper's criterion), ``tip_angle`` theta(L)
        (rad), ``from_descent`` (found only by descending from a saddle).
    saddles : list of dict
        ``energy``, ``joins`` (the two minima indices its descents end on; -1 when a
        descent failed), ``tip_angle``.
    barriers : list of dict
        One per open minimum: ``minimum`` (index), ``barrier`` (energy units; inf when no
        path to an encapsulated minimum is found), ``via`` (the bottleneck saddle index).
    """

    delta: float
    minima: list = field(default_factory=list)
    saddles: list = field(default_factory=list)
    barriers: list = field(default_factory=list)

    def to_dict(self) -> dict:
        return {"delta": self.delta, "minima": self.minima, "saddles": self.saddles,
                "barriers": self.barriers}


def lowest_barriers(energies_min, encapsulated, saddles) -> list[dict]:
    """Minimax barriers on a graph of minima joined by saddles.

    Parameters
    ----------
    energies_min : sequence of float
        Energy of each minimum.
    encapsulated : sequence of bool
        Kind of each minimum.
    saddles : sequence of (energy, i, j)
        A saddle of that energy joining minima i and j (-1: unknown end, ignored).

    Returns
    -------
    list of dict
        For each open minimum m: ``minimum``, ``barrier`` = E_bottleneck - E(m) (inf if no
        path), ``via`` (index into ``saddles`` of the bottleneck, -1 if none).
    """
    n = len(energies_min)
    parent = list(range(n))

    def find(a):
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    open_ids = [m for m in range(n) if not encapsulated[m]]
    done = {m: (math.inf, -1) for m in open_ids}
    for k in sorted(range(len(saddles)), key=lambda k: saddles[k][0]):
        e, i, j = saddles[k]
        if i < 0 or j < 0:
            continue
        a, b = find(i), find(j)
        if a != b:
            parent[a] = b
        for m in open_ids:
            if done[m][1] >= 0:
                continue
            root = find(m)
            if any(encapsulated[q] and find(q) == root for q in range(n)):
                done[m] = (e, k)
    return [{"minimum": m,
             "barrier": (done[m][0] - energies_min[m]) if done[m][1] >= 0 else math.inf,
             "via": done[m][1]} for m in open_ids]


def barrier_graph(bs, delta: float) -> BarrierGraph:
    """Minima, saddles and the lowest barrier of each open minimum at ``delta``."""
    from elastocap.strip.discrete import discrete_strip_for

    strip: DiscreteStrip = discrete_strip_for(bs.scene, bs.n).with_(delta=float(delta))
    eqs = equilibria_at(bs, delta)
    minima = [eq for idx, eq in eqs if idx == 0]
    from_descent = [False] * len(minima)
    saddle_eqs = [eq for idx, eq in eqs if idx == 1]

    def index_of(eq):
        for k, m in enumerate(minima):
            if np.max(np.abs(m.u - eq.u)) < 1e-6:
                return k
        minima.append(eq)
        from_descent.append(True)
        return len(minima) - 1

    saddles = []
    for sad in saddle_eqs:
        ends = descend_from_saddle(strip, sad)
        joins = [index_of(e) if (e is not None and e.success and e.index == 0) else -1
                 for e in ends]
        saddles.append({"energy": float(sad.energy), "joins": joins,
                        "tip_angle": float(sad.u[-1])})
    enc = [is_encapsulated(strip, m.u) for m in minima]
    g = BarrierGraph(float(delta))
    g.minima = [{"energy": float(m.energy), "encapsulated": bool(e),
                 "tip_angle": float(m.u[-1]), "from_descent": f}
                for m, e, f in zip(minima, enc, from_descent, strict=True)]
    g.saddles = saddles
    g.barriers = lowest_barriers([m["energy"] for m in g.minima], enc,
                                 [(s["energy"], *s["joins"]) for s in saddles])
    return g
