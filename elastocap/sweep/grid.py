"""Sweep grids: ``LO:HI:N`` ranges, the (x, We^1/2) and (x, Delta) points of a phase diagram,
and the points skipped because the wet interval leaves the rod.

Units: ``x`` is the paper's distance from the impact centre to the free end S = L; sweeps
take it in units of l_eg = (B / (mu g))^(1/3) (Antkowiak et al. 2011, Fig 3) when the scene
has gravity, in scene units otherwise. We^1/2 is converted to the wetted length Delta by the
scene's spreading law (Delta - Delta0) / (2 R) = 0.32 We^1/2 (paper, main text).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from elastocap.scene import Scene, SceneError

__all__ = [
    "SkippedPoint",
    "SweepPoint",
    "grid_points",
    "length_unit",
    "make_point",
    "parse_range",
]

#: Relative tolerance on the wet interval lying inside [0, L]: the scene's own (1e-12 L).
_EDGE_TOL = 1e-12


def parse_range(text: str, option: str) -> np.ndarray:
    """Parse ``LO:HI:N`` into N equally spaced values from LO to HI (both included).

    Raises
    ------
    ValueError
        Naming ``option``, the text received and what is allowed: three fields, finite
        numbers, an integer N >= 1, LO <= HI, and LO = HI when N = 1.
    """
    allowed = "expected LO:HI:N with finite numbers LO <= HI and an integer N >= 1, e.g. 1:6:11"
    parts = str(text).split(":")
    if len(parts) != 3:
        raise ValueError(f"{option}: got {text!r}; {allowed}")
    try:
        lo, hi = float(parts[0]), float(parts[1])
    except ValueError:
        raise ValueError(f"{option}: got {text!r}; {allowed}") from None
    try:
        n = int(parts[2])
    except ValueError:
        raise ValueError(
            f"{option}: got {text!r}; N = {parts[2]!r} is not an integer; {allowed}"
        ) from None
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise ValueError(f"{option}: got {text!r}; {allowed}")
    if n < 1:
        raise ValueError(f"{option}: got {text!r}; N = {n} < 1; {allowed}")
    if lo > hi:
        raise ValueError(f"{option}: got {text!r}; LO = {lo:g} > HI = {hi:g}; {allowed}")
    if n == 1:
        if lo != hi:
            raise ValueError(
                f"{option}: got {text!r}; N = 1 needs LO = HI (one value), "
                f"e.g. {parts[0]}:{parts[0]}:1"
            )
        return np.array([lo])
    return np.linspace(lo, hi, n)


def length_unit(scene: Scene) -> tuple[float, str]:
    """The unit of x in a phase diagram: (l_eg, "l_eg") with gravity, else (1, "scene")."""
    if scene.effects.gravity > 0.0:
        B, mu = scene.rod.bending_modulus, scene.rod.mass_per_length
        return (B / (mu * scene.effects.gravity)) ** (1.0 / 3.0), "l_eg"
    return 1.0, "scene"


@dataclass(frozen=True)
class SweepPoint:
    """One impact of a sweep.

    Attributes
    ----------
    x_over_leg : float
        x in the sweep's unit (l_eg with gravity, else scene units).
    x : float
        Distance from the impact centre to the free end (scene units).
    we_sqrt : float or None
        We^1/2 (None when the scene has no spreading law).
    wetted_length : float
        Delta (scene units).
    """

    x_over_leg: float
    x: float
    we_sqrt: float | None
    wetted_length: float

    def overrides(self) -> dict:
        return {"drop.distance_from_end": self.x, "drop.wetted_length": self.wetted_length}

    def to_dict(self) -> dict:
        return dict(vars(self))


@dataclass(frozen=True)
class SkippedPoint:
    """A requested point that was not run, and why."""

    x_over_leg: float
    x: float
    we_sqrt: float | None
    wetted_length: float
    reason: str

    def to_dict(self) -> dict:
        return dict(vars(self))


def make_point(
    scene: Scene,
    x_over_leg: float,
    *,
    we_sqrt: float | None = None,
    wetted_length: float | None = None,
) -> SweepPoint | SkippedPoint:
    """The point (x/l_eg, We^1/2) or (x/l_eg, Delta) of ``scene``, or the reason to skip it.

    Exactly one of ``we_sqrt`` and ``wetted_length`` is given. A point is skipped (not
    run) when Delta <= 0, Delta > L, or the wet interval [L - x - Delta/2, L - x + Delta/2]
    leaves [0, L].
    """
    if (we_sqrt is None) == (wetted_length is None):
        raise ValueError("make_point: give exactly one of we_sqrt and wetted_length")
    leg, _ = length_unit(scene)
    x = float(x_over_leg) * leg
    if we_sqrt is not None:
        if scene.spreading is None:
            raise SceneError(
                "spreading",
                None,
                "a We^1/2 sweep needs the scene's [spreading] "
                "law; sweep in Delta instead (--delta)",
            )
        delta = scene.spreading.delta(float(we_sqrt))
    else:
        delta = float(wetted_length)
        if scene.spreading is not None:
            we_sqrt = scene.spreading.we_sqrt(delta)
    L = scene.rod.length
    s1, s2 = L - x - 0.5 * delta, L - x + 0.5 * delta
    reason = None
    if not delta > 0.0:
        reason = f"wetted length Delta = {delta:.6g} <= 0"
    elif delta > L:
        reason = f"wetted length Delta = {delta:.6g} > L = {L:.6g}"
    elif s1 < -_EDGE_TOL * L or s2 > L * (1.0 + _EDGE_TOL):
        reason = f"wet interval [S1, S2] = [{s1:.6g}, {s2:.6g}] leaves the rod [0, L = {L:.6g}]"
    if reason is not None:
        return SkippedPoint(float(x_over_leg), x, we_sqrt, delta, reason)
    return SweepPoint(float(x_over_leg), x, we_sqrt, delta)


def grid_points(scene: Scene, xs, *, we_sqrts=None, deltas=None):
    """The grid xs x we_sqrts (or xs x deltas), x-major.

    Returns
    -------
    points : list of SweepPoint
    skipped : list of SkippedPoint
    """
    if (we_sqrts is None) == (deltas is None):
        raise ValueError("grid_points: give exactly one of we_sqrts and deltas")
    points, skipped = [], []
    for xv in xs:
        for v in we_sqrts if deltas is None else deltas:
            p = (
                make_point(scene, xv, we_sqrt=v)
                if deltas is None
                else make_point(scene, xv, wetted_length=v)
            )
            (points if isinstance(p, SweepPoint) else skipped).append(p)
    return points, skipped
