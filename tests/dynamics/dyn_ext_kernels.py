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
