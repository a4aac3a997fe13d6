"""Encapsulation criteria read from a final rod shape: the paper's lab-frame test and a
frame-independent companion.

Both take the final node positions of the rod (n + 1, 2) in the (x, z) plane, S = 0 at the
first node and S = L at the last, and the scene (for the impact centre S_c = L - x and the
contact line S1). Arclength along the polyline is measured on the positions themselves
(the rod is inextensible: it equals the scene's S up to the constraint tolerance).

* :func:`lab_frame_outcome` -- Antkowiak et al., PNAS 2011, Methods: encapsulated when the
  free end has moved to the left of the impact centre, x(L) < x(S_c), in the lab frame. It
  is what :func:`elastocap.impact.run_impact` reports. It assumes the rod still enters the
  drop along +x; a wrapped bundle that lifts off and flips over reads "open".
* :func:`companion_outcome` -- the same test in the rod's own frame (defined precisely in
  its docstring): invariant to any rotation and translation of the whole rod, and to the
  bundle (the wet part and the free end) rotating as one piece.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from elastocap.geometry import arclength, turning_from

__all__ = [
    "OUTCOMES",
    "CriterionResult",
    "ImpactVerdict",
    "UNDECIDED",
    "frame_verdicts",
    "impact_verdict",
    "companion_outcome",
    "companion_reading",
    "final_contact_lines",
    "lab_frame_outcome",
    "point_and_tangent",
    "swing_range",
]

ENCAPSULATED = "encapsulated"
OPEN = "open"
UNDECIDED = "undecided"
FAILED = "failed"
#: Every outcome an impact can have.
OUTCOMES = (OPEN, ENCAPSULATED, UNDECIDED, FAILED)


@dataclass(frozen=True)
class CriterionResult:
    """An encapsulation verdict and the number it was read from.

    Attributes
    ----------
    outcome : str
        "encapsulated" or "open".
    measure : float
        The signed quantity the verdict thresholds (its sign decides; see each criterion).
    criterion : str
        One line naming the test.
    turning : float
        (theta(L) - theta(S1)) / pi, the turning of the rod from the contact line S1 to the
        free end (a diagnostic, frame-independent; 0 for a flat strip, about 1 when the end
        has folded back over the drop).
    """

    outcome: str
    measure: float
    criterion: str
    turning: float = math.nan

    def to_dict(self) -> dict:
        return dict(vars(self))


def _check_positions(positions) -> np.ndarray:
    x = np.asarray(positions, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != 2 or x.shape[0] < 2:
        raise ValueError(
            f"positions: expected an array of shape (n + 1, 2) with n >= 1, got shape {x.shape}"
        )
    if not np.all(np.isfinite(x)):
        raise ValueError("positions: expected finite numbers, got NaN or inf")
    return x


def point_and_tangent(positions, s: float, length: float | None = None):
    """Point x(s) (linear interpolation) and unit tangent (of the edge holding s) of a
    polyline (n + 1, 2). At a node the edge that starts there is used (the last edge at S =
    L). ``length`` rescales the polyline's arclength to the rod length (scene units)."""
    x = _check_positions(positions)
    sn = arclength(x, length)
    if not (sn[0] - 1e-12 * sn[-1] <= s <= sn[-1] * (1.0 + 1e-12)):
        raise ValueError(f"s: got {s!r}; expected 0 <= s <= L = {sn[-1]!r}")
    k = int(np.clip(np.searchsorted(sn, s, side="right") - 1, 0, len(sn) - 2))
    e = x[k + 1] - x[k]
    h = math.hypot(e[0], e[1])
    frac = (s - sn[k]) / (sn[k + 1] - sn[k])
    return x[k] + frac * e, e / h


def final_contact_lines(scene) -> tuple[float, float]:
    """(S1, S2) in force at the end of an impact: the scene's, moved by its drop events."""
    s1, s2 = scene.drop.s1, scene.drop.s2
    for ev in scene.drop.events:
        s1 = s1 if ev.s1 is None else ev.s1
        s2 = s2 if ev.s2 is None else ev.s2
    return s1, s2


