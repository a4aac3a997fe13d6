"""The impact run: a scene's effects on the dynamic elastica, run to rest, and its outcome.

The rod starts straight along +x (S = 0 at x = 0) and at rest, on the ground z = 0 when the
scene has one; the drop is already spread to its wetted length Delta (the fast spreading is
over, paper main text) and the rod is released. The run ends when the kinetic energy stays
below ``numerics.rest_kinetic`` (times the scale gamma Delta, the capillary energy
available; under damping strong enough for the rod to creep, lowered by
:func:`rest_damping_ratio` squared) for ``numerics.rest_time``, or at ``numerics.t_max``.
Gravity without a ground is refused (the rod would fall for ever).

Three parts: :func:`build_effects` (the scene's effects, the capillary one by name),
running (:func:`dynamics.simulate` with the scene's method, retried with a smaller
automatic dt after a failure or an energy rise), and classifying (crossings, measures and
the outcome of :func:`elastocap.criteria.impact_verdict`).

Outcome
-------
* The criterion is read on every frame (:func:`elastocap.criteria.frame_verdicts`):
  scenes with gravity or a ground (the strip of Fig 3) use the paper's (Methods),
  encapsulated when the free end S = L ends to the left of the impact centre S = L - x,
  x(L) < x(L - x_impact) in the lab frame; the free rod without gravity (supp-fig5) uses
  the encapsulation measure M = (theta(L) - theta(0)) / pi > 1 (the ends have turned past
  antiparallel; for supp-fig5 every stable equilibrium of the flat family has M < 0.59 and
  every one of the encapsulated family M > 1.05, so M = 1 separates the two basins' end
  states at every Delta).  ``decision_time`` is the frame from which the verdict no longer
  changes.
* ``open`` / ``encapsulated`` only when the run came to rest before t_max, its energy audit
  passed, and the verdict settled before the rod first crossed itself (the model has no
  rod-rod contact).  Otherwise ``undecided``, with ``undecided_reason``.
* A run that fails numerically (the step does not converge, a non-finite state, an energy
  rise beyond the capillary energy scale) has outcome ``"failed"`` and a message saying
  where and what to try, never a guessed outcome.

What the model leaves out is flagged: the first time the rod crosses itself and the first
time the drop's interface crosses the rod (checked at every output frame) are reported,
and ``decided_after_crossing`` marks a verdict that settled after either.  The first touch
of the interface with the rod is located inside a time step (``interface_touches``: time,
its error bound, arclength, side, kind); ``drop.interface_contact`` says what follows:
"ignore" (the paper's model, the default: the same run, flagged) or "wet" (the contact line
on the touched side jumps to the touched point at the first step where the crossing shows,
the area kept, and the run restarts from that step's state; each jump reports the capillary
energy before and after; docs/guide/interface-contact.md).  Scenes the run
cannot represent (fewer than MIN_WET_EDGES edges across the wet interval, a time step
that is not finite, too long for the rest criterion or too short to reach t_max) are
refused before it starts.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field

import numpy as np

from dynamics import (
    Damping,
    Event,
    Gravity,
    Ground,
    RestCriterion,
    Rod,
    SelfContact,
    SimulationResult,
    euler_bernoulli_omega,
    frame_steps,
    simulate,
    stable_dt,
)
from elastocap._version import __version__
from elastocap.capillary import Capillary
from elastocap.criteria import ImpactVerdict, frame_verdicts, impact_verdict
from elastocap.crossings import (
    INTERFACE_POINTS,
    first_crossing_frames,
    interface_crossings,
    locate_interface_touch,
)
from elastocap.drop import capillary_energy_and_gradient
from elastocap.geometry import turning_measures
from elastocap.scene import Numerics, Scene, SceneError

__all__ = [
    "ImpactEffects",
    "ImpactResult",
    "build_effects",
    "edge_count",
    "edge_key",
    "impact_settings",
    "run_impact",
]

#: Edges per accuracy preset, as a minimum; also at least 16 edges across the wet part so
#: that the contact lines and the pressure are resolved (measured: README, "What accuracy
#: costs").
ACCURACY_EDGES = {"draft": 50, "default": 100, "publication": 200}
_EDGES_PER_DELTA = {"draft": 8, "default": 16, "publication": 32}
#: Fraction of the explicit stability bound used when numerics.dt = 0: 0.9 for a rod that
#: never touches a ground (measured on supp-fig5 at 100 edges: the final measure moves by
#: <= 3e-6 between 0.25 and 0.9, and the threshold Delta* stays in the same 6e-5 bracket at
#: 0.5 and 0.9; bending alone is stable up to 0.50/0.45 = 1.1 of the bound).  Above 0.79 of
#: the bound, large-amplitude grid-scale motion is unstable (the 4:1 resonance of Verlet,
#: below); supp-fig5's smooth, damped motion does not excite it, and a run that does is
#: caught by the energy audit (ENERGY_RISE_TOL) and repeated with dt halved.
DT_FRACTION = 0.9
#: With a ground, 0.7: impacts on the ground excite the grid-scale modes, and with large
#: amplitudes Verlet resonates where the highest mode turns by a quarter period a step,
#: omega_max dt = sqrt(2), i.e. 0.786 of the bound (measured sharp, between 0.75 and 0.80,
#: with and without a ground: tests/dynamics/test_dt_resonance.py; fig3-strip fails at 0.8
#: and 0.9).  0.7 keeps 10% for the stiffening of bending by curvature.  Outcomes are as
#: dt-sensitive at 0.5 as at 0.7: on the Fig 3d grid 6 of 130 outcomes differ between 0.25
#: and 0.5 of the bound, 7 of 121 between 0.25 and 0.7, median |dM| 2-4e-4 (README).
DT_FRACTION_GROUND = 0.7
#: Implicit stepper (numerics.integrator = "implicit", free rods): automatic dt is this
#: fraction of the period 2 pi / omega_1 of the rod's first free-free bending mode,
#: omega_1 = 22.373 sqrt(B / mu) / L^2, whatever the resolution: 1/400 is dt = 0.0149 on
#: supp-fig5, 16x the explicit bound at 100 edges, where outcomes, Delta* (to 5e-5) and
#: final measures (to 2e-4) match RATTLE's (measured: benchmarks/dynamics_implicit.py).
IMPLICIT_PERIOD_FRACTION = 1.0 / 400.0
#: ... but with a ground at most this multiple of the explicit bound (0.0189 on fig3-strip
#: at 198 edges). With the drop's stiffness in the Newton matrix and contact changes as
#: low-rank updates (dynamics.midpoint), what limits the step there is the fast bending
#: waves the midpoint rule neither resolves nor damps, plus the contact changes. Measured
#: (benchmarks/dynamics_implicit.py, sections 6-7): at 8x no rejected steps, energy rise
#: <= 8.4e-5 gamma Delta, outcomes as RATTLE's on the Fig 3d line x = 2 ... 3 with
#: |dM| <= 1.8e-3; 16x works damped (0.88 s) but undamped rejects 4104 steps.
IMPLICIT_GROUND_BOUND_MULTIPLE = 8.0
#: An impact has no energy source (the capillary force and gravity are conservative; the
#: damping and the perfectly inelastic ground dissipate), so a rise of the total energy
#: above its running minimum (restarted at each event, which does work) beyond the
#: integrator's O(dt^2) error is a numerical instability, even when the run goes on.
#: Measured rises, in units of gamma Delta: <= 3.3e-4 in healthy runs (fig3-strip at 0.7 of
#: the bound: 1.2e-4); 0.7 to 300 in unstable ones (strong capillarity closing the wrap:
#: supp-fig5 with gamma = 40 fails down to 0.6 of the bound; the 4:1 resonance above); and
#: 0.01-0.2, shrinking with dt, where the contact lines nearly meet inside a closed wrap
#: (supp-fig5 at Delta = 4.5 ~ L), where the cap model is singular. Above ENERGY_RISE_TOL
#: the run is repeated with a smaller automatic dt and, if it persists, flagged; above
#: ENERGY_RISE_FAIL (the capillary energy scale itself) it has no outcome.
ENERGY_RISE_TOL = 1e-2
ENERGY_RISE_FAIL = 1.0
#: With an automatic dt (numerics.dt = 0), a run that fails numerically or whose energy
#: rises is repeated with dt halved, at most this many times (the JSON says so).
DT_RETRIES = 2
#: Time between output frames when none are requested: crossings are detected on frames,
#: so this is the resolution of their reported times (0.05 = 1/170 of the period of the
#: slowest free-free mode of supp-fig5's rod).
FRAME_SPACING = 0.05
#: Upper bound on the number of frames (memory: frames x nodes x 16 bytes).
MAX_FRAMES = 20001
#: A run whose rest test fired at a turn of a slow swing of the criterion's margin
#: (:func:`elastocap.criteria.swing_range`) is run again, at most SWING_REPEATS times, each
#: time with the rest test's kinetic threshold SWING_REST_KINETIC_FACTOR lower and held for
#: at least SWING_REST_HALF_PERIODS of that swing's half-periods: the swing must decay (its
#: amplitude by about the square root of the factor) before the run is read again.  A
#: longer hold alone does not do it where the swing's kinetic energy is already below the
#: threshold (Fig 3d, x = 1, We^1/2 = 1.031, 200 edges: a swing of amplitude 3e-3 and
#: half-period 1.05 read at rest twice; with rest_kinetic 1e-9 it rests at t = 140, open).
SWING_REPEATS = 2
SWING_REST_KINETIC_FACTOR = 1e-3
SWING_REST_HALF_PERIODS = 2.0


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
    energy_rise: float
    at_rest: bool
    decision_time: float | None
    undecided_reason: str | None
    compile_time_s: float
    run_time_s: float
    settings: dict
    interface_contact: str = "ignore"
    interface_touches: list = field(default_factory=list)
    self_contact: dict = field(default_factory=dict)
    simulation: object = field(repr=False, default=None)
    measure_history: np.ndarray = field(repr=False, default=None)

    def to_dict(self) -> dict:
        d = {k: v for k, v in self.__dict__.items() if k not in ("simulation", "measure_history")}
        return d

    def __eq__(self, other) -> bool:
        # what it saves (its JSON, NaN equal to NaN), its measures and its run, by value:
        # the generated == would ask an array for its truth value and raise
        if type(other) is not type(self):
            return NotImplemented
        mine, theirs = self.measure_history, other.measure_history
        same_measures = (mine is None and theirs is None) or (
            mine is not None and theirs is not None
            and np.array_equal(mine, theirs, equal_nan=True))
        return (same_measures and self.simulation == other.simulation
                and _saved(self.to_dict()) == _saved(other.to_dict()))

    __hash__ = None


def _saved(d: dict) -> str:
    """``d`` as JSON text, keys sorted, NaN and infinities as JSON's words for them (so a
    NaN equals a NaN and +inf differs from -inf), numpy values as Python ones."""
    return json.dumps(d, sort_keys=True,
                      default=lambda o: o.tolist() if hasattr(o, "tolist") else repr(o))


def energy_rise(times, total, event_times) -> tuple[float, float]:
    """Largest rise of the total energy above its running minimum, and when it peaks.

    The minimum restarts at each event time (an event does work on the rod). Energies are
    those of the output frames; returns (rise, time), (0, 0) for a non-increasing energy.
    """
    times = np.asarray(times, float)
    total = np.asarray(total, float)
    rise = np.zeros_like(total)
    if rise.size == 0:
        return 0.0, 0.0
    # segments strictly between events; a frame at an event's time may hold the energy
    # before or after it, so it belongs to neither
    eps = 1e-9 * max(1.0, float(times[-1]))
    edges = [-math.inf, *sorted(event_times), math.inf]
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        idx = np.nonzero((times > a + eps) & (times < b - eps))[0]
        if idx.size:
            seg = total[idx]
            rise[idx] = seg - np.minimum.accumulate(seg)
    if not np.all(np.isfinite(rise)):
        return math.inf, float(times[np.argmin(np.isfinite(rise))])
    k = int(np.argmax(rise))
    return float(rise[k]), float(times[k])


def _rise_message(rise, scale, t_rise):
    return (
        f"the total energy rose by {rise:.3g} ({rise / scale:.3g} gamma Delta, tolerance "
        f"{ENERGY_RISE_TOL:g}) by t = {t_rise:.4g}, with no energy source in the model: "
        "a time-integration error (a numerical instability, or the stiffness of the drop "
        "closing inside the wrap, beyond the bending time-step bound)."
    )


def edge_count(scene: Scene) -> int:
    """Edges of an impact run: ``numerics.n_edges``, or the accuracy preset's count raised
    to resolve the wet interval (a fixed number of edges per Delta)."""
    num = scene.numerics
    return num.n_edges or max(
        ACCURACY_EDGES[num.accuracy],
        math.ceil(_EDGES_PER_DELTA[num.accuracy] * scene.rod.length / scene.drop.wetted_length),
    )


def edge_key(scene: Scene) -> tuple[str, object] | None:
    """The scene key (and its value) that sets the edge count of an impact run:
    ``numerics.n_edges`` when set, ``drop.wetted_length`` when a small Delta raises the
    count above the accuracy preset's, None when the preset's count applies."""
    num = scene.numerics
    if num.n_edges:
        return "numerics.n_edges", num.n_edges
    if edge_count(scene) > ACCURACY_EDGES[num.accuracy]:
        return "drop.wetted_length", scene.drop.wetted_length
    return None


#: The dynamics method of each value of ``numerics.integrator``.
METHOD = {"rattle": "rattle", "implicit": "midpoint"}
#: Fewest edges across the wet interval: the wetted part must bend into an arc round the
#: drop and carry its two contact lines on different edges; 4 edges (3 interior hinges)
#: is half of what the coarsest preset uses (draft: 8, whose error README "What accuracy
#: costs" measures).  Fewer is refused, not run.
MIN_WET_EDGES = 4


def impact_settings(scene: Scene) -> dict:
    """Resolution, time step and stopping rule of an impact run (scene numerics/presets).

    Raises
    ------
    SceneError
        For a resolution that cannot represent the scene (fewer than MIN_WET_EDGES edges
        across the wet interval) or a time step that cannot run it (not finite, fewer
        than MIN_REST_STEPS steps in numerics.rest_time, or more than MAX_IMPACT_STEPS
        steps to numerics.t_max).
    """
    num = scene.numerics
    L = scene.rod.length
    delta = scene.drop.wetted_length
    for ev in scene.drop.events:
        if ev.time > num.t_max:
            raise SceneError("drop.events", ev.time, f"event after numerics.t_max = {num.t_max}")
    if scene.effects.gravity > 0.0 and not scene.effects.ground:
        raise SceneError(
            "effects.gravity", scene.effects.gravity,
            "without effects.ground the rod and the drop fall freely and never come to rest; "
            "a uniform field on the uniform rod (and its damping) changes nothing in the "
            "rod's own frame: set effects.ground = true for the strip on the ground, or "
            "effects.gravity = 0 for the free rod")
    n = edge_count(scene)
    n_min = MIN_WET_EDGES * L / delta * (1.0 - 1e-12)
    n_min = math.ceil(n_min) if n_min < 1e15 else n_min
    if n < n_min:
        runs = _fewest_runnable_edges(scene, n_min) if n_min < 1e15 else n_min
        also = (f"; the fewest that run with the automatic dt: n_edges = {runs}"
                if runs != n_min else "")
        raise SceneError(
            "numerics.n_edges", n,
            f"the wet interval Delta = {delta:.4g} spans {n * delta / L:.3g} edges; at least "
            f"{MIN_WET_EDGES} are needed (n_edges >= {n_min:.15g} for L = {L:.4g}){also}; or 0 "
            "for the accuracy preset")
    h = L / n
    # the bound depends on the shortest edge only: one edge of length h stands for the n
    # equal ones (an array of n would allocate 8n bytes before a huge n can be refused)
    dt_max = stable_dt(np.array([h]), scene.rod.mass_per_length, scene.rod.bending_modulus)
    if num.integrator == "implicit":
        # no stability bound: dt is chosen for accuracy on the slow modes
        omega1 = euler_bernoulli_omega(
            "free-free", L, scene.rod.bending_modulus, scene.rod.mass_per_length
        )
        dt = num.dt or IMPLICIT_PERIOD_FRACTION * 2.0 * math.pi / omega1
        if scene.effects.ground and not num.dt:
            dt = min(dt, IMPLICIT_GROUND_BOUND_MULTIPLE * dt_max)
    else:
        dt = num.dt or (DT_FRACTION_GROUND if scene.effects.ground else DT_FRACTION) * dt_max
    if num.integrator == "rattle" and dt > dt_max:
        raise SceneError(
            "numerics.dt",
            num.dt,
            f"above the stability bound of bending dt_max = {dt_max:.8g} for {n:.6g} edges "
            f"(h = {h:.4g}); use dt <= {round_down(dt_max):.4g} or 0 for automatic",
        )
    dt_damping = damping_dt_max(scene)
    if num.dt and num.dt > dt_damping:
        c, mu = scene.effects.damping, scene.rod.mass_per_length
        raise SceneError(
            "numerics.dt", num.dt,
            f"with effects.damping = {c:g} the damping's decay per step c dt / mu = "
            f"{c * num.dt / mu:.3g} exceeds {DAMPING_DECAY_MAX:g}: the split exact decay then "
            "misreads an overdamped creep (the velocity the rest test reads is "
            "(a/2)/sinh(a/2) of the creep's, a = c dt / mu); use dt <= "
            f"{round_down(dt_damping):.4g} or 0 for automatic")
    damping_limited = not num.dt and dt > dt_damping
    _check_dt(scene, dt, n, dt_damping if damping_limited else None)
    if damping_limited:
        dt = dt_damping
    scale = scene.drop.line_tension * delta
    ratio = rest_damping_ratio(scene)
    # ratio * ratio, not ratio ** 2: inf (a threshold of 0, refused), not an OverflowError
    rest_kinetic = num.rest_kinetic * scale / (ratio * ratio)
    if not rest_kinetic > 0.0:
        key, value = (("numerics.rest_time", num.rest_time) if num.rest_time > 1.0
                      else ("effects.damping", scene.effects.damping))
        raise SceneError(
            key, value,
            f"c rest_time / mu = {ratio:.3g} lowers the kinetic rest threshold "
            "numerics.rest_kinetic / (c rest_time / mu)**2 to 0 (it underflows): no run could "
            "be read at rest; a smaller effects.damping or numerics.rest_time is needed")
    return {
        "integrator": num.integrator,
        "method": METHOD[num.integrator],
        "n_edges": n,
        "dt": dt,
        "dt_max": dt_max,
        "t_max": num.t_max,
        "rest_kinetic": rest_kinetic,
        "rest_time": num.rest_time,
        "dt_limited_by_damping": damping_limited,
    }


#: Largest decay of the velocity per step by the damping, c dt / mu, that an impact run
#: takes.  The damping is integrated as an exact decay between the force kicks, so a rod
#: creeping under a steady force f (the overdamped approach to rest) moves at
#: (a/2) coth(a/2) times its terminal speed f / c, a = c dt / mu, while the velocity the
#: rest test reads is (a/2) / sinh(a/2) of it (closed forms of the scheme, asserted in
#: ``tests/dynamics/test_dyn_effects.py``).  At a = 0.3: +0.75 % and -0.37 %.  At a = 86
#: (supp-fig5 with damping 1e5 at its automatic dt) the velocity read is 2e-17 of the
#: creep's and the rest test fires while the rod creeps on.  The automatic dt is capped
#: to it; an explicit numerics.dt above it is refused.
DAMPING_DECAY_MAX = 0.3


def damping_dt_max(scene: Scene) -> float:
    """The largest dt with ``c dt / mu <= DAMPING_DECAY_MAX`` (inf without damping)."""
    c = scene.effects.damping
    return DAMPING_DECAY_MAX * scene.rod.mass_per_length / c if c > 0.0 else math.inf


def rest_damping_ratio(scene: Scene) -> float:
    """How much less of an unbalanced force the kinetic rest test sees under the scene's
    damping than without it: ``max(1, c T / mu)`` (c = ``effects.damping``, T =
    ``numerics.rest_time``, mu the mass per length).

    Without damping an unbalanced force f per length, starting from rest, gives the rod a
    speed f T / mu within the rest window; with damping c it moves at most at the terminal
    speed f / c. Once c T / mu > 1 the rod can creep at kinetic energies below the
    threshold, far from equilibrium (the overdamped approach to rest). The threshold is
    divided by the square of this ratio, so that the test resolves the same unbalanced
    force at any damping; at c T / mu <= 1 (every built-in scene) it is unchanged."""
    c = scene.effects.damping
    return max(1.0, c * scene.numerics.rest_time / scene.rod.mass_per_length)


def rest_advice(scene: Scene) -> str:
    """What to try when an impact run does not come to rest by ``numerics.t_max``."""
    ratio = rest_damping_ratio(scene)
    if ratio > 1.0:
        return (f"raise numerics.t_max: effects.damping = {scene.effects.damping:g} is strong "
                f"(c rest_time / mu = {ratio:.3g} > 1), the rod creeps to rest slowly, and "
                "less damping can reach it sooner")
    return "raise numerics.t_max, or add damping"


#: Fewest steps within numerics.rest_time: "at rest" must rest on several samples of the
#: kinetic energy, not one or two.
MIN_REST_STEPS = 4
#: Most steps of one impact run (with automatic retries at dt/2 and dt/4 on top): at the
#: measured 5-8 us a step, 2e9 steps are 3-4 hours; a dt that needs more has underflowed.
MAX_IMPACT_STEPS = 2 * 10**9


def _fewest_runnable_edges(scene: Scene, n_min: int) -> int:
    """The fewest edges from ``n_min`` on with which :func:`impact_settings` accepts the
    scene (with few edges the automatic dt, which scales as h^2, can exceed what the rest
    criterion needs); ``n_min`` when none up to 2^20 n_min does."""

    def runs(k):
        try:
            impact_settings(scene.with_overrides({"numerics.n_edges": int(k)}))
            return True
        except SceneError:
            return False

    if runs(n_min):
        return n_min
    lo, hi = n_min, 2 * n_min
    while not runs(hi):
        lo, hi = hi, 2 * hi
        if hi > 2**20 * n_min:
            return n_min
    while hi - lo > 1:  # the accepted counts from the first one on: the automatic dt falls
        mid = (lo + hi) // 2
        lo, hi = (lo, mid) if runs(mid) else (mid, hi)
    return hi


def round_down(x: float, digits: int = 4) -> float:
    """``x > 0`` rounded down to ``digits`` significant digits: a bound quoted in a message
    that the quoted value itself meets."""
    q = 10.0 ** (math.floor(math.log10(x)) - digits + 1)
    y = math.floor(x / q) * q
    return y if float(f"{y:.{digits}g}") <= x else y - q


def _check_dt(scene: Scene, dt: float, n: int, capped: float | None = None) -> None:
    """Refuse a time step that cannot run the impact, naming the key that set it: the
    explicit ``numerics.dt``; else the key that set the edge count (the automatic dt scales
    as h^2: ``numerics.n_edges``, or ``drop.wetted_length`` when a small Delta raised the
    count); else the rod (``rod.bending_modulus``) at the preset's edges.  ``capped``: the
    automatic dt after the damping's cap (:data:`DAMPING_DECAY_MAX`), which can only lower
    it: the step count is checked on it and then names ``effects.damping``."""
    num = scene.numerics
    if num.dt:
        key, value, origin = "numerics.dt", num.dt, ""
    else:
        key, value = edge_key(scene) or ("rod.bending_modulus", scene.rod.bending_modulus)
        origin = (f" (the automatic dt of {n:.6g} edges, from rod.bending_modulus and "
                  "rod.mass_per_length)")
    if not (math.isfinite(dt) and dt > 0.0):
        raise SceneError(key, value, f"gives a time step dt = {dt!r}{origin}; a finite "
                         "dt > 0 is needed: set numerics.dt")
    if dt > num.rest_time / MIN_REST_STEPS and (capped is None
                                                or capped > num.rest_time / MIN_REST_STEPS):
        raise SceneError(
            key, value,
            f"gives a time step dt = {dt:.4g}{origin}: fewer than {MIN_REST_STEPS} steps in "
            f"numerics.rest_time = {num.rest_time:g}, over which the rest criterion reads "
            f"the kinetic energy; dt <= {round_down(num.rest_time / MIN_REST_STEPS):.4g} is "
            "needed: set numerics.dt")
    damping_limited = capped is not None
    if damping_limited:
        dt = capped
        key, value = "effects.damping", scene.effects.damping
        origin = (f" (the automatic dt, capped by the damping at c dt / mu = "
                  f"{DAMPING_DECAY_MAX:g})")
    steps = num.t_max / dt
    if steps > MAX_IMPACT_STEPS:
        default_t_max = Numerics().t_max
        if not num.dt and num.t_max > default_t_max and default_t_max / dt <= MAX_IMPACT_STEPS:
            key, value = "numerics.t_max", num.t_max  # the long t_max, not the rod, is at fault
        raise SceneError(
            key, value,
            f"gives {steps:.3g} time steps of dt = {dt:.4g}{origin} to numerics.t_max = "
            f"{num.t_max:g}, more than the {MAX_IMPACT_STEPS:.0e} an impact can take; use a "
            + ("smaller t_max or less damping" if damping_limited and key == "effects.damping"
               else "smaller t_max or a larger dt"))


def _wet_interval(scene: Scene) -> tuple[float, float]:
    """[S1, S2] clipped to [0, L]: the scene accepts a wet interval that ends at a rod end
    up to round-off (1e-12 L), the capillary kernel needs 0 <= S1 < S2 <= L exactly."""
    d, L = scene.drop, scene.rod.length
    return max(d.s1, 0.0), min(d.s2, L)


@dataclass(frozen=True)
class ImpactEffects:
    """The effects of an impact run, the capillary one by name, and the drop's events."""

    effects: tuple
    capillary: Capillary
    events: tuple


