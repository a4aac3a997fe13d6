"""Energies of the encapsulated strip (fig3-strip) against the energy the impact brings.

All energies are in the scene's unit: with g = mu = B = 1 (length l_eg), the energy unit is
mu g l_eg^2 = B / l_eg (mu, B per strip: the paper's hatted lineic mass and bending
modulus), 1.245e-8 J for the paper's strip (mu = 51.8 g/m^2 x 2 mm, l_eg = 3.50 mm).

Quantities, at a drop position x and wetted length Delta:

* ``e_flat`` = gamma lambda(A, Delta): the release state of the impact model (straight strip
  on the ground, drop spread to Delta, at rest; elastocap.impact starts there).
* ``e_wrapped``: the encapsulated (lifted, wrapped) equilibrium of
  :class:`~elastocap.strip.problem.StripProblem`, and its parts (``e_gravity`` is the
  gravitational energy q int z ds stored by lifting the strip).
* ``release`` = e_flat - e_wrapped: energy the capillary forces release by encapsulating.
* the least-energy path at prescribed tip angle theta(L) (an end couple C is the
  multiplier), from the wrapped state towards the open one, until it leaves the handled
  contact topology: ``e_edge`` - e_wrapped is the energy needed to unwrap the strip to the
  edge of that topology (where the lift-off point reaches S1): a lower bound of the depth
  of the encapsulated well along that path.
* ``kinetic_energy``: the drop's kinetic energy at impact, (1/2) rho V U^2 with
  V = A l_eg (the paper's A = V / l_eg) and rho U^2 = gamma We / R, so
  E_k = A gamma_hat We / (2 w R) in scene units, w = strip width / l_eg (2 mm / 3.50 mm);
  We from the spreading law, We^(1/2) = (Delta - Delta0) / (2 R 0.32).
"""

from __future__ import annotations

import math

import numpy as np

from continuation import ContinuationSettings, continue_branch
from elastocap.drop import cap_geometry
from elastocap.strip.branches import _event_valid, _events, trace_strip_branches
from elastocap.strip.problem import StripProblem

__all__ = [
    "PAPER_WIDTH",
    "barrier_table",
    "flat_energy",
    "kinetic_energy",
    "tip_angle_path",
    "existence_region",
    "wrapped_branches",
]

#: Strip width over l_eg for the paper's 2D experiment (w = 2 mm, l_eg = 3.4996 mm as in
#: the fig3-strip scene); the 2D model itself has no width, only E_k needs it.
PAPER_WIDTH = 2.0 / 3.4996


def kinetic_energy(scene, we, width: float = PAPER_WIDTH) -> float:
    """Kinetic energy of the impacting drop, (1/2) rho V U^2, in scene energy units.

    Parameters
    ----------
    scene : Scene
        Supplies A (= V / l_eg), gamma_hat and R (``spreading.drop_radius``).
    we : float
        Weber number rho U^2 R / gamma (not its square root).
    width : float
        Strip width in scene length units (gamma = gamma_hat / width is the surface
        tension).
    """
    if scene.spreading is None:
        raise ValueError("scene.spreading: got None; the kinetic energy needs drop_radius")
    R = scene.spreading.drop_radius
    return scene.drop.area * scene.drop.line_tension * we / (2.0 * width * R)


def flat_energy(area: float, gamma: float, delta: float) -> float:
    """gamma lambda(A, Delta): the drop on the straight strip (the impact's release state)."""
    return gamma * cap_geometry(area, delta)[3]


def tip_angle_path(problem: StripProblem, u, dtheta_max=0.1, max_steps=300) -> dict:
    """Least-energy path at prescribed tip angle, from an equilibrium towards smaller theta(L).

    Parameters
    ----------
    problem : StripProblem
        Unconstrained problem at the (x, Delta) of ``u``.
    u : ndarray
        An equilibrium of ``problem`` (couple 0).

    Returns
    -------
    dict with arrays ``tip_angle``, ``energy``, ``gravity``, ``couple``, ``lift_off``,
    ``stop`` (the branch message: which topology boundary ended the path) and the located
    end: ``edge`` (event name or None), ``edge_energy``, ``edge_tip_angle``.
    """
    theta_l = float(problem.full_theta(u)[-1])
    cp = StripProblem(problem.Ns, *(problem.params[k] for k in
                      ("L", "x_end", "delta", "area", "gamma", "B", "q", "F")),
                      parameter="tip_angle", tip_angle=theta_l)
    uc = np.concatenate([u[:-1], [0.0], u[-1:]])
    st = ContinuationSettings(
        ds0=0.02, ds_min=1e-9, ds_max=dtheta_max, max_steps=max_steps, p_min=-math.pi,
        p_max=theta_l + 1.0, direction=-1, newton_tol=1e-9, compute_stability=False,
        check_jacobian=False,
    )
    br = continue_branch(cp, uc, theta_l, st, events=_events(cp),
                         stop_on=["touchdown", "lift_off_at_S1"])
    o = br.observables
    ok = (o["dry_length"] > 0.0) & (o["lowest_point"] > -1e-9)
    # the located terminal event (the edge of the topology), if the path reached one
    edge = [
        sp for sp in br.points("event")
        if sp.name in ("touchdown", "lift_off_at_S1") and _event_valid(cp, sp)
    ]
    edge_e = edge_t = math.nan
    edge_name = None
    if edge and edge[0].u is not None:
        cp.set("tip_angle", edge[0].p)
        edge_e, edge_t, edge_name = cp.energy(edge[0].u), float(edge[0].p), edge[0].name
    return {
        "edge_energy": edge_e,
        "edge_tip_angle": edge_t,
        "edge": edge_name,
        "tip_angle": br.p[ok],
        "energy": o["energy"][ok],
        "gravity": o["gravity"][ok],
        "couple": o["couple"][ok],
        "lift_off": o["lift_off"][ok],
        "stop": br.message,
    }