def lab_frame_outcome(positions, scene) -> CriterionResult:
    """The paper's criterion (Methods): encapsulated iff x(L) < x(S_c) in the lab frame.

    Parameters
    ----------
    positions : array (n + 1, 2)
        Final node positions (scene length units), S = 0 first.
    scene : Scene
        Gives L and the impact centre S_c = L - x (``scene.drop.center``).

    Returns
    -------
    CriterionResult
        ``measure`` = (x(L) - x(S_c)) / x_impact: +1 for a flat strip along +x, negative when
        encapsulated. Not invariant: rotating the rod by 180 degrees flips the verdict.
    """
    x = _check_positions(positions)
    L = scene.rod.length
    pc, _ = point_and_tangent(x, scene.drop.center, L)
    s1, _ = final_contact_lines(scene)
    m = float(x[-1, 0] - pc[0]) / max(scene.distance_from_end, 1e-300)
    return CriterionResult(
        outcome=ENCAPSULATED if m < 0.0 else OPEN,
        measure=m,
        criterion="paper (Methods): x(L) < x(S_c) in the lab frame",
        turning=turning_from(x, s1, L),
    )


def companion_outcome(positions, scene) -> CriterionResult:
    """Frame-independent encapsulation: the free end lies behind the impact centre, measured
    along the direction in which the rod enters the drop.

    Definition. Let S1 be the contact line on the long side of the strip (the one nearer
    S = 0, after any drop events), t1 the unit tangent of the rod at S1 (pointing towards
    increasing S, i.e. into the drop), P_c = x(S_c) the material point at the impact centre
    S_c = L - x, and P_L = x(L) the free end. The measure is

        c = (P_L - P_c) . t1 / x

    and the strip is *encapsulated* iff c < 0. For a flat strip c = +1. When the rod enters
    the drop horizontally along +x (the strip's base lying on the ground, t1 = e_x) this is
    exactly the paper's test x(L) < x(S_c); otherwise it is that test read in the frame of
    the rod at the contact line. c involves only differences of positions and a tangent of
    the same shape, so it is unchanged by any rotation and translation of the whole rod, and
    by any rigid rotation of the part S >= S1 alone (a wrapped bundle that lifts off and
    flips over): the lab-frame test flips in those cases, this one does not.

    Parameters
    ----------
    positions : array (n + 1, 2)
        Final node positions (scene length units), S = 0 first.
    scene : Scene
        Gives L, the impact centre S_c = ``scene.drop.center`` (x = L - S_c) and S1.

    Returns
    -------
    CriterionResult
        ``measure`` = c (dimensionless), ``turning`` = (theta(L) - theta(S1)) / pi.
    """
    x = _check_positions(positions)
    L = scene.rod.length
    s1, _ = final_contact_lines(scene)
    _, t1 = point_and_tangent(x, s1, L)
    pc, _ = point_and_tangent(x, scene.drop.center, L)
    c = float(np.dot(x[-1] - pc, t1)) / max(scene.distance_from_end, 1e-300)
    return CriterionResult(
        outcome=ENCAPSULATED if c < 0.0 else OPEN,
        measure=c,
        criterion="companion: (x(L) - x(S_c)) . t(S1) < 0 (rod frame at the contact line S1)",
        turning=turning_from(x, s1, L),
    )


# ------------------------------------------------------------------------- impact outcome

#: The criterion each kind of scene is judged by (one line, recorded with the outcome).
LAB_FRAME = "paper (Methods): x(L) < x(L - x_impact) in the lab frame"
FREE_ROD = "free rod: measure (theta(L) - theta(0))/pi > 1"


def frame_verdicts(scene, positions, s_nodes, measures) -> tuple[str, np.ndarray, np.ndarray]:
    """The impact criterion read on every frame: (criterion, encapsulated (k,) bool, the
    signed margin (k,) to its threshold).

    Scenes with gravity or a ground: the paper's lab-frame test, margin x(L) - x(S_c)
    (negative when encapsulated; ``s_nodes`` the nodes' rest arclengths).  The free rod
    without gravity: the encapsulation measure M = (theta(L) - theta(0))/pi (``measures``,
    one per frame) against 1, margin M - 1 (positive when encapsulated).
    """
    pos = np.asarray(positions, dtype=np.float64)
    if scene.effects.gravity > 0 or scene.effects.ground:
        xc = np.array([np.interp(scene.drop.center, s_nodes, p[:, 0]) for p in pos])
        q = pos[:, -1, 0] - xc
        return LAB_FRAME, q < 0.0, q
    m = np.asarray(measures, dtype=np.float64)
    return FREE_ROD, m > 1.0, m - 1.0


