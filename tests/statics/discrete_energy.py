"""The discrete energy that `dynamics` integrates (DER bending + gamma lambda of the
polyline), as a function of the edge angles of an inextensible rod, for statics tests."""

import numpy as np

from dynamics.bending import bending_energy, bending_gradient
from elastocap.drop import capillary_energy_and_gradient


class DiscreteRodEnergy:
    """E(phi) for a rod of n equal edges of length h = L/n with edge angles phi."""

    def __init__(self, n, L, B, gamma, area, s1, s2):
        self.n, self.h = n, L / n
        self.edge = np.full(n, self.h)
        self.s = np.linspace(0.0, L, n + 1)
        self.B, self.gamma, self.area, self.s1, self.s2 = B, gamma, area, s1, s2

    def positions(self, phi):
        x = np.zeros((self.n + 1, 2))
        x[1:, 0] = np.cumsum(self.h * np.cos(phi))
        x[1:, 1] = np.cumsum(self.h * np.sin(phi))
        return x

    def energy_grad(self, phi):
        x = self.positions(phi)
        g = np.zeros_like(x)
        e = capillary_energy_and_gradient(x, self.s, self.s1, self.s2, self.area, self.gamma, g)[0]
        e += bending_energy(x, self.edge, self.B)
        gb = np.zeros_like(x)
        bending_gradient(x, self.edge, self.B, gb)
        g += gb
        # x_k depends on phi_i for k > i: dE/dphi_i = sum_{k>i} g_k . h (-sin, cos)
        tail = np.cumsum(g[::-1], axis=0)[::-1][1:]
        dphi = self.h * (-np.sin(phi) * tail[:, 0] + np.cos(phi) * tail[:, 1])
        return e, dphi
