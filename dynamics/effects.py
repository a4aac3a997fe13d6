"""Built-in effects acting on a planar rod, and the protocol external effects follow.

Every effect is a small object with four attributes (the *effect protocol*):

``name`` : str
    Unique within a simulation; energies are reported under it and events address it.
``kind`` : {"force", "damping", "constraint"}
    Selects the call site and the kernel signature, see below.
``params`` : ndarray of float64, shape (p,)
    All the effect's parameters.  The stepper passes this very array to the kernel, so a
    timed :class:`~dynamics.Event` (or the user, between runs) changes a
    parameter by writing ``params[j]``.  Integer parameters (node indices) are stored as
    floats and cast in the kernel.
``kernel`` : numba dispatcher, ``numba.njit(cache=True)``, defined at module level
    The stepper generates a module that imports it by ``kernel.__module__`` and
    ``kernel.__name__``, so it must be importable (not defined in ``__main__`` or in a
    function).  Signatures (arrays float64, C-contiguous; ``n = n_nodes``):

    * ``"force"``: ``kernel(x, v, t, params, edge_len, mass, out_force) -> float``
      with ``x, v`` (n, 2) positions and velocities, ``t`` the time, ``edge_len`` (n-1,)
      rest edge lengths, ``mass`` (n,) lumped node masses; *adds* the force (n, 2) to
      ``out_force`` and returns its potential energy ``U`` (0.0 for a non-conservative
      force).  For a conservative force ``out_force += -grad U``; the energy test of the
      integrator then covers it.  ``v`` is the half-step velocity (velocity-dependent
      forces are first order in time).
    * ``"damping"``: ``kernel(x, v, t, params, edge_len, mass, h) -> None`` advances the
      velocities in place by the *exact* solution of its linear dissipation over a time
      ``h`` (called twice per step, Strang splitting, ``h = dt/2``).
    * ``"constraint"``: ``kernel(x, v, t, params, edge_len, winv, stage) -> None``.
      ``stage == 0`` is called after the drift, before the inextensibility projection:
      set the held coordinates of the predicted positions ``x`` and zero the matching
      entries of the per-coordinate inverse mass ``winv`` (n, 2), so that the projection
      cannot move them.  ``stage == 1`` is called after the final kick, before the
      velocity projection: set the velocities of the held coordinates (and leave ``winv``
      as stage 0 set it: the velocity projection reuses SHAKE's copy of it).

How a method learns what an effect is: from ``kind`` and from optional attributes, never
from the effect's name or its position in the list.  Optional attributes:

``ground_height_param`` : int, of a constraint effect
    Declares the effect a frictionless rigid ground ``z >= params[ground_height_param]``
    (perfectly inelastic).  Both methods need the index to be 0.  RATTLE calls its kernel
    (stage 0 holds, stage 1 stops) and then releases every held node the ground would
    pull (no adhesion: :mod:`dynamics.rattle`); the midpoint method
    (:mod:`dynamics.midpoint`) does not call it and puts the ground into its Newton
    system instead.  :class:`Ground` sets it.
``self_contact_thickness_param`` : int, of a constraint effect
    Declares the effect the rod's self-contact with thickness
    ``params[self_contact_thickness_param]`` (must be 0): both methods handle it
    themselves (:mod:`dynamics.contact`) and never call its kernel.
    :class:`SelfContact` sets it.

Optional hook of a force effect, read by the midpoint method only (RATTLE needs no
derivatives):

``stiffness`` : numba dispatcher, ``numba.njit(cache=True)``, module level
    ``stiffness(x, v, t, params, edge_len, mass, K, U, C) -> int``: the stiffness
    ``-dF/dx`` of the force at ``x`` (the Hessian of ``U`` for a conservative force; force
    / length units), split into a band and a low-rank part so that the stepper can put it
    into its banded Newton matrix exactly, ``-dF/dx = K + sum_rs C[r, s] U[r] U[s]^T``:

    * ``K`` (n, 2, 2 STIFFNESS_BAND + 1, 2), accumulated into (other hooks share it):
      ``K[i, a, j - i + STIFFNESS_BAND, b] += -dF_{i,a}/dx_{j,b}`` for
      ``|i - j| <= STIFFNESS_BAND``;
    * ``U`` (>= k, n, 2) and ``C`` (>= k, >= k), zero on entry: write ``U[:k]`` and
      ``C[:k, :k]`` and return ``k <= STIFFNESS_RANK`` (0: no low-rank part).

    Without the hook (gravity, constant loads: zero stiffness) the Newton matrix leaves the
    force out and nothing is spent on it; a stiff force without it slows Newton to a linear
    rate ``~ dt**2 |K| / (4 m)`` (the drop of an encapsulating supp-fig5 impact at 64x the
    explicit bound: 11.6 iterations a step without its stiffness, 6.1 with it).  Returning
    0 without touching ``K`` is always allowed (e.g. a degenerate geometry): Newton then
    converges more slowly.

Built in: :class:`Gravity`, :class:`PointLoad`, :class:`DistributedLoad` (forces),
:class:`Damping` (damping), :class:`Ground`, :class:`Clamp`, :class:`SelfContact`
(constraints).

An external force effect, e.g. a drop with ``params = [area, s1, s2, gamma]``::

    # mypkg/capillary.py  (module level, importable)
    @numba.njit(cache=True)
    def capillary_kernel(x, v, t, params, edge_len, mass, out_force):
        area, s1, s2, gamma = params[0], params[1], params[2], params[3]
        ...                       # out_force += -grad U
        return U

    class Capillary:              # or subclass dynamics.Effect
        kind = "force"
        param_names = ("area", "s1", "s2", "gamma")
        kernel = capillary_kernel
        def __init__(self, area, s1, s2, gamma, name="capillary"):
            self.name = name
            self.params = np.array([area, s1, s2, gamma], dtype=np.float64)

    simulate(rod, (Capillary(1.0, 0.5, 2.0, 1.0), Damping(0.1)), dt=..., t_end=...,
             events=(Event(2.0, "capillary", "s2", 2.4),))

The stepper regenerates (and numba recompiles) its loop when the kernel's source file
changes (its modification time and size are part of the generated module's hash).
"""