@dataclass(frozen=True)
class Swing:
    """Where a swinging margin is headed (:func:`swing_range`).

    Attributes
    ----------
    lo, hi : float
        The range the margin still covers: its last value, the extrapolated rest value and
        the extrapolated next extreme (or the last swing's extremes).
    limit : float or None
        The extrapolated rest value (None without three extremes of a decaying swing).
    half_period : float
        Time between the last two extremes.
    """

    lo: float
    hi: float
    limit: float | None
    half_period: float


#: A margin that has moved back from the extreme of its last leg by more than this
#: fraction of itself has turned (:func:`swing_range`); wiggles at rest are smaller.
REVERSAL = 1e-3
#: A swing is live while the time since its last turn is below this many half-periods (a
#: swing turns again within one; measured on supp-fig5 next door: readings at a turn come
#: 0.2 half-periods after the last, and a creep that had turned at the impact's overshoot
#: came 1.8 after it, open at rest as a strict rest test confirms)
LIVE = 1.5


def _extremes(y: np.ndarray, h: float) -> list[int]:
    """Indices of the turning points of ``y`` that it left by more than ``h`` (a zigzag
    with hysteresis ``h``; wiggles smaller than h are not turns), then the running extreme
    of its last leg."""
    turns: list[int] = []
    k_ext, direction = 0, 0
    for k in range(1, y.size):
        if direction == 0:
            # the first leg: its direction is set once y has left y[0] by more than h
            if abs(y[k] - y[0]) > h:
                direction, k_ext = (1 if y[k] > y[0] else -1), k
        elif y[k] * direction >= y[k_ext] * direction:
            k_ext = k
        elif abs(y[k] - y[k_ext]) > h:
            turns.append(k_ext)
            direction, k_ext = -direction, k
    return turns + [k_ext]


def swing_range(times, margins) -> Swing | None:
    """The range a margin that is still swinging will cover, or None when it is not
    swinging.

    A run at rest can be read at a turning point of a slow, weakly damped oscillation: the
    kinetic energy passes through zero there, so a kinetic rest test can fire while the
    shape is still far from its equilibrium.  The margin's last turns tell: with
    ``h = |margin[-1]| / 2``, its turning points left by more than h are found (a swing
    smaller than h cannot carry the margin across 0); the extreme of the last leg is a turn
    too when the margin has moved back from it by more than ``REVERSAL`` of itself (the
    rest test fired just after a turn).  The swing is live when there are two turns and the
    time since the last is below ``LIVE`` times the time between the last two (else the
    margin has gone a half-period and a half without the turn a swing would make: no
    swing).  Three turns e0, e1, e2 of a
    decaying oscillation about m give the ratio r = (e2 - e1)/(e1 - e0) in (-1, 0), the
    rest value m = e2 + r (e2 - e1)/(1 - r) (Aitken's extrapolation, exact for a geometric
    decay) and the extreme after e2, m + r (e2 - m); the range is the hull of the last
    margin with those.  With two turns only, or a swing that does not decay, it is the hull
    of the last margin and the last two turns.
    """
    t = np.asarray(times, dtype=np.float64)
    y = np.asarray(margins, dtype=np.float64)
    if y.size < 3 or not np.all(np.isfinite(y)):
        return None
    last = float(y[-1])
    ks = _extremes(y, 0.5 * abs(last))
    turns, ext = ks[:-1], ks[-1]
    if turns and abs(last - float(y[ext])) > REVERSAL * abs(last):
        # the margin has turned back from the extreme of its last leg: a turn
        turns = ks
    if len(turns) < 2 or t[-1] - t[turns[-1]] >= LIVE * (t[turns[-1]] - t[turns[-2]]):
        return None
    half = float(t[turns[-1]] - t[turns[-2]])
    e1, e2 = float(y[turns[-2]]), float(y[turns[-1]])
    if len(turns) >= 3:
        e0 = float(y[turns[-3]])
        r = (e2 - e1) / (e1 - e0)
        if -1.0 < r < 0.0:
            limit = e2 + r * (e2 - e1) / (1.0 - r)
            cover = (last, limit, limit + r * (e2 - limit))
            return Swing(min(cover), max(cover), limit, half)
    cover = (last, e1, e2)
    return Swing(min(cover), max(cover), None, half)