def build_effects(scene: Scene) -> ImpactEffects:
    """Fresh effect objects for one run (events write into their parameters)."""
    d = scene.drop
    s1, s2 = _wet_interval(scene)
    cap = Capillary(d.area, s1, s2, d.line_tension)
    eff = [cap]
    if scene.effects.gravity > 0:
        eff.append(Gravity(scene.effects.gravity))
    if scene.effects.ground:
        eff.append(Ground())
    if scene.effects.damping > 0:
        eff.append(Damping(scene.effects.damping))
    if scene.rod.thickness > 0:
        # the rod cannot pass through itself (rod.thickness; 0 = the paper's model)
        eff.append(SelfContact(scene.rod.thickness))
    events = []
    for e in d.events:
        if e.s1 is not None:
            events.append(Event(e.time, cap.name, "s1", e.s1))
        if e.s2 is not None:
            events.append(Event(e.time, cap.name, "s2", e.s2))
    return ImpactEffects(tuple(eff), cap, tuple(events))


def _initial_rod(scene: Scene, n: int) -> Rod:
    """Straight along +x (S = 0 at x = 0), at rest, on the ground z = 0."""
    L = scene.rod.length
    x0 = np.zeros((n + 1, 2))
    x0[:, 0] = np.linspace(0.0, L, n + 1)
    return Rod(x0, np.zeros_like(x0), np.full(n, L / n), scene.rod.mass_per_length,
               scene.rod.bending_modulus)


