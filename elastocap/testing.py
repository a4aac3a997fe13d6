"""Helpers for users' own CI: compare fold points against a reference file.

A reference file is the JSON that ``elastocap folds SCENE --json`` prints (a key ``folds``,
a list of objects with at least ``value``). Two fold lists match when they have the same
number of folds and, sorted by value, each pair agrees within ``rtol`` (relative, on the
parameter value).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

__all__ = ["FoldMismatch", "assert_folds", "compare_folds", "load_folds"]

#: Default relative tolerance: the default accuracy gives folds to ~1e-12; 1e-8 leaves room
#: for another machine's round-off and a coarser preset while catching any real change.
DEFAULT_RTOL = 1e-8


class FoldMismatch(AssertionError):
    """Raised by :func:`assert_folds`; the message is the comparison table."""


def load_folds(path) -> list[dict]:
    """Read the ``folds`` list of a JSON file (as written by ``elastocap folds --json``)."""
    p = Path(path)
    try:
        data = json.loads(p.read_text())
    except FileNotFoundError:
        raise ValueError(f"--check: got {str(path)!r}; no such file") from None
    except json.JSONDecodeError as err:
        raise ValueError(f"--check: got {str(path)!r}; not valid JSON ({err})") from None
    folds = data.get("folds") if isinstance(data, dict) else None
    if not isinstance(folds, list) or not all(
        isinstance(f, dict) and isinstance(f.get("value"), int | float) for f in folds
    ):
        raise ValueError(
            f"--check: got {str(path)!r}; expected a JSON object with a key 'folds': a list "
            "of objects each with a numeric 'value' (the output of `elastocap folds --json`)"
        )
    return folds


def compare_folds(found, expected, rtol=DEFAULT_RTOL) -> tuple[bool, str]:
    """Compare two fold lists. Returns (match, table) where table is printable text."""
    f = sorted(float(x["value"]) for x in found)
    e = sorted(float(x["value"]) for x in expected)
    n = max(len(f), len(e))
    lines = [f"{'#':>3}  {'expected':>20}  {'found':>20}  {'rel. diff':>10}  status"]
    ok = len(f) == len(e)
    for k in range(n):
        ev = e[k] if k < len(e) else math.nan
        fv = f[k] if k < len(f) else math.nan
        rel = abs(fv - ev) / max(abs(ev), 1e-300) if k < len(e) and k < len(f) else math.nan
        good = math.isfinite(rel) and rel <= rtol
        ok &= good
        lines.append(
            f"{k:>3}  {ev:>20.12g}  {fv:>20.12g}  {rel:>10.2e}  {'ok' if good else 'MISMATCH'}"
        )
    lines.append(
        f"{'all folds match' if ok else 'folds differ'} (rtol={rtol:g}; expected "
        f"{len(e)}, found {len(f)})"
    )
    return ok, "\n".join(lines)


def assert_folds(found, expected, rtol=DEFAULT_RTOL) -> None:
    """pytest helper: raise :class:`FoldMismatch` with the table unless the folds match.

    Parameters
    ----------
    found : list of dict, or a BranchSet
        e.g. ``elastocap.find_folds(scene)``.
    expected : list of dict, or a path to a reference JSON file
    """
    if hasattr(found, "folds"):
        found = found.folds
    if isinstance(expected, str | Path):
        expected = load_folds(expected)
    ok, table = compare_folds(found, expected, rtol)
    if not ok:
        raise FoldMismatch("\n" + table)