@dataclass(frozen=True)
class ImpactVerdict:
    """The outcome of an impact run and what it rests on.

    Attributes
    ----------
    outcome : str
        "open" or "encapsulated" when the run is decided; "undecided" (``reason`` says
        why) or "failed" (a numerical failure) otherwise.
    criterion : str
    at_rest : bool
        The run came to rest before t_max.
    decision_time : float or None
        Time of the frame from which the criterion's verdict no longer changes (None when
        there are no frames).
    reason : str or None
        Why the outcome is undecided (None when decided or failed).
    swing_half_period : float or None
        When the only reason is that the rest test fired at a turn of a swing of the
        criterion's margin (:func:`swing_range`): that swing's half-period (a longer
        ``numerics.rest_time`` decides such a run); else None.
    """

    outcome: str
    criterion: str
    at_rest: bool
    decision_time: float | None
    reason: str | None = None
    swing_half_period: float | None = None


def companion_reading(outcome: str, companion: str) -> str:
    """The companion criterion's outcome of a run whose paper's-criterion outcome is
    ``outcome``: a run left undecided (not at rest, or its verdict settled after the rod
    crossed itself: properties of the run, not of the criterion) is undecided under the
    companion criterion too; else ``companion``."""
    return UNDECIDED if outcome == UNDECIDED else companion


def impact_verdict(*, criterion, encapsulated, times, success, at_rest, t_max,
                   rise_ok, rise_note, rod_crossing_time, rest_advice, margins=None,
                   ) -> ImpactVerdict:
    """The outcome of an impact, decided in one place.

    ``open``/``encapsulated`` only when the run succeeded numerically (else ``failed``),
    came to rest before ``t_max``, its energy audit passed (``rise_ok``; ``rise_note`` says
    what failed), the verdict was settled before the rod first crossed itself (the model
    has no rod-rod contact: a verdict reached after such a crossing rests on motion the
    model cannot represent), and the criterion's margin (``margins``, one per frame, its
    sign the verdict) was not still swinging across its threshold when the run was read at
    rest (:func:`swing_range`).  Otherwise ``undecided`` with the reason (``rest_advice``:
    what to try when the run did not come to rest).  The verdict at the last frame is the
    outcome; it is "settled" at the first frame after which it no longer changes
    (``decision_time``).
    """
    enc = np.asarray(encapsulated, dtype=bool)
    times = np.asarray(times, dtype=np.float64)
    decision = None
    if enc.size:
        flips = np.nonzero(enc[1:] != enc[:-1])[0]
        decision = float(times[flips[-1] + 1] if flips.size else times[0])
    if not success or not enc.size:
        return ImpactVerdict(FAILED, criterion, bool(at_rest), decision)
    reasons = []
    if not at_rest:
        reasons.append(f"the run did not come to rest by t_max = {t_max:g} ({rest_advice})")
    if not rise_ok:
        reasons.append(f"the energy audit failed: {rise_note}")
    if rod_crossing_time is not None and decision >= rod_crossing_time:
        reasons.append(
            f"the verdict settled at t = {decision:.4g}, after the rod crossed itself at "
            f"t = {rod_crossing_time:.4g} (the model has no contact of the rod with itself)")
    swing = swing_range(times, margins) if at_rest and margins is not None else None
    if swing is not None and not swing.lo < 0.0 < swing.hi:
        swing = None  # a swing that cannot carry the margin across 0 changes nothing
    if swing is not None:
        where = ("" if swing.limit is None
                 else f", its damped swing extrapolates to rest at {swing.limit:+.4g}")
        reasons.append(
            f"at rest the criterion's margin {float(margins[-1]):+.4g} was still swinging "
            f"across 0 (half-period {swing.half_period:.3g}{where}; it covers "
            f"{swing.lo:+.4g} ... {swing.hi:+.4g}): the rest test fired near a turning "
            "point (lower numerics.rest_kinetic, or raise numerics.rest_time above the "
            "half-period)")
    outcome = ENCAPSULATED if enc[-1] else OPEN
    if reasons:
        return ImpactVerdict(UNDECIDED, criterion, bool(at_rest), decision,
                             f"would read {outcome}, but " + "; ".join(reasons),
                             swing.half_period if swing is not None and len(reasons) == 1
                             else None)
    return ImpactVerdict(outcome, criterion, bool(at_rest), decision)
