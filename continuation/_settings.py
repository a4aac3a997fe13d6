"""Frozen, validated continuation settings."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass


def checked_fields(cls, d: dict) -> dict:
    """A copy of ``d``, refused (naming them) if it has keys that are not fields of the
    dataclass ``cls``: what each settings class's ``from_dict`` reads."""
    unknown = set(d) - {f.name for f in dataclasses.fields(cls)}
    if unknown:
        raise ValueError(f"{cls.__name__}.from_dict: unknown fields {sorted(unknown)}")
    return dict(d)


@dataclass(frozen=True)
class ContinuationSettings:
    """Immutable settings of the pseudo-arclength driver.

    Every check quotes the offending field and value. Build variants with
    ``dataclasses.replace(settings, ds_max=0.5)`` or :meth:`replace`.

    Parameters
    ----------
    ds0 : float
        Initial arclength step (> 0), in the weighted norm below.
    ds_min, ds_max : float
        Bounds of the adaptive step. The run stops (status 2) when a step
        shorter than ``ds_min`` fails.
    max_steps : int
        Number of continuation steps per direction.
    p_min, p_max : float
        Parameter bounds; the branch ends exactly on a bound it crosses.
    direction : {+1, -1, 0}
        Initial direction of p (+1 increasing, -1 decreasing); 0 continues both
        ways from the start and joins the two halves.
    newton_tol : float
        Newton stops when ``max|F| <= newton_tol`` (absolute, in the units of F).
    max_newton : int
        Newton iterations per corrector. From a tangent predictor Newton
        converges quadratically in 2-4 iterations; needing more means the step
        is too long, and shrinking is cheaper than iterating.
    theta : float in (0, 1)
        Weight of the state in the arclength norm
        ``|(du, dp)|^2 = theta |du|^2 / n + (1 - theta) dp^2`` (BifurcationKit
        convention): the 1/n makes the step independent of the resolution.
    corrector : {"keller", "moore-penrose"}
        Keller's pseudo-arclength (fixed tangent in the corrector) or
        Moore-Penrose (tangent updated at every Newton iteration).
    step_grow, step_shrink : float
        Step factors after an easy step / a failed one. 1.5 and 0.5 are the
        usual safe choices (AUTO, pde2path): growth is cautious, retreat fast.
    newton_easy : int
        A corrector that converges within this many iterations counts as easy
        and lets the step grow.
    max_turn : float
        Largest angle (radians) between consecutive tangents; a step that turns
        more is rejected and shortened, so the corrector cannot jump to another
        branch near a branch point or cut a fold corner.
    detect_folds, detect_branch_points, locate : bool
        Detect folds (sign change of dp/ds), branch points (sign change of the
        bordered determinant), and locate them exactly.
    locate_tol : float
        Newton tolerance of the fold / branch-point location systems.
    event_dips : bool
        Also look for an event whose function has one sign at both ends of a step but
        changes sign and back inside it: each entry's values and slopes along the tangent
        at the step's ends give a cubic; where the cubic changes sign, points corrected on
        the step's arc confirm it, and a confirmed crossing is an event like any other.
        Costs one more evaluation of each event function per point (its slope, a forward
        difference), and corrected points only on the steps where a cubic changes sign.
    event_steps : bool
        Approach an event's zero as a fold: where an event's value, extrapolated linearly
        along the tangent, reaches 0 within half the next step, that step ends at most one
        predicted distance past it (it shrinks by at most 20 at a time), so that a step
        cannot pass over a stretch where the event has the other sign (a corrector that
        jumps there sees the event at neither end). Uses the slopes of ``event_dips``
        (computed where either is on); changes the steps, not the curve.
    compute_stability : bool
        Record the stability index when the problem has ``hessian``.
    store_states : bool
        Keep every state and tangent (else only observables, and states at
        special points and endpoints).
    check_jacobian : bool
        Compare the supplied derivatives with finite differences at the start
        (16 residual evaluations) and raise a clear error if wrong.
    """

    ds0: float = 0.01
    ds_min: float = 1e-8
    ds_max: float = 0.1
    max_steps: int = 500
    p_min: float = -math.inf
    p_max: float = math.inf
    direction: int = 1
    newton_tol: float = 1e-10
    max_newton: int = 8
    theta: float = 0.5
    corrector: str = "keller"
    step_grow: float = 1.5
    step_shrink: float = 0.5
    newton_easy: int = 3
    max_turn: float = 0.5
    detect_folds: bool = True
    detect_branch_points: bool = True
    locate: bool = True
    locate_tol: float = 1e-12
    event_dips: bool = True
    event_steps: bool = True
    compute_stability: bool = True
    store_states: bool = True
    check_jacobian: bool = True

    def __post_init__(self):
        def bad(field, value, expected, hint=""):
            raise ValueError(
                f"ContinuationSettings.{field}={value!r}: expected {expected}." + (
                    f" {hint}" if hint else "")
            )

        for f in ("ds0", "ds_min", "ds_max", "newton_tol", "locate_tol", "max_turn"):
            v = getattr(self, f)
            if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
                bad(f, v, "a finite number > 0")
        if not self.ds_min <= self.ds0 <= self.ds_max:
            bad("ds0", self.ds0, f"ds_min <= ds0 <= ds_max (ds_min={self.ds_min!r}, "
                f"ds_max={self.ds_max!r})", "Widen [ds_min, ds_max] or change ds0.")
        for f in ("max_steps", "max_newton", "newton_easy"):
            v = getattr(self, f)
            if not (isinstance(v, int) and not isinstance(v, bool) and v >= 1):
                bad(f, v, "an integer >= 1")
        if not (self.p_min < self.p_max) or math.isnan(self.p_min) or math.isnan(self.p_max):
            bad("p_min", self.p_min, f"p_min < p_max (p_max={self.p_max!r})")
        if self.direction not in (-1, 0, 1):
            bad("direction", self.direction, "+1, -1 or 0 (both directions)")
        if not 0.0 < self.theta < 1.0:
            bad("theta", self.theta, "a weight strictly between 0 and 1")
        if self.corrector not in ("keller", "moore-penrose"):
            bad("corrector", self.corrector, "'keller' or 'moore-penrose'")
        if not self.step_grow >= 1.0:
            bad("step_grow", self.step_grow, "a factor >= 1")
        if not 0.0 < self.step_shrink < 1.0:
            bad("step_shrink", self.step_shrink, "a factor in (0, 1)")

    def replace(self, **changes) -> ContinuationSettings:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict:
        """Plain JSON data: every field; an unbounded ``p_min`` / ``p_max`` (-inf / inf)
        is ``None`` (JSON ``null``: no bound). :meth:`from_dict` reads it back."""
        d = dataclasses.asdict(self)
        for k in ("p_min", "p_max"):
            if math.isinf(d[k]):
                d[k] = None
        return d

    @classmethod
    def from_dict(cls, d: dict) -> ContinuationSettings:
        """The settings :meth:`to_dict` wrote (``p_min`` / ``p_max`` ``None``: unbounded)."""
        d = checked_fields(cls, d)
        for k, inf in (("p_min", -math.inf), ("p_max", math.inf)):
            if k in d and d[k] is None:
                d[k] = inf
        return cls(**d)
