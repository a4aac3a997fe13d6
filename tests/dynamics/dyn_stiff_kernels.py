"""External force effects with a ``stiffness`` hook (the optional part of the protocol):
a vertical tether between two far nodes (all low rank) and a node spring (all band)."""

import numba
import numpy as np


@numba.njit(cache=True)
def tether_kernel(x, v, t, params, edge_len, mass, out_force):
    """Vertical spring of stiffness ``k`` between nodes ``i`` and ``j``: it pulls their
    heights together.  ``params = [i, j, k]``; ``U = k/2 (z_i - z_j)**2``."""
    i = int(params[0])
    j = int(params[1])
    k = params[2]
    dz = x[i, 1] - x[j, 1]
    out_force[i, 1] -= k * dz
    out_force[j, 1] += k * dz
    return 0.5 * k * dz * dz


@numba.njit(cache=True)
def tether_stiffness(x, v, t, params, edge_len, mass, K, U, C):
    """Hessian ``k (e_iz - e_jz)(e_iz - e_jz)^T``: rank 1, no band part.  It returns the
    rank ``params[3]`` (1; :class:`BadTether` sets a rank the protocol refuses, with the
    same compiled code)."""
    U[0, int(params[0]), 1] = 1.0
    U[0, int(params[1]), 1] = -1.0
    C[0, 0] = params[2]
    return int(params[3])


@numba.njit(cache=True)
def node_spring_kernel(x, v, t, params, edge_len, mass, out_force):
    """Spring pulling node ``i`` to the origin: ``params = [i, k]``, ``U = k/2 |x_i|**2``."""
    i = int(params[0])
    out_force[i, 0] -= params[1] * x[i, 0]
    out_force[i, 1] -= params[1] * x[i, 1]
    return 0.5 * params[1] * (x[i, 0] ** 2 + x[i, 1] ** 2)


@numba.njit(cache=True)
def node_spring_stiffness(x, v, t, params, edge_len, mass, K, U, C):
    """``k I`` on node ``i``: band only (diagonal block, offset STIFFNESS_BAND)."""
    i = int(params[0])
    K[i, 0, 2, 0] += params[1]
    K[i, 1, 2, 1] += params[1]
    return 0


class Tether:
    kind = "force"
    param_names = ("i", "j", "k", "rank")

    def __init__(self, i, j, k, name="tether", rank=1):
        self.name = name
        self.params = np.array([i, j, k, rank], dtype=np.float64)
        self.kernel = tether_kernel
        self.stiffness = tether_stiffness


class BadTether(Tether):
    """A tether whose hook breaks the protocol (rank above STIFFNESS_RANK)."""

    def __init__(self, i, j, k, name="tether"):
        super().__init__(i, j, k, name, rank=99)


class NodeSpring:
    kind = "force"
    param_names = ("i", "k")

    def __init__(self, i, k, name="node_spring"):
        self.name = name
        self.params = np.array([i, k], dtype=np.float64)
        self.kernel = node_spring_kernel
        self.stiffness = node_spring_stiffness
