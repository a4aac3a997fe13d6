"""The capillary effect for `dynamics`: the drop's force on the rod, -gamma grad(lambda).

A force effect of the `dynamics` effect protocol (see :mod:`dynamics.effects`) with
``params = [area, s1, s2, gamma]``: drop area A (length^2), contact arclengths S1 < S2
(length, anywhere inside edges) and line tension gamma (force). A timed
``dynamics.Event(time, "capillary", "s2", value)`` moves a contact line (the paper's
secondary drop, Fig 5). The kernel is the exact gradient of gamma lambda from
:func:`elastocap.drop.capillary_energy_and_gradient`, so with no damping and no contact the
total energy is conserved by the symplectic stepper (tested). Its stiffness, the Hessian of
gamma lambda, is the optional ``stiffness`` hook of the protocol
(:func:`elastocap.capillary_hessian.capillary_stiffness`), which the implicit stepper puts
into its Newton matrix.
"""

from __future__ import annotations

import numba
import numpy as np

from elastocap.capillary_hessian import capillary_stiffness
from elastocap.drop import capillary_energy_and_gradient

__all__ = ["Capillary", "capillary_kernel"]


@numba.njit(cache=True)
def capillary_kernel(x, v, t, params, edge_len, mass, out_force):
    """Add -gamma grad(lambda) to ``out_force`` (n, 2); return gamma lambda.

    Parameters follow the `dynamics` force protocol; ``params = [A, S1, S2, gamma]``.
    """
    n = x.shape[0]
    s = np.empty(n)
    # node arclengths by blocks of four edges: the running sum (the serial chain of
    # additions, 4 cycles each: 0.2 us at 200 nodes, 2% of a time step) advances once a
    # block; the result differs from a running sum by round-off
    s[0] = 0.0
    acc = 0.0
    i = 0
    while i + 4 <= n - 1:
        e01 = edge_len[i] + edge_len[i + 1]
        e012 = e01 + edge_len[i + 2]
        s[i + 1] = acc + edge_len[i]
        s[i + 2] = acc + e01
        s[i + 3] = acc + e012
        acc = acc + (e012 + edge_len[i + 3])
        s[i + 4] = acc
        i += 4
    while i < n - 1:
        acc = acc + edge_len[i]
        s[i + 1] = acc
        i += 1
    # the gradient is linear in gamma: passing -gamma ADDS the force -gamma grad(lambda)
    # to out_force directly (no scratch array) and returns -gamma lambda
    e, _tau, _kappa = capillary_energy_and_gradient(
        x, s, params[1], params[2], params[0], -params[3], out_force
    )
    return -e


class Capillary:
    """The drop as a `dynamics` force effect.

    Parameters
    ----------
    area : float
        Drop area A (length^2).
    s1, s2 : float
        Contact arclengths, 0 <= s1 < s2 <= L.
    gamma : float
        Line tension (force).
    name : str
    """

    kind = "force"
    param_names = ("area", "s1", "s2", "gamma")
    kernel = capillary_kernel
    stiffness = capillary_stiffness

    def __init__(self, area, s1, s2, gamma, name="capillary"):
        if not (area > 0 and gamma > 0 and 0.0 <= s1 < s2):
            raise ValueError(
                f"Capillary: got area={area!r}, s1={s1!r}, s2={s2!r}, gamma={gamma!r}; "
                "expected area > 0, gamma > 0 and 0 <= s1 < s2"
            )
        self.name = name
        self.params = np.array([area, s1, s2, gamma], dtype=np.float64)