@dataclass
class _Attempt:
    dt: float
    sim: object
    effects: ImpactEffects
    rise: float
    t_rise: float
    touches: list


#: Most contact-line jumps of one run under ``interface_contact = "wet"``; a further touch
#: is flagged and left (the interface then passes through the rod, as under "ignore").
MAX_WET_JUMPS = 1000
#: After a jump, "wet" runs on in pieces of this duration (a touch found in one costs a
#: re-run of that piece, not of the rest of the run) until WET_QUIET_TIME has passed
#: without a touch; then to t_max with the rest criterion.  Measured on supp-fig5 at
#: Delta = 4 (173 jumps at 200 edges): runs to t_max after every jump cost 750 s.
WET_CHUNK_TIME = 0.5
WET_QUIET_TIME = 2.0


def _frame_steps(frames, t_max: float, dt: float) -> np.ndarray:
    """The steps of the output frames (those :func:`dynamics.simulate` records): ``frames``,
    or one every ``FRAME_SPACING`` up to ``MAX_FRAMES``."""
    return frame_steps(int(frames or min(MAX_FRAMES, int(t_max / FRAME_SPACING) + 1)), t_max, dt)


class _Segments:
    """Runs of one impact from any step and state, with the capillary parameters in force
    (the scene's events at their steps), on the global time grid ``k dt``."""

    def __init__(self, scene: Scene, st: dict, dt: float, frame_steps, options):
        self.scene, self.st, self.dt, self.options = scene, st, dt, options
        self.frame_steps = frame_steps
        self.n_total = int(math.ceil(st["t_max"] / dt - 1e-9))
        self.eff = build_effects(scene)  # the scene's events, and the initial parameters
        self.ev_steps = [int(math.ceil(e.time / dt - 1e-9)) for e in self.eff.events]
        self.runs = []  # every simulate() call (cost accounting)

    def run(self, rod, m0, m1, params, fresh, frames=None, rest=True):
        """simulate() from step m0 (state ``rod``, capillary ``params``) to step m1.

        Frames at the global frame steps in [m0, m1] (or at the relative steps
        ``frames``); the scene's events at steps > m0 (>= m0 when ``fresh``) up to m1.
        Returns the result and the capillary parameters at m1 (events applied)."""
        dt = self.dt
        eff = build_effects(self.scene)
        eff.capillary.params[:] = params
        events = [
            Event((k - m0) * dt, e.effect, e.param, e.value)
            for e, k in zip(self.eff.events, self.ev_steps, strict=True)
            if (k >= m0 if fresh else k > m0) and k <= m1
        ]
        if frames is None:
            f = self.frame_steps
            frames = np.concatenate([[0], f[(f > m0) & (f <= m1)] - m0])
        sim = simulate(
            rod, eff.effects, method=self.st["method"], dt=dt, t_end=(m1 - m0) * dt,
            frames=np.asarray(frames, dtype=np.float64) * dt, events=events,
            rest=RestCriterion(self.st["rest_kinetic"], self.st["rest_time"]) if rest else None,
            t0=m0 * dt, **self.options,
        )
        self.runs.append(sim)
        return sim, eff.capillary.params.copy()

    def cap_frames(self, sim, params0) -> np.ndarray:
        """Capillary parameters at each frame of a run that started with ``params0``."""
        frames = np.repeat(np.asarray(params0, float)[None], len(sim.times), axis=0)
        for t_ev, _name, j, val in sim.events_fired:
            frames[sim.times >= t_ev - 1e-12, j] = val
        return frames

    def locate(self, rod, m0, params, fresh, k_frame, sim, s_nodes) -> _Located:
        """The first touch in the frame interval (k_frame - 1, k_frame] of ``sim`` (a run
        from step m0, state ``rod``, with ``params``): re-run to frame k_frame - 1, then
        step by step to frame k_frame, then bisection inside the first step with a
        crossing (:func:`elastocap.crossings.locate_interface_touch`)."""
        dt = self.dt
        ma = int(round(sim.times[k_frame - 1] / dt))
        mb = int(round(sim.times[k_frame] / dt))
        if ma == m0:
            head, state_a = sim, rod
            pa = self.cap_frames(sim, params)[k_frame - 1]
        else:
            head, pa = self.run(rod, m0, ma, params, fresh, rest=False)
            state_a = _rod_at(rod, head.positions[-1], head.velocities)
        win = self.window(state_a, ma, mb, pa, s_nodes)
        if win.j is None:
            # the step run does not reproduce the crossing (round-off at a grazing touch):
            # the touch is known to the frame interval only
            j = mb - ma
            xs = interface_crossings(sim.positions[k_frame], s_nodes,
                                     self.cap_frames(sim, params)[k_frame])
            win.touch = {"time": 0.5 * (ma + mb) * dt, "time_error": 0.5 * (mb - ma) * dt,
                         "step_bracket": [ma * dt, mb * dt], "s": float(0.5 * (xs[0] + xs[-1])),
                         "s_spread": float(xs[-1] - xs[0])}
        else:
            j = win.j
        x_j = win.run.positions[j] if win.j is not None else sim.positions[k_frame]
        return _Located(win.touch, head, state_a, ma, pa, j, win.caps[j], x_j)

    def window(self, state, ma, mb, params, s_nodes) -> _Window:
        """A run from step ma to mb with a frame at every step; the first step with a
        crossing (None without) and the touch located inside the step before it."""
        dt = self.dt
        steps, _ = self.run(state, ma, mb, params, False, frames=np.arange(mb - ma + 1),
                            rest=False)
        caps = self.cap_frames(steps, params)
        j = next((j for j in range(steps.positions.shape[0])
                  if interface_crossings(steps.positions[j], s_nodes, caps[j]).size), None)
        touch = None
        if j == 0:  # already crossing where the run starts (after a jump, on the wet part)
            xs = interface_crossings(steps.positions[0], s_nodes, caps[0])
            touch = {"time": ma * dt, "time_error": 0.0, "step_bracket": [ma * dt, ma * dt],
                     "s": float(0.5 * (xs[0] + xs[-1])), "s_spread": float(xs[-1] - xs[0])}
        elif j is not None:
            lt = locate_interface_touch(steps.positions[j - 1], steps.positions[j],
                                        steps.times[j - 1], steps.times[j], s_nodes, caps[j])
            lo, hi = float(steps.times[j - 1]), float(steps.times[j])
            # the crossing shows between these two steps of the run: the bound on the error;
            # the time inside the step is that of the linear interpolation of the nodes
            touch = {"time": lt.time, "time_error": max(lt.time - lo, hi - lt.time),
                     "step_bracket": [lo, hi], "s": lt.s, "s_spread": lt.s_spread}
        return _Window(steps, caps, j, touch)