def wrapped_branches(bs) -> list:
    """The stable encapsulated branches of a StripBranchSet: every point stable, the tail
    folded back over the impact point (the paper's criterion, encapsulation > 0)."""
    return [
        br for br in bs.branches
        if len(br) and np.all(br.stability == 0) and np.all(br.observables["encapsulation"] > 0)
    ]


def barrier_table(scene, xs, n_delta=6, N=None) -> list[dict]:
    """Energies of the wrapped equilibrium over its existence window, for each x.

    Returns one dict per x: ``x``, ``window`` [Delta_lo, Delta_hi] and the reasons that end
    it, and lists over ``n_delta`` values of Delta in the window of ``delta``, ``we_sqrt``,
    ``e_flat``, ``e_wrapped``, ``e_gravity``, ``release``, ``unwrap`` (e_edge - e_wrapped),
    ``kinetic`` (E_k at that We), ``stable`` (stability index 0).
    """
    out = []
    for x in xs:
        sc = scene.with_overrides({"drop.distance_from_end": float(x)})
        bs = trace_strip_branches(sc, N=N, error_estimates=False)
        row = {"x": float(x), "window": None, "ends": [], "delta": [], "we_sqrt": [],
               "e_flat": [], "e_wrapped": [], "e_gravity": [], "release": [], "unwrap": [],
               "kinetic": [], "stable": []}
        good = wrapped_branches(bs)
        if not good:
            out.append(row)
            continue
        br = max(good, key=len)
        b = bs.branches.index(br)
        row["ends"] = [(e["value"], e["kind"]) for e in bs.endpoints
                       if e["kind"] != "endpoint" and e["branch"] == b]
        vals = [float(br.p.min()), float(br.p.max())] + [v for v, _k in row["ends"]]
        row["window"] = [min(vals), max(vals)]
        pr = bs.problem
        for d in np.linspace(br.p.min(), br.p.max(), n_delta):
            i = int(np.argmin(np.abs(br.p - d)))
            d, u = float(br.p[i]), br.u[i]
            pr.set("drop.wetted_length", d)
            ob = pr.observables(u, d)
            ef = flat_energy(pr.params["area"], pr.params["gamma"], d)
            path = tip_angle_path(pr, u)
            ws = sc.spreading.we_sqrt(d)
            row["delta"].append(d)
            row["we_sqrt"].append(ws)
            row["e_flat"].append(ef)
            row["e_wrapped"].append(ob["energy"])
            row["e_gravity"].append(ob["gravity"])
            row["release"].append(ef - ob["energy"])
            e_edge = path["edge_energy"] if math.isfinite(path["edge_energy"]) else math.nan
            row["unwrap"].append(float(e_edge - ob["energy"]))
            row["kinetic"].append(kinetic_energy(sc, max(ws, 0.0) ** 2))
            row["stable"].append(bool(br.stability[i] == 0))
        out.append(row)
    return out


def existence_region(scene, deltas, x_seeds=(1.6, 2.0), N=None) -> list[dict]:
    """The window of x in which the lifted, wrapped equilibrium exists, for each Delta.

    Branches in Delta are traced at the drop positions ``x_seeds``; from their state at each
    Delta of ``deltas`` the equilibrium is continued in x both ways until it leaves the
    handled topology. Returns per Delta: ``delta``, ``we_sqrt``, ``x_lo``, ``x_hi`` (NaN if no
    seed branch covers that Delta), ``ends`` (the events ending the x-window), ``stable``
    (stability index 0 over the whole window).
    """
    from elastocap.statics.branches import newton
    from elastocap.strip.branches import trim_branch

    seeds = []
    for x0 in x_seeds:
        bs = trace_strip_branches(scene.with_overrides({"drop.distance_from_end": float(x0)}),
                                  N=N, error_estimates=False)
        seeds += [(float(x0), br, bs.problem) for br in wrapped_branches(bs)]
    out = []
    for d in deltas:
        row = {"delta": float(d), "we_sqrt": scene.spreading.we_sqrt(d), "x_lo": math.nan,
               "x_hi": math.nan, "ends": [], "stable": False}
        for x0, br, pr in seeds:
            if not br.p.min() <= d <= br.p.max():
                continue
            i = int(np.argmin(np.abs(br.p - d)))
            P = pr.copy(parameter="drop.distance_from_end")
            P.set("drop.wetted_length", float(br.p[i]))
            P.set("drop.wetted_length", float(d))
            u = newton(P, br.u[i], x0, 1e-9, max_iter=30)
            if u is None:
                continue
            st = ContinuationSettings(
                ds0=0.02, ds_min=1e-9, ds_max=0.05, max_steps=400, p_min=0.5 * d + 0.02,
                p_max=8.0, direction=0, newton_tol=1e-9, check_jacobian=False,
            )
            bx = trim_branch(continue_branch(P, u, x0, st, events=_events(P),
                                             stop_on=["touchdown", "lift_off_at_S1"]), P)
            row["x_lo"], row["x_hi"] = float(bx.p.min()), float(bx.p.max())
            row["ends"] = [(float(sp.p), sp.name) for sp in bx.points("event")]
            # the located events bound the window (the points stop one step inside)
            for v, _name in row["ends"]:
                if v <= row["x_lo"]:
                    row["x_lo"] = v
                elif v >= row["x_hi"]:
                    row["x_hi"] = v
            row["stable"] = bool(np.all(bx.stability == 0))
            break
        out.append(row)
    return out
