"""From a dimensional experiment to the dimensionless scene (paper: main text and Methods).

All inputs are SI (m, kg, s, N, Pa). Per unit width: the strip's bending modulus
B = E h^3 / (12 (1 - nu^2)) (N m), areal mass mu (kg/m^2), surface tension gamma (N/m). The 2D
model uses the lineic B w, mu w, gamma w; every length scale below is a ratio of those, so the
width w cancels from the dimensionless scene (it only sets the 2D drop area's meaning).

Length scales
    l_ec = (B / gamma)^(1/2)      elasto-capillary
    l_eg = (B / (mu g))^(1/3)     elasto-gravitational
    l_gc = (gamma / (rho g))^(1/2) gravito-capillary
Impact
    We = rho U^2 R / gamma,  capillary velocity (gamma / (rho R))^(1/2)
    spreading law (paper, supplementary eq. [1]): (Delta - Delta0) / (2 R) = 0.32 We^(1/2)
    2D drop area A = V / l_eg with V = 4/3 pi R^3 (paper, Methods)

Dimensionless scene with gravity: units g = mu w = B w = 1, i.e. length l_eg, so that
gamma* = (l_eg / l_ec)^2 and A* = A / l_eg^2; without gravity: units B = gamma = mu = 1, i.e.
length l_ec.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = [
    "DELTA0_TABLE_MM",
    "SPREADING_COEFFICIENT",
    "Experiment",
    "DimensionlessScene",
    "bending_modulus",
    "delta0_for_radius",
    "spreading_length",
    "weber_from_spreading",
    "weber_number",
]

#: Paper, supplementary S1: Delta0 (quasi-static spreading) in mm against drop radius R in mm.
DELTA0_TABLE_MM: tuple[tuple[float, float], ...] = (
    (1.2, 2.04),
    (1.5, 2.20),
    (1.6, 1.96),
    (1.85, 3.68),
)
#: Paper, supplementary eq. [1]: (Delta - Delta0) / (2 R) = 0.32 We^(1/2).
SPREADING_COEFFICIENT = 0.32


def _positive(name: str, value: float) -> float:
    v = float(value)
    if not math.isfinite(v) or v <= 0.0:
        raise ValueError(f"{name}: got {value!r}; expected a finite number > 0")
    return v


def bending_modulus(youngs_modulus: float, thickness: float, poisson_ratio: float) -> float:
    """Plate bending modulus B = E h^3 / (12 (1 - nu^2)), N m (per unit width).

    Parameters
    ----------
    youngs_modulus : float
        E, Pa.
    thickness : float
        h, m.
    poisson_ratio : float
        nu, in (-1, 0.5].
    """
    E = _positive("youngs_modulus", youngs_modulus)
    h = _positive("thickness", thickness)
    nu = float(poisson_ratio)
    if not (-1.0 < nu <= 0.5):
        raise ValueError(f"poisson_ratio: got {poisson_ratio!r}; expected -1 < nu <= 0.5")
    return E * h**3 / (12.0 * (1.0 - nu * nu))


def weber_number(density: float, speed: float, radius: float, surface_tension: float) -> float:
    """We = rho U^2 R / gamma (dimensionless); speed U in m/s may be 0."""
    rho = _positive("liquid_density", density)
    R = _positive("drop_radius", radius)
    gam = _positive("surface_tension", surface_tension)
    U = float(speed)
    if not math.isfinite(U) or U < 0.0:
        raise ValueError(f"impact_speed: got {speed!r}; expected a finite number >= 0")
    return rho * U * U * R / gam


def delta0_for_radius(radius: float) -> float:
    """Quasi-static spreading Delta0 (m) for a drop of radius R (m), from the paper's table.

    Linear interpolation in the table :data:`DELTA0_TABLE_MM`; outside 1.2 mm <= R <= 1.85 mm
    there is no data and a ValueError says to give Delta0 explicitly.
    """
    R_mm = _positive("drop_radius", radius) * 1e3
    rs = [r for r, _ in DELTA0_TABLE_MM]
    ds = [d for _, d in DELTA0_TABLE_MM]
    # 1e-12 mm: accept the table's end points despite the m -> mm round-off
    if R_mm < rs[0] - 1e-12 or R_mm > rs[-1] + 1e-12:
        raise ValueError(
            f"drop_radius: got {radius!r} m ({R_mm:.4g} mm); the paper's Delta0 table covers "
            f"{rs[0]} mm to {rs[-1]} mm only. Give experiment.delta0 explicitly."
        )
    return float(np.interp(R_mm, rs, ds)) * 1e-3


def spreading_length(we: float, radius: float, delta0: float) -> float:
    """Wetted length Delta = Delta0 + 2 R * 0.32 We^(1/2) (same length unit as R, Delta0)."""
    if not math.isfinite(we) or we < 0.0:
        raise ValueError(f"weber: got {we!r}; expected a finite number >= 0")
    return float(delta0) + 2.0 * float(radius) * SPREADING_COEFFICIENT * math.sqrt(we)


def weber_from_spreading(delta: float, radius: float, delta0: float) -> float:
    """Inverse spreading law: We^(1/2) = (Delta - Delta0) / (0.64 R).

    Returns the square root of the Weber number (the paper's plotting variable). A Delta
    below Delta0 gives a negative value: that spreading is not reached by any impact.
    """
    return (float(delta) - float(delta0)) / (2.0 * SPREADING_COEFFICIENT * float(radius))


@dataclass(frozen=True)
class Experiment:
    """Dimensional inputs of a drop-impact experiment (SI units).

    Give either ``bending_modulus`` (N m) or all of ``youngs_modulus`` (Pa), ``thickness`` (m)
    and ``poisson_ratio``. ``delta0`` (m) defaults to the paper's table for ``drop_radius``.
    """

    drop_radius: float
    areal_mass: float
    length: float
    impact_distance: float
    surface_tension: float = 0.072
    liquid_density: float = 1000.0
    gravity: float = 9.81
    width: float = 2e-3
    impact_speed: float = 0.0
    bending_modulus: float | None = None
    youngs_modulus: float | None = None
    thickness: float | None = None
    poisson_ratio: float | None = None
    delta0: float | None = None

    def bending(self) -> float:
        """B, N m."""
        if self.bending_modulus is not None:
            both = [k for k in ("youngs_modulus", "poisson_ratio") if getattr(self, k) is not None]
            if both:  # which B was meant is not knowable (thickness alone sets the contact)
                raise ValueError(
                    f"bending_modulus: got {self.bending_modulus!r}; {' and '.join(both)} "
                    "given too: give bending_modulus, or youngs_modulus, thickness and "
                    "poisson_ratio, not both")
            return _positive("bending_modulus", self.bending_modulus)
        missing = [
            k for k in ("youngs_modulus", "thickness", "poisson_ratio") if getattr(self, k) is None
        ]
        if missing:
            raise ValueError(
                "experiment: give bending_modulus, or youngs_modulus, thickness and "
                f"poisson_ratio (missing: {', '.join(missing)})"
            )
        return bending_modulus(self.youngs_modulus, self.thickness, self.poisson_ratio)

    @property
    def l_ec(self) -> float:
        """Elasto-capillary length (B/gamma)^(1/2), m."""
        return math.sqrt(self.bending() / _positive("surface_tension", self.surface_tension))

    @property
    def l_eg(self) -> float:
        """Elasto-gravitational length (B/(mu g))^(1/3), m."""
        mu = _positive("areal_mass", self.areal_mass)
        g = _positive("gravity", self.gravity)
        return (self.bending() / (mu * g)) ** (1.0 / 3.0)

    @property
    def l_gc(self) -> float:
        """Gravito-capillary length (gamma/(rho g))^(1/2), m."""
        return math.sqrt(self.surface_tension / (self.liquid_density * self.gravity))

    @property
    def capillary_velocity(self) -> float:
        """(gamma / (rho R))^(1/2), m/s."""
        return math.sqrt(self.surface_tension / (self.liquid_density * self.drop_radius))

    @property
    def weber(self) -> float:
        return weber_number(
            self.liquid_density, self.impact_speed, self.drop_radius, self.surface_tension
        )

    @property
    def volume(self) -> float:
        """Drop volume 4/3 pi R^3, m^3."""
        return 4.0 / 3.0 * math.pi * _positive("drop_radius", self.drop_radius) ** 3

    @property
    def area_2d(self) -> float:
        """The paper's 2D drop area A = V / l_eg, m^2."""
        return self.volume / self.l_eg

    def quasi_static_spreading(self) -> float:
        """Delta0, m."""
        if self.delta0 is not None:
            return _positive("delta0", self.delta0)
        return delta0_for_radius(self.drop_radius)

    def wetted_length(self) -> float:
        """Delta from the spreading law at this experiment's impact speed, m."""
        return spreading_length(self.weber, self.drop_radius, self.quasi_static_spreading())

    def dimensionless(self) -> DimensionlessScene:
        """The scene in units g = mu = B = 1 (length l_eg, time (l_eg/g)^(1/2))."""
        leg = self.l_eg
        L = _positive("length", self.length) / leg
        x = float(self.impact_distance) / leg
        delta = self.wetted_length() / leg
        return DimensionlessScene(
            length=L,
            line_tension=(leg / self.l_ec) ** 2,
            area=self.area_2d / leg**2,
            wetted_length=delta,
            distance_from_end=x,
            gravity=1.0,
            length_unit=leg,
            drop_radius=self.drop_radius / leg,
            delta0=self.quasi_static_spreading() / leg,
        )


@dataclass(frozen=True)
class DimensionlessScene:
    """An experiment in units g = mu = B = 1. Lengths in units of ``length_unit`` (m)."""

    length: float
    line_tension: float
    area: float
    wetted_length: float
    distance_from_end: float
    gravity: float
    length_unit: float
    drop_radius: float
    delta0: float
