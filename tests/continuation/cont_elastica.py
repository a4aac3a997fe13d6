"""Pinned-pinned inextensible elastica under end load P (bending stiffness B = 1).

theta(s) is the tangent angle; the energy
``E = int theta'^2 / 2 ds + P int cos(theta) ds`` (end shortening times P,
up to a constant) is minimised subject to ``y(L) = int sin(theta) ds = 0``
(the ends stay on the line of the load), with multiplier R (the transverse
end reaction). Discretised by the energy itself: nodes s_i = i h, trapezoid
weights, so the residual is an exact gradient, the Jacobian is symmetric and
the natural boundary conditions theta'(0) = theta'(L) = 0 come out weakly.
Order 2 in h. The discrete buckling loads are known in closed form:
``P_k^h = (4 / h^2) sin^2(k pi h / (2 L))`` (eigenvectors cos(k pi s_i / L)),
tending to ``k^2 pi^2 / L^2``.
"""

import numpy as np
import scipy.sparse as sp

from continuation import Problem


class Elastica(Problem):
    def __init__(self, N=100, L=1.0, sparse=False):
        self.N, self.L, self.h = N, L, L / N
        self.name = f"elastica-{N}"
        h = self.h
        w = np.full(N + 1, h)
        w[[0, -1]] = h / 2
        self.w = w
        main = np.full(N + 1, 2.0)
        main[[0, -1]] = 1.0
        self.K = (sp.diags([-np.ones(N), main, -np.ones(N)], [-1, 0, 1]) / h).toarray()
        self.sparse = sparse

    def split(self, u):
        return u[:-1], u[-1]

    def residual(self, u, P):
        th, R = self.split(u)
        w = self.w
        return np.concatenate([self.K @ th - P * w * np.sin(th) + R * w * np.cos(th),
                               [w @ np.sin(th)]])

    def hessian(self, u, P):
        th, R = self.split(u)
        H = self.K.copy()
        H[np.diag_indices_from(H)] += -P * self.w * np.cos(th) - R * self.w * np.sin(th)
        return H

    def constraint_jacobian(self, u, P):
        th, _ = self.split(u)
        return (self.w * np.cos(th))[None, :]

    def jacobian(self, u, P):
        n = self.N + 2
        J = np.zeros((n, n))
        J[:-1, :-1] = self.hessian(u, P)
        c = self.constraint_jacobian(u, P)[0]
        J[:-1, -1] = c
        J[-1, :-1] = c
        return sp.csc_matrix(J) if self.sparse else J

    def dfdp(self, u, P):
        th, _ = self.split(u)
        return np.concatenate([-self.w * np.sin(th), [0.0]])

    def observables(self, u, P):
        th, R = self.split(u)
        return {"theta0": float(th[0]), "R": float(R)}

    def discrete_buckling_load(self, k):
        return (4.0 / self.h**2) * np.sin(k * np.pi * self.h / (2 * self.L)) ** 2
