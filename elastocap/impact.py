"""The impact run: a scene's effects on the dynamic elastica, run to rest, and its outcome.

The rod starts straight along +x (S = 0 at x = 0) and at rest, on the ground z = 0 when the
scene has one; the drop is already spread to its wetted length Delta (the fast spreading is
over, paper main text) and the rod is released. The run ends when the kinetic energy stays
below ``numerics.rest_kinetic`` (times the scale gamma Delta, the capillary energy
available) for ``numerics.rest_time``, or at ``numerics.t_max``.

Outcome
-------
* Scenes with gravity or a ground (the strip of Fig 3): the paper's criterion (Methods):
  encapsulated when the free end S = L ends to the left of the impact centre S = L - x,
  x(L) < x(L - x_impact) in the lab frame.
* A run that fails numerically (the projection does not converge, a non-finite state) has
  outcome ``"failed"`` and a message saying where and what to try, never a guessed outcome.
* The free rod without gravity (supp-fig5): encapsulated when the encapsulation measure
  M = (theta(L) - theta(0)) / pi exceeds 1 (the two ends have turned past antiparallel: the
  rod closes round the drop). For supp-fig5 every stable equilibrium of the flat family has
  M < 0.59 and every one of the encapsulated family M > 1.05 (statics), so M = 1 separates
  the two basins' end states at every Delta.

What the model leaves out is flagged: the first time the rod crosses itself and the first
time the drop's interface crosses the rod (checked at every output frame) are reported, and
a run whose outcome was decided after such a crossing is marked.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from dynamics import Damping, Event, Ground, Rod, simulate
from dynamics.effects import Gravity
from dynamics.stepper import RestCriterion, stable_dt
from elastocap._version import __version__
from elastocap.capillary import Capillary
from elastocap.drop import capillary_energy_and_gradient
from elastocap.scene import Scene, SceneError
from elastocap.statics.shape import arc_points, count_crossings

__all__ = ["ImpactResult", "impact_settings", "run_impact", "turning_measure"]

#: Edges per accuracy preset, as a minimum; also at least 16 edges across the wet part so
#: that the contact lines and the pressure are resolved (measured: README, "What accuracy
#: costs").
ACCURACY_EDGES = {"draft": 50, "default": 100, "publication": 200}
_EDGES_PER_DELTA = {"draft": 8, "default": 16, "publication": 32}
#: Fraction of the explicit stability bound used when numerics.dt = 0.
DT_FRACTION = 0.5
#: Time between output frames when none are requested: crossings are detected on frames,
#: so this is the resolution of their reported times (0.05 = 1/170 of the period of the
#: slowest free-free mode of supp-fig5's rod).
FRAME_SPACING = 0.05
#: Upper bound on the number of frames (memory: frames x nodes x 16 bytes).
MAX_FRAMES = 20001


def turning_measure(x: np.ndarray) -> float:
    """M = (theta(L) - theta(0)) / pi of a polyline (n, 2): the summed turning angles."""
    e = np.diff(x, axis=0)
    cross = e[:-1, 0] * e[1:, 1] - e[:-1, 1] * e[1:, 0]
    dot = np.sum(e[:-1] * e[1:], axis=1)
    return float(np.sum(np.arctan2(cross, dot)) / math.pi)


def _interface(x, s_nodes, area, s1, s2, gamma):
    """Drop interface points (k, 2) of a rod configuration."""
    g = np.zeros_like(x)
    _e, tau, _k = capillary_energy_and_gradient(x, s_nodes, s1, s2, area, gamma, g)
    p1 = np.array([np.interp(s1, s_nodes, x[:, 0]), np.interp(s1, s_nodes, x[:, 1])])
    p2 = np.array([np.interp(s2, s_nodes, x[:, 0]), np.interp(s2, s_nodes, x[:, 1])])
    return arc_points(p1, p2, tau, 80), tau


@dataclass
class ImpactResult:
    """Outcome, measures and diagnostics of one impact run (plain data, JSON-ready)."""

    outcome: str
    criterion: str
    final_measure: float
    t_end: float
    steps: int
    wall_time_s: float
    status: str
    message: str
    end_position: float
    impact_position: float
    rod_crossing_time: float | None
    interface_crossing_time: float | None
    decided_after_crossing: bool
    settings: dict
    simulation: object = field(repr=False, default=None)
    measure_history: np.ndarray = field(repr=False, default=None)

    def to_dict(self) -> dict:
        d = {k: v for k, v in self.__dict__.items() if k not in ("simulation", "measure_history")}
        return d


def impact_settings(scene: Scene) -> dict:
    """Resolution, time step and stopping rule of an impact run (scene numerics/presets)."""
    num = scene.numerics
    L = scene.rod.length
    n = num.n_edges or max(
        ACCURACY_EDGES[num.accuracy],
        math.ceil(_EDGES_PER_DELTA[num.accuracy] * L / scene.drop.wetted_length),
    )
    h = L / n
    dt_max = stable_dt(np.full(n, h), scene.rod.mass_per_length, scene.rod.bending_modulus)
    dt = num.dt or DT_FRACTION * dt_max
    if dt > dt_max:
        raise SceneError(
            "numerics.dt",
            num.dt,
            f"above the stability bound of bending dt_max = {dt_max:.4g} for {n} edges "
            f"(h = {h:.4g}); use dt <= {dt_max:.4g} or 0 for automatic",
        )
    scale = scene.drop.line_tension * scene.drop.wetted_length
    return {
        "n_edges": n,
        "dt": dt,
        "dt_max": dt_max,
        "t_max": num.t_max,
        "rest_kinetic": num.rest_kinetic * scale,
        "rest_time": num.rest_time,
    }


def _wet_interval(scene: Scene) -> tuple[float, float]:
    """[S1, S2] clipped to [0, L]: the scene accepts a wet interval that ends at a rod end
    up to round-off (1e-12 L), the capillary kernel needs 0 <= S1 < S2 <= L exactly."""
    d, L = scene.drop, scene.rod.length
    return max(d.s1, 0.0), min(d.s2, L)


def _effects(scene: Scene):
    d = scene.drop
    s1, s2 = _wet_interval(scene)
    eff = [Capillary(d.area, s1, s2, d.line_tension)]
    if scene.effects.gravity > 0:
        eff.append(Gravity(scene.effects.gravity))
    if scene.effects.ground:
        eff.append(Ground())
    if scene.effects.damping > 0:
        eff.append(Damping(scene.effects.damping))
    events = []
    for e in d.events:
        if e.s1 is not None:
            events.append(Event(e.time, "capillary", "s1", e.s1))
        if e.s2 is not None:
            events.append(Event(e.time, "capillary", "s2", e.s2))
    return eff, events


def run_impact(scene: Scene, frames: int | None = None) -> ImpactResult:
    """Release the rod with the drop spread to Delta and run it to rest.

    Parameters
    ----------
    scene : Scene
    frames : int, optional
        Output frames over [0, t_max] (default: one every FRAME_SPACING time units, at most
        MAX_FRAMES); crossings are checked on them.

    Returns
    -------
    ImpactResult
        ``simulation`` holds the :class:`dynamics.SimulationResult` (trajectory).
    """
    t0 = time.perf_counter()
    st = impact_settings(scene)
    n, L = st["n_edges"], scene.rod.length
    x0 = np.zeros((n + 1, 2))
    x0[:, 0] = np.linspace(0.0, L, n + 1)
    rod = Rod(
        x0,
        np.zeros_like(x0),
        np.full(n, L / n),
        scene.rod.mass_per_length,
        scene.rod.bending_modulus,
    )
    effects, events = _effects(scene)
    for ev in events:
        if ev.time > st["t_max"]:
            raise SceneError("drop.events", ev.time, f"event after numerics.t_max = {st['t_max']}")
    sim = simulate(
        rod,
        effects,
        dt=st["dt"],
        t_end=st["t_max"],
        frames=frames or min(MAX_FRAMES, int(st["t_max"] / FRAME_SPACING) + 1),
        events=events,
        rest=RestCriterion(st["rest_kinetic"], st["rest_time"]),
    )
    s_nodes = np.concatenate([[0.0], np.cumsum(rod.edge_len)])
    measures = np.array([turning_measure(p) for p in sim.positions])
    # crossings, frame by frame, with the contact lines in force at that time
    rod_t = if_t = None
    cap = effects[0].params.copy()
    cap[1:3] = _wet_interval(scene)
    fired = list(sim.events_fired)
    for k, (tk, pos) in enumerate(zip(sim.times, sim.positions, strict=True)):
        if rod_t is not None and if_t is not None:
            break
        while fired and fired[0][0] <= tk + 1e-12:
            _, _, j, val = fired.pop(0)
            cap[j] = val
        if rod_t is None and count_crossings(pos, pos, True, 0, n) > 0:
            rod_t = float(tk)
        if if_t is None and k > 0:
            iface, _tau = _interface(pos, s_nodes, cap[0], cap[1], cap[2], cap[3])
            m = iface.shape[0]
            if count_crossings(iface, pos, False, 1, m - 2) > 0:
                if_t = float(tk)
    final = sim.positions[-1]
    M = float(measures[-1])
    impact_s = scene.drop.center
    x_end = float(final[-1, 0])
    x_imp = float(np.interp(impact_s, s_nodes, final[:, 0]))
    if scene.effects.gravity > 0 or scene.effects.ground:
        criterion = "paper (Methods): x(L) < x(L - x_impact) in the lab frame"
        enc = x_end < x_imp
    else:
        criterion = "free rod: measure (theta(L) - theta(0))/pi > 1"
        enc = M > 1.0
    t_end = float(sim.t_final)
    crossed = [t for t in (rod_t, if_t) if t is not None]
    outcome = "encapsulated" if enc else "open"
    message = sim.message
    if not sim.success:
        # a failed run has no outcome: say what failed, and whether the contact lines met
        outcome = "failed"
        d = float(
            np.hypot(
                *(
                    np.array(
                        [
                            np.interp(cap[2], s_nodes, final[:, 0]),
                            np.interp(cap[2], s_nodes, final[:, 1]),
                        ]
                    )
                    - np.array(
                        [
                            np.interp(cap[1], s_nodes, final[:, 0]),
                            np.interp(cap[1], s_nodes, final[:, 1]),
                        ]
                    )
                )
            )
        )
        if d < 0.05 * (cap[2] - cap[1]):
            message += (
                f" At the last frame the contact lines are {d:.3g} apart (Delta = "
                f"{cap[2] - cap[1]:.3g}): the drop is closing inside the wrap, where "
                "the circular-cap model is singular (chord -> 0); the outcome up to "
                "then was encapsulation-bound. Try a smaller numerics.dt or a larger "
                "numerics.n_edges, or read it as a closed wrap."
            )
    return ImpactResult(
        outcome=outcome,
        criterion=criterion,
        final_measure=M,
        t_end=t_end,
        steps=int(sim.steps),
        wall_time_s=time.perf_counter() - t0,
        status=sim.status,
        message=message,
        end_position=x_end,
        impact_position=x_imp,
        rod_crossing_time=rod_t,
        interface_crossing_time=if_t,
        decided_after_crossing=bool(crossed) and min(crossed) <= t_end,
        settings={
            **st,
            "scene": scene.name,
            "scene_digest": scene.digest(),
            "version": __version__,
        },
        simulation=sim,
        measure_history=measures,
    )