@dataclass
class _Window:
    run: object
    caps: np.ndarray
    j: int | None
    touch: dict | None


@dataclass
class _Located:
    touch: dict
    head: object  # the run from the segment's start to step ma
    state_a: Rod  # the state at step ma
    ma: int
    params_a: np.ndarray
    j: int  # steps after ma to the first step with a crossing
    cap_j: np.ndarray
    x_j: np.ndarray  # the configuration there


def _rod_at(rod: Rod, x, v) -> Rod:
    return Rod(np.array(x), np.array(v), rod.edge_len.copy(), rod.mu, rod.B)


def _side(s: float, s1: float, s2: float) -> str:
    return "s1" if s < s1 else ("s2" if s > s2 else "wet")


def _classify_touch(touch: dict, x, s_nodes, cap) -> None:
    """Side of the touched point and its kind: "contact angle" when it lies within two
    segments of the drawn interface (lambda / (INTERFACE_POINTS - 1)) of the contact line
    on its side (the interface folds onto the dry rod there: the contact angle has reached
    pi), else "separate" (another part of the rod meets the interface)."""
    touch["side"] = side = _side(touch["s"], cap[1], cap[2])
    lam = _cap_energy(x, s_nodes, cap) / cap[3]
    near = 2.0 * lam / (INTERFACE_POINTS - 1)
    line = cap[1] if side == "s1" else cap[2]
    touch["kind"] = ("contact angle" if side != "wet" and abs(touch["s"] - line) <= near
                     else "separate")


