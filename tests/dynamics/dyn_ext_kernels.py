"""An external effect defined outside the dynamics package, as elastocap will do."""

import numba
import numpy as np


@numba.njit(cache=True)
def anchor_spring_kernel(x, v, t, params, edge_len, mass, out_force):
    """Harmonic spring pulling node ``params[0]`` to ``(params[2], params[3])``.

    ``params = [node, k, ax, az]``; ``U = k/2 |x_node - a|**2``.
    """
    i = int(params[0])
    dx = x[i, 0] - params[2]
    dz = x[i, 1] - params[3]
    out_force[i, 0] -= params[1] * dx
    out_force[i, 1] -= params[1] * dz
    return 0.5 * params[1] * (dx * dx + dz * dz)


class AnchorSpring:
    """Follows the effect protocol without subclassing dynamics.Effect."""

    kind = "force"
    param_names = ("node", "k", "ax", "az")

    def __init__(self, node, k, anchor, name="spring"):
        self.name = name
        self.params = np.array([node, k, anchor[0], anchor[1]], dtype=np.float64)
        self.kernel = anchor_spring_kernel


@numba.njit(cache=True)
def pull_kernel(x, v, t, params, edge_len, mass, out_force):
    """Constant forces ``T e_x`` on nodes ``params[0]`` and ``params[1]`` and ``-2 T e_x``
    on node ``params[2]`` (``T = params[3]``): no net force.  ``U = -T (x_a + x_b - 2 x_c)``.
    """
    a = int(params[0])
    b = int(params[1])
    c = int(params[2])
    T = params[3]
    out_force[a, 0] += T
    out_force[b, 0] += T
    out_force[c, 0] -= 2.0 * T
    return -T * (x[a, 0] + x[b, 0] - 2.0 * x[c, 0])


class Pull:
    """Two tails pulled along +x by T, a third node along -x by 2 T."""

    kind = "force"
    param_names = ("a", "b", "c", "T")

    def __init__(self, a, b, c, T, name="pull"):
        self.name = name
        self.params = np.array([a, b, c, T], dtype=np.float64)
        self.kernel = pull_kernel
