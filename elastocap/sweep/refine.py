"""Boundary analysis along one line of a phase diagram (fixed x, increasing We^1/2 or Delta).

The paper (Fig 3d) finds, for each x, one critical We^1/2 below which the strip stays open
and above which it is encapsulated. :func:`classify_line` checks that from the outcomes
actually computed instead of assuming it: a line whose outcomes change more than once, or
from encapsulated to open, is reported "non-monotonic" with every change bracketed, and
each change is then refined on its own (bisection never crosses another change it cannot
see, so a single bracket between the largest open and the smallest encapsulated value
would be meaningless there).

Three outcome classes: "open", "encapsulated" and "undecided" (a run the engine could not
decide, with its reason). An undecided run is a class of its own: a change to or from it
is a transition like any other (bisected like any other), and a line with an undecided run
is never reported as decided ("undecided"; ``decided_status`` says what its decided runs
alone show). A line with a run that failed (no result) is "failed", never "all-open".
"""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["Boundary", "CLASSES", "Transition", "classify_line", "decided_status",
           "first_threshold"]

OPEN, ENC, UND = "open", "encapsulated", "undecided"
CLASSES = (OPEN, ENC, UND)


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
        the smallest encapsulated value), "all-open", "all-encapsulated", "all-undecided",
        "non-monotonic" (see ``transitions``; ``low`` / ``high`` None), "undecided" (some
        runs undecided), "failed" (some runs have no result), or "no-runs".
    decided_status : str
        The status the decided (open / encapsulated) runs alone give; equal to ``status``
        on a line without undecided or failed runs.
    low, high : float or None
        The bracket of the decided runs when they change once from open to encapsulated
        (for all-open: ``low`` = the largest value run; for all-encapsulated: ``high`` =
        the smallest).
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
    level, n_edges, dt : int, int or None, float or None
        The resolution level of the bracket (0: the sweep's; k: 1.5^k the edges) and its
        discretization.
    undecided : list of dict
        The undecided runs on the line at that level (``value``, ``reason``).
    failed : list of float
        Values of the line whose runs failed (no result) at that level.
    verification : dict or None
        What ``--verify`` found (None: not verified); see :mod:`elastocap.sweep.engine`.
    verified : bool or None
        The threshold bracket was re-run at the next finer level and holds (None: not
        checked).
    threshold_low, threshold_high : float or None
        The line's *threshold*: its first outcome change when that change is from open
        (every run below it open; :func:`first_threshold`): the smallest impact that does
        not stay open. Equal to ``low`` / ``high`` on a bracketed line; also defined where
        the line changes again above it (undecided runs, a flip back to open). None
        otherwise, and on a line with a failed run. This is the bracket that verification
        checks.
    threshold_to : str or None
        What the line turns into at its threshold: "encapsulated" (the paper's boundary)
        or "undecided" (the first impact that leaves open cannot be decided, e.g. the rod
        crossed itself).
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
    decided_status: str = ""
    level: int = 0
    n_edges: int | None = None
    dt: float | None = None
    undecided: list[dict] = field(default_factory=list)
    failed: list[float] = field(default_factory=list)
    verification: dict | None = None
    verified: bool | None = None
    threshold_low: float | None = None
    threshold_high: float | None = None
    threshold_to: str | None = None

    def to_dict(self) -> dict:
        d = dict(vars(self))
        d["transitions"] = [t.to_dict() for t in self.transitions]
        d["notes"] = list(self.notes)
        d["undecided"] = [dict(u) for u in self.undecided]
        d["failed"] = list(self.failed)
        return d


def _status(pairs) -> tuple[str, list[Transition]]:
    trans = [
        Transition(a, b, oa, ob)
        for (a, oa), (b, ob) in zip(pairs[:-1], pairs[1:], strict=True)
        if oa != ob
    ]
    if any(t.low == t.high for t in trans):
        t = next(t for t in trans if t.low == t.high)
        raise ValueError(f"value {t.low!r} has two different outcomes")
    if not pairs:
        return "no-runs", []
    if not trans:
        return "all-" + pairs[0][1], []
    if any(o == UND for _, o in pairs):
        return "undecided", trans
    if len(trans) == 1 and trans[0].outcome_low == OPEN:
        return "bracketed", trans
    return "non-monotonic", trans


def classify_line(values, outcomes) -> tuple[str, list[Transition]]:
    """Status and outcome changes of one line from its computed (value, outcome) pairs.

    Parameters
    ----------
    values : sequence of float
        Values of the line variable (any order; duplicates must agree).
    outcomes : sequence of str
        "open", "encapsulated" or "undecided", one per value.

    Returns
    -------
    status : str
        "no-runs", "all-open", "all-encapsulated", "all-undecided", "undecided" (some runs
        undecided, some not), "bracketed" (exactly one change, open to encapsulated) or
        "non-monotonic" (several changes, or one from encapsulated to open).
    transitions : list of Transition
        Adjacent computed values with different outcomes (undecided included), in
        increasing value.
    """
    pairs = sorted(zip(values, outcomes, strict=True))
    for v, o in pairs:
        if o not in CLASSES:
            raise ValueError(
                f"outcome: got {o!r} at {v!r}; expected 'open', 'encapsulated' or 'undecided'")
    return _status(pairs)


def first_threshold(transitions) -> Transition | None:
    """The first of a line's outcome changes (increasing value) if it starts from open,
    else None: every run below it is open, so it brackets the smallest impact that does
    not stay open (``outcome_high``: encapsulated, or undecided), whatever the line does
    above it."""
    if transitions and transitions[0].outcome_low == OPEN:
        return transitions[0]
    return None


def decided_status(values, outcomes) -> str:
    """:func:`classify_line`'s status of the decided (open / encapsulated) runs alone."""
    return classify_line(*_decided(values, outcomes))[0]


def _decided(values, outcomes):
    keep = [(v, o) for v, o in zip(values, outcomes, strict=True) if o != UND]
    return [v for v, _ in keep], [o for _, o in keep]