from __future__ import annotations

import inspect
import math

import numba
import numpy as np

__all__ = [
    "Effect",
    "Gravity",
    "PointLoad",
    "DistributedLoad",
    "Damping",
    "Ground",
    "Clamp",
    "SelfContact",
    "KINDS",
    "STIFFNESS_BAND",
    "STIFFNESS_RANK",
]

KINDS = ("force", "damping", "constraint")

#: Node half-bandwidth of the band part ``K`` of a ``stiffness`` hook: the implicit
#: stepper's banded Newton matrix couples nodes up to two apart (bending's reach).
STIFFNESS_BAND = 2
#: Most low-rank columns one ``stiffness`` hook may return (the drop needs 5); each costs
#: one extra band solve per factorisation of the Newton matrix.
STIFFNESS_RANK = 8


class Effect:
    """Base class of the built-in effects (external effects need not subclass it).

    Attributes
    ----------
    name : str
    kind : str
    params : ndarray, shape (p,)
    param_names : tuple of str
        Names of the entries of ``params``; events may address a parameter by name.
    kernel : numba dispatcher
    """

    kind = "force"
    param_names: tuple[str, ...] = ()
    kernel = None

    def __init__(self, name, params):
        self.name = str(name)
        # a numba dispatcher stored as a class attribute binds like a method when read
        # through the instance; keep the plain dispatcher on the instance
        self.kernel = inspect.getattr_static(self, "kernel")
        self.params = np.ascontiguousarray(params, dtype=np.float64).ravel()
        if self.param_names and self.params.size != len(self.param_names):
            raise ValueError(
                f"{type(self).__name__} {self.name!r}: expected {len(self.param_names)} "
                f"parameters {self.param_names}, got {self.params.size}"
            )
        if not np.all(np.isfinite(self.params)):
            raise ValueError(
                f"{type(self).__name__} {self.name!r}: parameters must be finite, got "
                f"{dict(zip(self.param_names, self.params.tolist(), strict=False))}"
            )

    def __repr__(self):
        vals = ", ".join(
            f"{k}={v:g}" for k, v in zip(self.param_names, self.params, strict=False)
        )
        return f"{type(self).__name__}(name={self.name!r}, {vals})"


