"""Where the open and the encapsulated strip exist in Delta: the static bistability window.

At one drop position x and resolution n (:class:`~elastocap.strip.discrete.DiscreteStrip`):

* the open branch is the open state of a quasi-static deposition at a small Delta
  (:func:`~elastocap.strip.mep.open_state`), continued up in Delta; ``open_max`` is where
  it ends;
* the encapsulated branch is the strip folded over the drop at a large Delta
  (:func:`~elastocap.strip.mep.wrapped_state`), continued down; ``wrapped_min`` is where
  it ends.

Both ends are bisected to ``min_step`` by :func:`~elastocap.strip.mep.continue_in_delta_end`,
which also says how each branch ended (a fold, a jump to another branch, a continuous change
of kind, or the end of the scanned range). Both states exist for wrapped_min < Delta <
open_max when that interval is not empty.

A branch continued from one seed is one branch: another open (or encapsulated) state may
exist beyond its end (measured at x = 4: the open branch ends at 1.233 at n = 143 while a
deposition at Delta = 1.3 still gives an open state). :func:`branch_window` therefore also
tries, just beyond each end, a fresh deposition (or a fresh fold), and reports it in
``open_beyond`` / ``wrapped_beyond``.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass

import numpy as np

from elastocap.strip.discrete import DiscreteStrip
from elastocap.strip.mep import (
    continue_in_delta_end,
    is_encapsulated,
    open_state,
    wrapped_state,
)

__all__ = ["Window", "branch_window", "window_at"]

# Continuation step in Delta (length): steps of 0.05 move the edges by < 0.05 rad on a
# branch (mep._JUMP is 0.3), and a failed step is bisected down to ``min_step`` anyway.
_STEP = 0.05
# The fresh deposition / fold beyond an end is tried this many ``min_step`` past it, so as
# to be past the bracketed end whatever its place in the bracket.
_BEYOND = 2.0


@dataclass
class Window:
    """The Delta range of the open and of the encapsulated branch at one (x, n).

    Attributes
    ----------
    x : float
        Drop position, distance from the free end (length).
    n : int
        Edges.
    open_max : float
        Last Delta (length) where the open branch was kept; nan if the seed failed.
    open_end : str
        How the open branch ended (``mep.END_REASONS``), or ``seed_failed``.
    open_failed : float or None
        Delta of the first failed attempt past ``open_max`` (within ``min_step``).
    wrapped_min, wrapped_end, wrapped_failed
        The same for the encapsulated branch, continued downwards.
    open_beyond : bool or None
        A fresh deposition (descent from the flat strip) at open_max + 2 min_step gives a
        stable open state: another open branch exists there. None when not tried.
    wrapped_beyond : bool or None
        A fresh fold at wrapped_min - 2 min_step gives a stable encapsulated state.
    d_lo, d_hi, min_step : float
        The scanned range and the bisection resolution (length).
    time : float
        Wall time (s).
    """

    x: float
    n: int
    open_max: float
    open_end: str
    open_failed: float | None
    wrapped_min: float
    wrapped_end: str
    wrapped_failed: float | None
    open_beyond: bool | None
    wrapped_beyond: bool | None
    d_lo: float
    d_hi: float
    min_step: float
    time: float

    @property
    def bistable(self) -> bool:
        """Both branches exist over an interval of Delta longer than ``min_step``."""
        return self.open_max - self.wrapped_min > self.min_step

    def to_dict(self) -> dict:
        return {**asdict(self), "bistable": self.bistable}


def _fresh(strip: DiscreteStrip, delta: float, want_encapsulated: bool) -> bool | None:
    """Does a fresh deposition (open) or fold (encapsulated) at ``delta`` give a stable
    state of the wanted kind? None if ``delta`` puts the drop off the strip."""
    try:
        s = strip.with_(delta=delta)
    except ValueError:
        return None
    eq = wrapped_state(s) if want_encapsulated else open_state(s)
    return bool(eq.success and eq.index == 0 and is_encapsulated(s, eq.u) == want_encapsulated)


def branch_window(strip: DiscreteStrip, d_lo=0.5, d_hi=2.2, d_start_open=0.6,
                  d_start_wrap=1.6, step=_STEP, min_step=1e-3, check_beyond=True) -> Window:
    """Ends of the open and of the encapsulated branch in Delta at the strip's x and n.

    Parameters
    ----------
    strip : DiscreteStrip
        Supplies n, L, x, A, gamma, B, q (its own Delta is not used).
    d_lo, d_hi : float
        Range of Delta scanned (length); a branch reaching it ends with ``scan_limit``.
        Needs 0 < d_lo < d_start_open, d_start_wrap < d_hi < 2 x (the drop on the strip).
    d_start_open : float
        Delta of the deposition that seeds the open branch (length).
    d_start_wrap : float
        Delta of the fold that seeds the encapsulated branch (length).
    step : float
        Continuation step in Delta (length).
    min_step : float
        Bisection resolution of each end (length).
    check_beyond : bool
        Try a fresh deposition / fold just beyond each end (``open_beyond``,
        ``wrapped_beyond``).

    Returns
    -------
    Window
    """
    x = float(strip.x_end)
    if not (0.0 < d_lo < d_start_open < d_hi and d_lo < d_start_wrap < d_hi):
        raise ValueError(
            f"d_lo, d_start_open, d_start_wrap, d_hi: got {d_lo}, {d_start_open}, "
            f"{d_start_wrap}, {d_hi}; expected 0 < d_lo < d_start_open, d_start_wrap < d_hi")
    if d_hi >= 2.0 * x:
        raise ValueError(f"d_hi: got {d_hi} at x = {x}; expected d_hi < 2 x = {2.0 * x} "
                         "(the wet interval must stay on the strip)")
    if min_step <= 0.0 or step <= min_step:
        raise ValueError(f"step, min_step: got {step}, {min_step}; expected "
                         "0 < min_step < step")
    t0 = time.perf_counter()

    def ends(d0, seed, deltas, want_encapsulated):
        s = strip.with_(delta=d0)
        eq = seed(s)
        if not (eq.success and eq.index == 0 and is_encapsulated(s, eq.u) == want_encapsulated):
            return math.nan, "seed_failed", None
        states, end = continue_in_delta_end(s, eq, deltas, min_step=min_step)
        last = states[-1][0] if states else d0
        return last, end["reason"], end["delta_failed"]

    up = np.arange(d_start_open + step, d_hi + 1e-9, step)
    o_max, o_end, o_fail = ends(d_start_open, open_state, up, False)
    dn = np.arange(d_start_wrap - step, d_lo - 1e-9, -step)
    w_min, w_end, w_fail = ends(d_start_wrap, wrapped_state, dn, True)
    o_beyond = w_beyond = None
    if check_beyond:
        if o_end not in ("scan_limit", "seed_failed"):
            o_beyond = _fresh(strip, o_max + _BEYOND * min_step, False)
        if w_end not in ("scan_limit", "seed_failed"):
            w_beyond = _fresh(strip, w_min - _BEYOND * min_step, True)
    return Window(x, int(strip.n), float(o_max), o_end, o_fail, float(w_min), w_end,
                  w_fail, o_beyond, w_beyond, float(d_lo), float(d_hi), float(min_step),
                  time.perf_counter() - t0)


def window_at(template: DiscreteStrip, x: float, n: int, **kw) -> Window:
    """:func:`branch_window` at drop position ``x`` and ``n`` edges, other parameters from
    ``template`` (e.g. :func:`~elastocap.strip.discrete.discrete_strip_for` of a scene)."""
    d0 = kw.get("d_start_open", 0.6)
    return branch_window(template.with_(n=int(n), x_end=float(x), delta=d0), **kw)