def _cap_energy(x, s_nodes, params) -> float:
    g = np.zeros_like(x)
    e, _tau, _k = capillary_energy_and_gradient(np.ascontiguousarray(x), s_nodes, params[1],
                                                params[2], params[0], params[3], g)
    return float(e)


def _simulate_drop(scene: Scene, st: dict, rod: Rod, dt: float, frames, options):
    """One run of the impact under the scene's ``drop.interface_contact``.

    "ignore": one :func:`dynamics.simulate` call (the touch is located afterwards, by
    :func:`_locate_first_touch`).  "wet": runs from the start to t_max; at the first frame
    where the interface crosses the rod, the touch is located (re-run to the frame before,
    then step by step, then bisection inside the step); if the touched point lies outside
    [S1, S2] the contact line on that side jumps to it at the first step where the
    crossing shows (as a scheduled event fires at the first step at or after its time),
    and the run restarts from that step's state; repeated until no touch is left.
    Returns (SimulationResult, touches, ImpactEffects)."""
    fsteps = _frame_steps(frames, st["t_max"], dt)
    seg = _Segments(scene, st, dt, fsteps, options)
    if scene.drop.interface_contact == "ignore":
        eff = seg.eff
        sim = simulate(
            rod, eff.effects, method=st["method"], dt=dt, t_end=st["t_max"],
            frames=frames or min(MAX_FRAMES, int(st["t_max"] / FRAME_SPACING) + 1),
            events=eff.events, rest=RestCriterion(st["rest_kinetic"], st["rest_time"]),
            **options,
        )
        return sim, [], eff
    s_nodes = np.concatenate([[0.0], np.cumsum(rod.edge_len)])
    name = seg.eff.capillary.name
    params = seg.eff.capillary.params.copy()
    state, m0, fresh, after_jump = rod, 0, True, False
    quiet = math.inf  # time since the last jump
    fset = set(fsteps.tolist())
    keep = []  # (piece, first frame kept?) of the stitched trajectory
    fired, touches = [], []
    while True:
        if after_jump:
            # right after a jump the next touch often follows within steps (the contact line
            # advancing while the contact angle exceeds pi): step by step to the next frame
            later = fsteps[fsteps > m0]
            mb = int(later[0]) if later.size else seg.n_total
            win = seg.window(state, m0, mb, params, s_nodes)
            if win.j is None:
                if mb in fset:
                    keep.append((_last_frame(win.run), True))
                fired += win.run.events_fired
                state = _rod_at(rod, win.run.positions[-1], win.run.velocities)
                quiet += (mb - m0) * dt
                m0, params, after_jump, last = mb, win.caps[-1], False, win.run
                if m0 >= seg.n_total:
                    break
                continue
            loc = _Located(win.touch, None, state, m0, params, win.j, win.caps[win.j],
                           win.run.positions[win.j])
            whole, head = None, []
        else:
            m_end, rest = seg.n_total, True
            if quiet < WET_QUIET_TIME:
                # soon after a jump: short runs (a touch costs a re-run of one of them)
                later = fsteps[fsteps >= m0 + math.ceil(WET_CHUNK_TIME / dt)]
                m_end, rest = (int(later[0]) if later.size else seg.n_total), False
            sim, p_end = seg.run(state, m0, m_end, params, fresh, rest=rest)
            _k_rod, k_if = first_crossing_frames(sim.positions, s_nodes,
                                                 seg.cap_frames(sim, params))
            if k_if < 0:
                keep.append((sim, fresh))
                fired += sim.events_fired
                last = sim
                if m_end >= seg.n_total or sim.status != "completed":
                    break
                quiet += (m_end - m0) * dt
                state = _rod_at(rod, sim.positions[-1], sim.velocities)
                m0, params, fresh = m_end, p_end, False
                continue
            loc = seg.locate(state, m0, params, fresh, k_if, sim, s_nodes)
            whole = (sim, fresh) if m_end >= seg.n_total else None
            # the kept frames and events up to the frame before the crossing frame
            head = [(_first_frames(loc.head, loc.ma), fresh),
                    [e for e in loc.head.events_fired if e[0] <= (loc.ma + 0.5) * dt]]
        touch, ma, j = loc.touch, loc.ma, loc.j
        _classify_touch(touch, loc.x_j, s_nodes, loc.cap_j)
        if touch["side"] == "wet" or len(touches) >= MAX_WET_JUMPS or j == 0:
            touch["action"] = ("flagged: the touched point is on the wet part" if
                               touch["side"] == "wet" else
                               "flagged: the interface crosses the rod at the restart"
                               if j == 0 else f"flagged: more than {MAX_WET_JUMPS} jumps")
            touches.append(touch)
            if whole is not None:
                # the run to t_max that found it stands (as under "ignore")
                keep.append(whole)
                fired += whole[0].events_fired
                last = whole[0]
                break
            if head:
                keep.append(head[0])
                fired += head[1]
            # the rest of the run as under "ignore", from the state at ma
            rest_run, _p = seg.run(loc.state_a, ma, seg.n_total, loc.params_a, False)
            keep.append((rest_run, False))
            fired += rest_run.events_fired
            last = rest_run
            break
        if head:
            keep.append(head[0])
            fired += head[1]
        # the state at the first step with a crossing, with its velocities
        m_jump = ma + j
        run_c, pc = seg.run(loc.state_a, ma, m_jump, loc.params_a, False, frames=[0, j],
                            rest=False)
        x_c = run_c.positions[-1]
        params_c = pc
        pc, done = _wet(x_c, s_nodes, pc, touch, m_jump * dt, MAX_WET_JUMPS - len(touches))
        touches += done
        fired += run_c.events_fired
        if m_jump in fset:
            keep.append((_last_frame(run_c), True))
        fired += [(m_jump * dt, name, k, float(pc[k])) for k in (1, 2)
                  if pc[k] != params_c[k]]
        state, m0, fresh, params = _rod_at(rod, x_c, run_c.velocities), m_jump, False, pc
        after_jump, last, quiet = True, run_c, 0.0
        if m0 >= seg.n_total:
            break
    return _stitch(keep, fired, seg.runs, dt, last), touches, seg.eff