# ----------------------------------------------------------------------------- kernels


@numba.njit(cache=True)
def voronoi_lengths(edge_len, out):
    """Voronoi length of every node, ``(l_{i-1} + l_i)/2`` (half an edge at the ends)."""
    n = out.shape[0]
    for i in range(n):
        s = 0.0
        if i > 0:
            s += edge_len[i - 1]
        if i < n - 1:
            s += edge_len[i]
        out[i] = 0.5 * s
    return out


@numba.njit(cache=True)
def gravity_kernel(x, v, t, params, edge_len, mass, out_force):
    """Uniform gravity ``-m_i g e_z``; ``params = [g]``; returns ``U = sum m_i g z_i``."""
    g = params[0]
    n = x.shape[0]
    for i in range(n):
        out_force[i, 1] -= mass[i] * g
    # four partial sums (a running sum is a serial chain of additions: 0.2 us at 200
    # nodes); the result differs from it by round-off
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    s3 = 0.0
    i = 0
    while i + 3 < n:
        s0 += mass[i] * x[i, 1]
        s1 += mass[i + 1] * x[i + 1, 1]
        s2 += mass[i + 2] * x[i + 2, 1]
        s3 += mass[i + 3] * x[i + 3, 1]
        i += 4
    while i < n:
        s0 += mass[i] * x[i, 1]
        i += 1
    return g * ((s0 + s1) + (s2 + s3))


@numba.njit(cache=True)
def point_load_kernel(x, v, t, params, edge_len, mass, out_force):
    """Constant force ``(fx, fz)`` on one node; ``params = [node, fx, fz]``; ``U = -f.x``."""
    i = int(params[0])
    if i < 0:
        i += x.shape[0]
    out_force[i, 0] += params[1]
    out_force[i, 1] += params[2]
    return -(params[1] * x[i, 0] + params[2] * x[i, 1])


@numba.njit(cache=True)
def distributed_load_kernel(x, v, t, params, edge_len, mass, out_force):
    """Constant load per unit length ``(qx, qz)`` lumped on Voronoi lengths.

    ``params = [qx, qz]``; returns ``U = -sum_i lbar_i q.x_i``.
    """
    n = x.shape[0]
    U = 0.0
    for i in range(n):
        s = 0.0
        if i > 0:
            s += edge_len[i - 1]
        if i < n - 1:
            s += edge_len[i]
        fx = 0.5 * s * params[0]
        fz = 0.5 * s * params[1]
        out_force[i, 0] += fx
        out_force[i, 1] += fz
        U -= fx * x[i, 0] + fz * x[i, 1]
    return U


@numba.njit(cache=True)
def damping_kernel(x, v, t, params, edge_len, mass, h):
    """Exact viscous decay over ``h``: force ``-c v`` per unit length; ``params = [c]``.

    Node ``i`` obeys ``m_i dv/dt = -c lbar_i v``, so ``v_i <- v_i exp(-c lbar_i h / m_i)``;
    for a uniform rod the rate ``c / mu`` is the same at every node, which keeps the
    velocities tangent to the constraints.
    """
    c = params[0]
    n = x.shape[0]
    r_prev = -1.0
    f = 1.0
    for i in range(n):
        s = 0.0
        if i > 0:
            s += edge_len[i - 1]
        if i < n - 1:
            s += edge_len[i]
        r = 0.5 * s / mass[i]
        # exp is the cost here (2 n per step, +30% on a 200-edge step); the rate is the
        # same at every node of a uniform rod, so reuse it unless it changes beyond
        # round-off
        if abs(r - r_prev) > 4e-16 * r:
            f = math.exp(-c * r * h)
            r_prev = r
        v[i, 0] *= f
        v[i, 1] *= f


@numba.njit(cache=True)
def ground_kernel(x, v, t, params, edge_len, winv, stage):
    """Frictionless rigid ground ``z >= z0``; ``params = [z0]``.

    Stage 0: a predicted node below the ground is put on it and its vertical coordinate
    held (``winv[i, 1] = 0``) during the inextensibility projection, which can then only
    slide it horizontally: no penetration, no sinking.  Stage 1: a node on the ground
    loses any downward velocity (perfectly inelastic impulse); a node resting on the
    ground therefore has exactly zero vertical velocity, hence no jitter.
    """
    z0 = params[0]
    n = x.shape[0]
    if stage == 0:
        for i in range(n):
            if x[i, 1] < z0:
                x[i, 1] = z0
                winv[i, 1] = 0.0
    else:
        for i in range(n):
            if x[i, 1] <= z0 and v[i, 1] < 0.0:
                v[i, 1] = 0.0


