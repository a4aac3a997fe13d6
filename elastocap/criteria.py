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

__all__ = [
    "CriterionResult",
    "companion_outcome",
    "final_contact_lines",
    "lab_frame_outcome",
    "point_and_tangent",
]

ENCAPSULATED = "encapsulated"
OPEN = "open"


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


def _arclength(x: np.ndarray, length: float | None) -> np.ndarray:
    """Node arclengths (n + 1,) of a polyline, rescaled so the last one is ``length``."""
    seg = np.hypot(*np.diff(x, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    if length is not None and s[-1] > 0.0:
        s *= length / s[-1]
    return s


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
    sn = _arclength(x, length)
    if not (sn[0] - 1e-12 * sn[-1] <= s <= sn[-1] * (1.0 + 1e-12)):
        raise ValueError(f"s: got {s!r}; expected 0 <= s <= L = {sn[-1]!r}")
    k = int(np.clip(np.searchsorted(sn, s, side="right") - 1, 0, len(sn) - 2))
    e = x[k + 1] - x[k]
    h = math.hypot(e[0], e[1])
    frac = (s - sn[k]) / (sn[k + 1] - sn[k])
    return x[k] + frac * e, e / h


def _turning(x: np.ndarray, s_from: float, length: float) -> float:
    """(theta(L) - theta(s_from)) / pi: summed turning angles of the edges after s_from."""
    sn = _arclength(x, length)
    k = int(np.clip(np.searchsorted(sn, s_from, side="right") - 1, 0, len(sn) - 2))
    e = np.diff(x[k:], axis=0)
    if len(e) < 2:
        return 0.0
    cross = e[:-1, 0] * e[1:, 1] - e[:-1, 1] * e[1:, 0]
    dot = np.sum(e[:-1] * e[1:], axis=1)
    return float(np.sum(np.arctan2(cross, dot)) / math.pi)


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
        turning=_turning(x, s1, L),
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
        turning=_turning(x, s1, L),
    )