def _wet(x, s_nodes, params, touch, t_jump, budget):
    """The contact-line jumps at state ``x`` (time ``t_jump``) under "wet": first to the
    located touch, then, while the new interface crosses the dry rod there, to the mean of
    the crossings on that side (at most ``budget`` jumps).  Returns the new capillary
    parameters and the touches (each with the capillary energy before and after)."""
    out = []
    p = np.array(params, dtype=np.float64)
    while len(out) < budget:
        k = 1 if touch["side"] == "s1" else 2
        new = p.copy()
        new[k] = touch["s"]
        e0, e1 = _cap_energy(x, s_nodes, p), _cap_energy(x, s_nodes, new)
        touch.update(action="wetted", jump_time=t_jump, s1=float(new[1]), s2=float(new[2]),
                     capillary_energy_before=e0, capillary_energy_after=e1, energy_jump=e1 - e0)
        out.append(touch)
        p = new
        xs = interface_crossings(x, s_nodes, p)
        lo, hi = xs[xs < p[1]], xs[xs > p[2]]
        if not (lo.size or hi.size):
            return p, out
        xs = lo if lo.size else hi
        touch = {"time": t_jump, "time_error": 0.0, "step_bracket": [t_jump, t_jump],
                 "s": float(xs.mean()), "s_spread": float(xs[-1] - xs[0]),
                 "cause": "the interface after the previous jump crosses the rod"}
        _classify_touch(touch, x, s_nodes, p)
    if xs.size:
        out.append({**touch, "action": f"flagged: more than {MAX_WET_JUMPS} jumps"})
    return p, out


def _first_frames(sim, m_last):
    """The frames of ``sim`` up to step m_last (a view as a light result)."""
    k = int(np.searchsorted(sim.times, (m_last + 0.5) * sim.dt))
    return _Frames(sim.times[:k], sim.positions[:k],
                   {key: v[:k] for key, v in sim.energies.items()})


def _last_frame(sim):
    return _Frames(sim.times[-1:], sim.positions[-1:],
                   {key: v[-1:] for key, v in sim.energies.items()})


@dataclass
class _Frames:
    times: np.ndarray
    positions: np.ndarray
    energies: dict


#: Entries of ``SimulationResult.stats`` that an impact made of several runs sums over them
#: (costs, and the self-contact's counts: :func:`dynamics.contact.contact_stats`) and that
#: it takes the largest of (extremes); an entry a run lacks (no self-contact) is skipped.
STATS_SUMMED = ("rejected_steps", "contact_rounds", "compile_time", "run_time",
                "self_contact_steps", "self_contact_rounds", "self_contact_rebuilds",
                "self_contact_band_solves", "self_contact_dense_solves",
                "self_contact_velocity_unsettled", "self_contact_failures")