@numba.njit(cache=True)
def clamp_kernel(x, v, t, params, edge_len, winv, stage):
    """Clamp node ``k`` at ``(px, pz)``, optionally with its edge at angle ``theta``.

    ``params = [node, px, pz, fix_direction, theta]``.  With ``fix_direction != 0`` the
    neighbouring node (``k+1``, or ``k-1`` for the last node) is also held so that the
    tangent of the clamped edge, in the direction of increasing node index, is
    ``(cos theta, sin theta)``.  Held nodes have zero velocity.
    """
    n = x.shape[0]
    k = int(params[0])
    if k < 0:
        k += n
    if stage == 0:
        x[k, 0] = params[1]
        x[k, 1] = params[2]
        winv[k, 0] = 0.0
        winv[k, 1] = 0.0
        if params[3] != 0.0:
            ct = math.cos(params[4])
            st = math.sin(params[4])
            if k < n - 1:
                j = k + 1
                sgn = 1.0
                le = edge_len[k]
            else:
                j = k - 1
                sgn = -1.0
                le = edge_len[k - 1]
            x[j, 0] = params[1] + sgn * le * ct
            x[j, 1] = params[2] + sgn * le * st
            winv[j, 0] = 0.0
            winv[j, 1] = 0.0
    else:
        v[k, 0] = 0.0
        v[k, 1] = 0.0
        if params[3] != 0.0:
            j = k + 1 if k < n - 1 else k - 1
            v[j, 0] = 0.0
            v[j, 1] = 0.0


@numba.njit(cache=True)
def self_contact_kernel(x, v, t, params, edge_len, winv, stage):
    """The kernel slot of :class:`SelfContact`: never called (the methods enforce
    self-contact inside their projections, :mod:`dynamics.contact`); does nothing."""
    return None


# ----------------------------------------------------------------------------- classes


class Gravity(Effect):
    """Uniform gravity acting along ``-z``.

    Parameters
    ----------
    g : float
        Gravitational acceleration (length / time**2), >= 0 pulls down.
    name : str, optional
    """

    kind = "force"
    param_names = ("g",)
    kernel = gravity_kernel

    def __init__(self, g=1.0, name="gravity"):
        super().__init__(name, [g])


class PointLoad(Effect):
    """Constant point force on one node.

    Parameters
    ----------
    node : int
        Node index (negative indices count from the end, ``-1`` = last node).
    force : (float, float)
        Force ``(fx, fz)`` (force units).
    name : str, optional
    """

    kind = "force"
    param_names = ("node", "fx", "fz")
    kernel = point_load_kernel

    def __init__(self, node, force, name="point_load"):
        fx, fz = force
        super().__init__(name, [node, fx, fz])


class DistributedLoad(Effect):
    """Constant load per unit (rest) length, lumped on the nodes' Voronoi lengths.

    Parameters
    ----------
    q : (float, float)
        Load ``(qx, qz)`` (force / length units).
    name : str, optional
    """

    kind = "force"
    param_names = ("qx", "qz")
    kernel = distributed_load_kernel

    def __init__(self, q, name="distributed_load"):
        super().__init__(name, list(q))


class Damping(Effect):
    """Viscous damping, force ``-c v`` per unit length, integrated exactly.

    Parameters
    ----------
    c : float
        Damping coefficient (mass / (length time)); ``c / mu`` is the velocity decay rate
        (1 / time), so kinetic energy of a rigid translation decays as
        ``exp(-2 c t / mu)``.  Exact integration means damping never limits stability.
        Its accuracy does: under a steady force f the rod creeps at ``(a/2) coth(a/2)``
        times its terminal speed ``f / c`` (``a = c dt / mu``), and the velocity held at
        the step is ``(a/2) / sinh(a/2)`` of it, so at ``a >> 1`` a kinetic
        :class:`RestCriterion` reads an overdamped creep as rest.  Keep ``a`` below
        about 0.3 (+0.75 % and -0.37 %).
    name : str, optional
    """

    kind = "damping"
    param_names = ("c",)
    kernel = damping_kernel

    def __init__(self, c, name="damping"):
        if c < 0:
            raise ValueError(f"Damping coefficient c must be >= 0, got c = {c!r}")
        super().__init__(name, [c])


