"""The planar inextensible discrete rod: state and material."""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

__all__ = ["Rod", "kinetic_energy"]

#: Relative edge-length mismatch tolerated between given positions and ``edge_len``.
#: Positions built with trigonometric functions satisfy 1e-14; 1e-9 only refuses real
#: mistakes (the first projection then restores round-off accuracy).
EDGE_LEN_TOL = 1e-9


@numba.njit(cache=True)
def kinetic_energy(mass, v):
    """Kinetic energy ``sum_i m_i |v_i|**2 / 2`` of node masses ``mass`` (n,) and velocities
    ``v`` (n, 2) (energy units).

    Four partial sums: one running sum is a serial chain of additions (4 cycles each,
    0.3 us at 200 nodes, 2% of a time step); the result differs from it by round-off.
    """
    n = mass.shape[0]
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    s3 = 0.0
    i = 0
    while i + 3 < n:
        s0 += mass[i] * (v[i, 0] * v[i, 0] + v[i, 1] * v[i, 1])
        s1 += mass[i + 1] * (v[i + 1, 0] * v[i + 1, 0] + v[i + 1, 1] * v[i + 1, 1])
        s2 += mass[i + 2] * (v[i + 2, 0] * v[i + 2, 0] + v[i + 2, 1] * v[i + 2, 1])
        s3 += mass[i + 3] * (v[i + 3, 0] * v[i + 3, 0] + v[i + 3, 1] * v[i + 3, 1])
        i += 4
    while i < n:
        s0 += mass[i] * (v[i, 0] * v[i, 0] + v[i, 1] * v[i, 1])
        i += 1
    return 0.5 * ((s0 + s1) + (s2 + s3))


@dataclass
class Rod:
    """A planar discrete rod with fixed edge lengths (inextensible) and no twist.

    Attributes
    ----------
    x : ndarray, shape (n_nodes, 2)
        Node positions, columns ``(x, z)`` with ``z`` up (length units).
    v : ndarray, shape (n_nodes, 2)
        Node velocities (length / time).
    edge_len : ndarray, shape (n_nodes - 1,)
        Rest edge lengths ``l_i`` (length units), held fixed by the stepper.
    mu : float
        Mass per unit length (mass / length); node masses are lumped on Voronoi lengths,
        ``m_i = mu (l_{i-1} + l_i) / 2`` (half an edge at each end).
    B : float
        Bending modulus (energy x length); bending as in Discrete Elastic Rods, see
        :mod:`dynamics.bending`.

    Notes
    -----
    The stepper works on copies; the rod is not modified by :func:`dynamics.simulate`.
    """

    x: np.ndarray
    v: np.ndarray
    edge_len: np.ndarray
    mu: float = 1.0
    B: float = 1.0

    def __post_init__(self):
        self.x = np.array(self.x, dtype=np.float64, order="C")
        if self.x.ndim != 2 or self.x.shape[1] != 2 or self.x.shape[0] < 2:
            raise ValueError(
                f"Rod positions x must have shape (n_nodes >= 2, 2), got {self.x.shape}"
            )
        n = self.x.shape[0]
        self.v = np.array(self.v, dtype=np.float64, order="C")
        if self.v.shape != self.x.shape:
            raise ValueError(
                f"Rod velocities v must have the shape of x {self.x.shape}, got {self.v.shape}"
            )
        self.edge_len = np.array(self.edge_len, dtype=np.float64).ravel()
        if self.edge_len.shape != (n - 1,):
            raise ValueError(
                f"Rod edge_len must have shape ({n - 1},), got {self.edge_len.shape}"
            )
        if not np.all(self.edge_len > 0):
            i = int(np.argmin(self.edge_len))
            raise ValueError(
                f"Rod edge lengths must be > 0; edge {i} has length {self.edge_len[i]!r}"
            )
        if not (np.all(np.isfinite(self.x)) and np.all(np.isfinite(self.v))):
            raise ValueError("Rod positions and velocities must be finite")
        if not (self.mu > 0 and np.isfinite(self.mu)):
            raise ValueError(f"Rod mass per unit length mu must be > 0, got mu = {self.mu!r}")
        if not (self.B >= 0 and np.isfinite(self.B)):
            raise ValueError(f"Rod bending modulus B must be >= 0, got B = {self.B!r}")
        self.mu = float(self.mu)
        self.B = float(self.B)
        actual = np.linalg.norm(np.diff(self.x, axis=0), axis=1)
        rel = np.abs(actual - self.edge_len) / self.edge_len
        if rel.max() > EDGE_LEN_TOL:
            i = int(np.argmax(rel))
            raise ValueError(
                f"Rod positions violate the edge lengths: edge {i} has length {actual[i]!r} "
                f"but edge_len[{i}] = {self.edge_len[i]!r} (relative error {rel[i]:.2e} > "
                f"{EDGE_LEN_TOL:g}). Build x from the edge lengths, or use Rod.from_positions."
            )

    # ------------------------------------------------------------------ constructors
    @classmethod
    def straight(cls, n_edges, length, mu=1.0, B=1.0, origin=(0.0, 0.0), angle=0.0):
        """A straight rod of ``n_edges`` equal edges at rest.

        Parameters
        ----------
        n_edges : int
            Number of edges (``n_nodes = n_edges + 1``), >= 1.
        length : float
            Total length (length units).
        mu, B : float
            Mass per unit length and bending modulus.
        origin : (float, float)
            Position of node 0.
        angle : float
            Direction of the rod (radians from ``+x`` towards ``+z``).
        """
        n_edges = int(n_edges)
        if n_edges < 1:
            raise ValueError(f"n_edges must be >= 1, got {n_edges}")
        if not length > 0:
            raise ValueError(f"Rod length must be > 0, got {length!r}")
        s = np.linspace(0.0, length, n_edges + 1)
        x = np.empty((n_edges + 1, 2))
        x[:, 0] = origin[0] + s * np.cos(angle)
        x[:, 1] = origin[1] + s * np.sin(angle)
        h = length / n_edges
        return cls(x, np.zeros_like(x), np.full(n_edges, h), mu, B)

    @classmethod
    def from_positions(cls, x, v=None, mu=1.0, B=1.0):
        """A rod whose rest edge lengths are those of the given positions."""
        x = np.asarray(x, dtype=np.float64)
        if x.ndim != 2 or x.shape[1] != 2:
            raise ValueError(f"x must have shape (n_nodes, 2), got {x.shape}")
        edge_len = np.linalg.norm(np.diff(x, axis=0), axis=1)
        if v is None:
            v = np.zeros_like(x)
        return cls(x, v, edge_len, mu, B)

    # ------------------------------------------------------------------ derived data
    @property
    def n_nodes(self) -> int:
        return self.x.shape[0]

    @property
    def length(self) -> float:
        """Total rest length (length units)."""
        return float(self.edge_len.sum())

    @property
    def mass(self) -> np.ndarray:
        """Lumped node masses ``mu (l_{i-1} + l_i) / 2``, shape (n_nodes,)."""
        lv = np.zeros(self.n_nodes)
        lv[:-1] += 0.5 * self.edge_len
        lv[1:] += 0.5 * self.edge_len
        return self.mu * lv

    def copy(self) -> Rod:
        return Rod(self.x.copy(), self.v.copy(), self.edge_len.copy(), self.mu, self.B)