STATS_MAX = ("max_halvings", "iterations_max", "constraint_error", "self_contact_max_active",
             "self_contact_gap_error", "self_contact_penetration")


def combined_stats(runs, last) -> dict:
    """The ``stats`` of an impact made of the runs ``runs`` (their ``stats`` mappings, in
    the order made) that ends in the final state of the run ``last`` (one of them, not
    always the last made): ``last``'s, with :data:`STATS_SUMMED` summed over every run,
    :data:`STATS_MAX` the largest of any, ``self_contact_failure`` the last reason given,
    and ``runs`` and ``steps_all_runs`` (the steps of every run, re-runs included)."""
    stats = dict(last)
    for key in STATS_SUMMED:
        if key in stats:
            stats[key] = sum(r[key] for r in runs)
    for key in STATS_MAX:
        if key in stats:
            stats[key] = max(r[key] for r in runs)
    failures = [r["self_contact_failure"] for r in runs if r.get("self_contact_failure")]
    if failures:
        stats["self_contact_failure"] = failures[-1]
    stats["runs"] = len(runs)
    stats["steps_all_runs"] = int(sum(r["steps"] for r in runs))
    return stats


def self_contact_summary(stats) -> dict:
    """What the rod's self-contact did in a run, from its ``stats``: the
    ``self_contact_*`` entries without the prefix (``steps``, ``max_active``,
    ``gap_error``, ``failures``, ...; see :func:`dynamics.contact.contact_stats`), or
    ``{}`` when the rod has no thickness (no self-contact effect)."""
    p = "self_contact_"
    return {k[len(p):]: v for k, v in stats.items() if k.startswith(p)}


def _stitch(keep, fired, runs, dt, last) -> SimulationResult:
    """One SimulationResult from the kept pieces, ending in the final state of the run
    ``last``; its stats those of every run made (:func:`combined_stats`: the located
    touches re-run parts of the trajectory, so the counts go with ``steps_all_runs``)."""
    times, pos, ens = [], [], {}
    for piece, first in keep:
        a = 0 if first else 1
        times.append(piece.times[a:])
        pos.append(piece.positions[a:])
        for key, v in piece.energies.items():
            ens.setdefault(key, []).append(v[a:])
    stats = combined_stats([r.stats for r in runs], last.stats)
    stats["steps"] = int(round(last.t_final / dt))
    return SimulationResult(
        times=np.concatenate(times), positions=np.concatenate(pos),
        velocities=last.velocities, energies={k: np.concatenate(v) for k, v in ens.items()},
        status=last.status, success=last.success, message=last.message, method=last.method,
        t_final=last.t_final, dt=dt, stats=stats,
        events_fired=sorted(fired, key=lambda e: e[0]))


def _locate_first_touch(scene, st, rod, sim, options, k_if, s_nodes) -> list:
    """Under "ignore": the first touch of a finished run whose interface first crosses the
    rod at frame ``k_if`` (its time located by re-running to the frame before, then step
    by step, then bisection inside the step), flagged; [] when the interface never
    crosses the rod (``k_if`` < 0)."""
    if k_if < 0:
        return []
    seg = _Segments(scene, st, sim.dt, None, options)
    params = seg.eff.capillary.params.copy()
    seg.frame_steps = np.rint(sim.times / sim.dt).astype(np.int64)
    loc = seg.locate(rod, 0, params, True, k_if, sim, s_nodes)
    touch = loc.touch
    _classify_touch(touch, loc.x_j, s_nodes, loc.cap_j)
    touch["action"] = "flagged: the interface passes through the rod (interface_contact = ignore)"
    touch["relocation_runs"] = len(seg.runs)
    return [touch]


def _run_attempts(scene: Scene, st: dict, rod: Rod, frames, options) -> list:
    """The runs of one impact: at the settings' dt, and, with an automatic dt, again with
    dt halved (at most DT_RETRIES times) while a run fails or its energy rises."""
    scale = scene.drop.line_tension * scene.drop.wetted_length
    retries = DT_RETRIES if not scene.numerics.dt else 0
    dt = st["dt"]
    attempts = []
    for _ in range(retries + 1):
        sim, touches, eff = _simulate_drop(scene, st, rod, dt, frames, options)
        # events fire at the first step boundary at or after their time
        fired_at = [t for t, *_ in sim.events_fired]
        rise, t_rise = energy_rise(sim.times, sim.energies["total"], fired_at)
        attempts.append(_Attempt(dt, sim, eff, rise, t_rise, touches))
        if sim.success and rise <= ENERGY_RISE_TOL * scale:
            break
        dt *= 0.5
    return attempts


def _contact_lines_per_frame(sim, eff: ImpactEffects, s1s2) -> np.ndarray:
    """The capillary parameters in force at each frame (events move S1, S2)."""
    cap = eff.capillary.params.copy()
    cap[1:3] = s1s2
    frames = np.repeat(cap[None], len(sim.times), axis=0)
    for t_ev, name, j, val in sim.events_fired:
        if name == eff.capillary.name:
            frames[np.asarray(sim.times) >= t_ev - 1e-12, j] = val
    return frames


def _closing_note(cap, s_nodes, final) -> str:
    """A note on a failed run whose contact lines have nearly met (else empty)."""
    p = [np.array([np.interp(s, s_nodes, final[:, 0]), np.interp(s, s_nodes, final[:, 1])])
         for s in (cap[1], cap[2])]
    d = float(np.hypot(*(p[1] - p[0])))
    if d >= 0.05 * (cap[2] - cap[1]):
        return ""
    return (f" At the last frame the contact lines are {d:.3g} apart (Delta = "
            f"{cap[2] - cap[1]:.3g}): the drop is closing inside the wrap, where the "
            "circular-cap model is singular (chord -> 0); the outcome up to then was "
            "encapsulation-bound. Try a smaller numerics.dt or a larger numerics.n_edges, "
            "or read it as a closed wrap.")


def run_impact(scene: Scene, frames: int | None = None, **options) -> ImpactResult:
    """Release the rod with the drop spread to Delta and run it to rest.

    Parameters
    ----------
    scene : Scene
    frames : int, optional
        Output frames over [0, t_max] (default: one every FRAME_SPACING time units, at most
        MAX_FRAMES); crossings and the decision time are read on them.
    **options
        Passed to :func:`dynamics.simulate` for the scene's method
        (``numerics.integrator``), e.g. ``jacobian_age=1`` for the midpoint method.

    Returns
    -------
    ImpactResult
        ``simulation`` holds the :class:`dynamics.SimulationResult` (trajectory).
    """
    t0 = time.perf_counter()
    st = impact_settings(scene)
    res, verdict = _impact_once(scene, dict(st), frames, options, t0)
    repeats = []
    while verdict.swing_half_period is not None and len(repeats) < SWING_REPEATS:
        # the rest test fired at a turn of a slow swing: run again with a stricter test
        # (kinetic threshold SWING_REST_KINETIC_FACTOR lower, held for
        # SWING_REST_HALF_PERIODS of that swing's half-periods)
        st["rest_kinetic"] *= SWING_REST_KINETIC_FACTOR
        st["rest_time"] = max(st["rest_time"],
                              SWING_REST_HALF_PERIODS * verdict.swing_half_period)
        repeats.append({"t_end": res.t_end, "final_measure": res.final_measure,
                        "steps": res.steps, "run_time_s": res.run_time_s,
                        "compile_time_s": res.compile_time_s,
                        "swing_half_period": verdict.swing_half_period,
                        "rest_kinetic": st["rest_kinetic"], "rest_time": st["rest_time"]})
        res, verdict = _impact_once(scene, dict(st), frames, options, t0)
    if repeats:
        res.settings["rest_repeats"] = repeats
        res.run_time_s += sum(r["run_time_s"] for r in repeats)
        res.compile_time_s += sum(r["compile_time_s"] for r in repeats)
        res.message = "".join(
            f"At rest at t = {r['t_end']:.4g} the criterion's margin was swinging across 0 "
            f"(half-period {r['swing_half_period']:.3g}): run again with a rest test of "
            f"kinetic energy {r['rest_kinetic']:.3g} for {r['rest_time']:.4g} time units. "
            for r in repeats) + res.message
    return res