class Ground(Effect):
    """Frictionless rigid ground ``z >= z0`` (perfectly inelastic contact).

    Coexistence with inextensibility: a node that would penetrate is put on the ground
    and its vertical inverse mass set to zero for the SHAKE and RATTLE projections, so the
    edge-length projection can only slide it along the ground; afterwards its downward
    velocity is removed.  Contact is re-detected every step (a node lifts off as soon as
    its predicted position is above the ground).  Contact energy is lost, as in a
    plastic impact: with ground contact the total energy is not conserved.

    Parameters
    ----------
    z0 : float, optional
        Ground height (length units).
    name : str, optional
    """

    kind = "constraint"
    param_names = ("z0",)
    kernel = ground_kernel
    ground_height_param = 0

    def __init__(self, z0=0.0, name="ground"):
        super().__init__(name, [z0])


class Clamp(Effect):
    """Fix a node's position and, optionally, the direction of its edge.

    Parameters
    ----------
    node : int
        Clamped node (negative indices count from the end).
    position : (float, float)
        Clamp position ``(px, pz)`` (length units).
    angle : float or None, optional
        Tangent angle (radians, from ``+x`` towards ``+z``) of the clamped edge in the
        direction of increasing node index; ``None`` (default) leaves the rod free to
        rotate about the node (a pin).  A clamped edge is rigid: for a clamped-free beam
        of length ``L`` put the clamp at the *midpoint* of the first edge (node 0 at
        ``-h/2``, node 1 at ``+h/2``), which gives second-order convergence of the
        frequencies (``tests/dynamics/test_validation.py``).
    name : str, optional
    """

    kind = "constraint"
    param_names = ("node", "px", "pz", "fix_direction", "theta")
    kernel = clamp_kernel

    def __init__(self, node, position, angle=None, name="clamp"):
        px, pz = position
        fix = 0.0 if angle is None else 1.0
        theta = 0.0 if angle is None else float(angle)
        super().__init__(name, [node, px, pz, fix, theta])


class SelfContact(Effect):
    """The rod cannot pass through itself: a tube of diameter ``thickness``.

    Non-penetration is a set of unilateral constraints, frictionless, with restitution 0
    (as the ground's): every node stays at least ``thickness`` away from every segment
    more than :func:`dynamics.contact.exclusion_length` (``pi thickness / 2``) away from it
    along the rod.  Both methods enforce it inside their position and velocity projections
    to the tolerance of the edge lengths (:mod:`dynamics.contact`); the contact forces of
    the last step are ``SimulationResult.contact_forces``.  A run without this effect
    generates no contact code.

    Parameters
    ----------
    thickness : float
        Diameter of the rod (length units), > 0.  The initial state should respect it.
    name : str, optional
    """

    kind = "constraint"
    param_names = ("thickness",)
    kernel = self_contact_kernel
    self_contact_thickness_param = 0

    def __init__(self, thickness, name="self_contact"):
        if not (thickness > 0 and math.isfinite(thickness)):
            raise ValueError(f"SelfContact thickness must be > 0 and finite, got {thickness!r}")
        super().__init__(name, [thickness])


def is_ground(effect) -> bool:
    """Whether an effect is a frictionless rigid ground, by the effect protocol (a
    constraint effect declaring ``ground_height_param``, the index of its height z0 in
    ``params``; :class:`Ground` does)."""
    return (getattr(effect, "kind", None) == "constraint"
            and getattr(effect, "ground_height_param", None) is not None)


def is_self_contact(effect) -> bool:
    """Whether an effect is the rod's self-contact, by the effect protocol (it declares
    ``self_contact_thickness_param``; :class:`SelfContact` does)."""
    return (getattr(effect, "kind", None) == "constraint"
            and getattr(effect, "self_contact_thickness_param", None) is not None)
