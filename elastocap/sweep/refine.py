"""Boundary analysis along one line of a phase diagram (fixed x, increasing We^1/2 or Delta).

The paper (Fig 3d) finds, for each x, one critical We^1/2 below which the strip stays open
and above which it is encapsulated. :func:`classify_line` checks that from the outcomes
actually computed instead of assuming it: a line whose outcomes change more than once, or
from encapsulated to open, is reported "non-monotonic" with every change bracketed, and
each change is then refined on its own (bisection never crosses another change it cannot
see, so a single bracket between the largest open and the smallest encapsulated value
would be meaningless there).
"""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["Boundary", "Transition", "classify_line"]

OPEN, ENC = "open", "encapsulated"


@dataclass
class Transition:
    """An outcome change between two computed values of the line variable (low < high)."""

    low: float
    high: float
    outcome_low: str
    outcome_high: str

    @property
    def width(self) -> float:
        return self.high - self.low

    def to_dict(self) -> dict:
        return dict(vars(self))


@dataclass
class Boundary:
    """The encapsulation boundary on the line x = const.

    Attributes
    ----------
    x_over_leg, x : float
        The line (sweep units, scene units).
    variable : str
        "we_sqrt" or "wetted_length": what ``low`` / ``high`` are in.
    status : str
        "bracketed" (one open -> encapsulated change; ``low`` the largest open and ``high``
        the smallest encapsulated value), "all-open", "all-encapsulated", "non-monotonic"
        (see ``transitions``; ``low`` / ``high`` None), or "no-runs".
    low, high : float or None
        The bracket (for all-open: ``low`` = the largest value run; for all-encapsulated:
        ``high`` = the smallest).
    transitions : list of Transition
        Every outcome change found along the line, refined.
    tolerance : float or None
        Requested bracket width (None: no refinement).
    converged : bool
        Every transition is narrower than ``tolerance``.
    refinement_runs : int
        Runs added by bisection on this line.
    we_sqrt_low, we_sqrt_high, wetted_length_low, wetted_length_high : float or None
        ``low`` / ``high`` in both variables (None where the scene has no spreading law).
    notes : list of str
        Anything that stopped a bisection early (a failed run).
    """

    x_over_leg: float
    x: float
    variable: str
    status: str
    low: float | None = None
    high: float | None = None
    transitions: list[Transition] = field(default_factory=list)
    tolerance: float | None = None
    converged: bool = False
    refinement_runs: int = 0
    notes: list[str] = field(default_factory=list)
    we_sqrt_low: float | None = None
    we_sqrt_high: float | None = None
    wetted_length_low: float | None = None
    wetted_length_high: float | None = None

    def to_dict(self) -> dict:
        d = dict(vars(self))
        d["transitions"] = [t.to_dict() for t in self.transitions]
        d["notes"] = list(self.notes)
        return d


def classify_line(values, outcomes) -> tuple[str, list[Transition]]:
    """Status and outcome changes of one line from its computed (value, outcome) pairs.

    Parameters
    ----------
    values : sequence of float
        Values of the line variable (any order; duplicates must agree).
    outcomes : sequence of str
        "open" or "encapsulated", one per value.

    Returns
    -------
    status : str
        "no-runs", "all-open", "all-encapsulated", "bracketed" (exactly one change, open to
        encapsulated) or "non-monotonic" (several changes, or one from encapsulated to open).
    transitions : list of Transition
        Adjacent computed values with different outcomes, in increasing value.
    """
    pairs = sorted(zip(values, outcomes, strict=True))
    for v, o in pairs:
        if o not in (OPEN, ENC):
            raise ValueError(f"outcome: got {o!r} at {v!r}; expected 'open' or 'encapsulated'")
    if not pairs:
        return "no-runs", []
    trans = [
        Transition(a, b, oa, ob)
        for (a, oa), (b, ob) in zip(pairs[:-1], pairs[1:], strict=True)
        if oa != ob
    ]
    if any(t.low == t.high for t in trans):
        t = next(t for t in trans if t.low == t.high)
        raise ValueError(f"value {t.low!r} has two different outcomes")
    if not trans:
        return ("all-open" if pairs[0][1] == OPEN else "all-encapsulated"), []
    if len(trans) == 1 and trans[0].outcome_low == OPEN:
        return "bracketed", trans
    return "non-monotonic", trans