def _impact_once(scene: Scene, st: dict, frames, options, t0: float):
    """One impact at settings ``st`` (its dt retries included): the result and its
    :class:`elastocap.criteria.ImpactVerdict`."""
    rod = _initial_rod(scene, st["n_edges"])
    attempts = _run_attempts(scene, st, rod, frames, options)
    scale = scene.drop.line_tension * scene.drop.wetted_length
    # the successful attempt with the smallest rise (else the last one)
    done = [a for a in attempts if a.sim.success]
    best = min(done, key=lambda a: a.rise) if done else attempts[-1]
    st["dt"] = best.dt
    st["dt_retries"] = len(attempts) - 1
    # the first crossings of the kept run, found once: the touch location and the
    # classification both read them
    s_nodes = np.concatenate([[0.0], np.cumsum(rod.edge_len)])
    cap_frames = _contact_lines_per_frame(best.sim, best.effects, _wet_interval(scene))
    crossings = first_crossing_frames(best.sim.positions, s_nodes, cap_frames)
    if scene.drop.interface_contact == "ignore":
        best.touches = _locate_first_touch(scene, st, rod, best.sim, options, crossings[1],
                                           s_nodes)
    best.touches = [_plain_touch(t) for t in best.touches]
    return _classify(scene, st, best, attempts, scale, t0, s_nodes, cap_frames, crossings)


def _plain_touch(t: dict) -> dict:
    """A touch with Python floats (JSON-ready)."""
    def plain(v):
        if isinstance(v, list | tuple):
            return [plain(u) for u in v]
        return float(v) if isinstance(v, np.floating) else v
    return {k: plain(v) for k, v in t.items()}


def touch_note(touches: list, scale: float, most: int = 3) -> str:
    """The touches of the interface with the rod in words (empty without): the first
    ``most`` and, for more, how many, the last and the capillary energy they released."""
    def one(t):
        where = {"s1": "beyond S1", "s2": "beyond S2", "wet": "on the wet part"}[t["side"]]
        txt = (f"t = {t['time']:.6g} +- {t['time_error']:.2g} at S = {t['s']:.6g} ({where}, "
               f"{t['kind']})")
        if t["action"] == "wetted":
            return txt + (f": wetted, S1 = {t['s1']:.6g}, S2 = {t['s2']:.6g}, capillary "
                          f"energy {t['energy_jump'] / scale:+.3g} gamma Delta")
        return txt + ": " + t["action"]

    if not touches:
        return ""
    shown = [one(t) for t in touches[:most]]
    if len(touches) > most:
        jumps = [t for t in touches if t["action"] == "wetted"]
        de = sum(t["energy_jump"] for t in jumps)
        shown.append(f"... {len(touches)} touches in all ({len(jumps)} contact-line jumps, "
                     f"capillary energy {de / scale:+.3g} gamma Delta in all), the last at "
                     + one(touches[-1]))
    return "The drop's interface touches the rod at " + "; ".join(shown) + "."


def _classify(scene, st, best, attempts, scale, t0, s_nodes, cap_frames,
              crossings) -> tuple[ImpactResult, ImpactVerdict]:
    """Measures, the outcome (:func:`elastocap.criteria.impact_verdict`) and the message
    of the kept attempt: nodes at arclengths ``s_nodes``, capillary parameters per frame
    ``cap_frames``, first crossing frames ``crossings``
    (:func:`elastocap.crossings.first_crossing_frames`)."""
    sim, rise, t_rise = best.sim, best.rise, best.t_rise
    measures = turning_measures(sim.positions)
    k_rod, k_if = crossings
    rod_t = float(sim.times[k_rod]) if k_rod >= 0 else None
    if_t = float(sim.times[k_if]) if k_if >= 0 else None
    final = sim.positions[-1]
    criterion, enc, margins = frame_verdicts(scene, sim.positions, s_nodes, measures)
    rise_ok = rise <= ENERGY_RISE_TOL * scale
    verdict = impact_verdict(
        criterion=criterion,
        encapsulated=enc,
        times=sim.times,
        success=sim.success and rise <= ENERGY_RISE_FAIL * scale,
        at_rest=sim.status == "at_rest",
        t_max=st["t_max"],
        rest_advice=rest_advice(scene),
        rise_ok=rise_ok,
        rise_note="" if rise_ok else _rise_message(rise, scale, t_rise),
        rod_crossing_time=rod_t,
        margins=margins,
    )
    message, status = sim.message, sim.status
    if sim.success and not rise_ok:
        message += (" WARNING: " + _rise_message(rise, scale, t_rise)
                    + f" Try a smaller numerics.dt (this run: {st['dt']:.4g}).")
    rejected = [
        f"dt = {a.dt:.4g}: "
        + (a.sim.message if not a.sim.success else _rise_message(a.rise, scale, a.t_rise))
        for a in attempts if a is not best
    ]
    if rejected:
        message += (f" Automatic dt: {len(attempts)} attempts, this one kept; the others: "
                    + "; ".join(rejected))
    if sim.success and rise > ENERGY_RISE_FAIL * scale:
        status = "energy_rise"
    elif not sim.success:
        # a failed run has no outcome: say what failed, and whether the contact lines met
        message += _closing_note(cap_frames[-1], s_nodes, final)
    if verdict.reason:
        message += f" Outcome undecided: {verdict.reason}."
    if best.touches:
        message += " " + touch_note(best.touches, scale)
    crossed = [t for t in (rod_t, if_t) if t is not None]
    decided_after = (bool(crossed) and verdict.decision_time is not None
                     and verdict.decision_time >= min(crossed))
    result = ImpactResult(
        outcome=verdict.outcome,
        criterion=criterion,
        final_measure=float(measures[-1]),
        t_end=float(sim.t_final),
        steps=int(sim.steps),
        wall_time_s=time.perf_counter() - t0,
        status=status,
        message=message,
        end_position=float(final[-1, 0]),
        impact_position=float(np.interp(scene.drop.center, s_nodes, final[:, 0])),
        rod_crossing_time=rod_t,
        interface_crossing_time=if_t,
        decided_after_crossing=bool(decided_after),
        energy_rise=rise / scale,
        at_rest=verdict.at_rest,
        decision_time=verdict.decision_time,
        undecided_reason=verdict.reason,
        compile_time_s=float(sim.stats["compile_time"]),
        run_time_s=float(sim.stats["run_time"]),
        settings={
            **st,
            "scene": scene.name,
            "scene_digest": scene.digest(),
            "version": __version__,
        },
        interface_contact=scene.drop.interface_contact,
        interface_touches=best.touches,
        self_contact=self_contact_summary(sim.stats),
        simulation=sim,
        measure_history=measures,
    )
    return result, verdict
