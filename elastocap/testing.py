"""Helpers for users' own CI: compare fold points against a reference file.

A reference file is the JSON that ``elastocap folds SCENE --json`` prints (a key ``folds``,
a list of objects with at least ``value``). Two fold lists match when every expected fold
has a found fold within ``rtol`` (relative, on the parameter value) and no fold is found
that was not expected. An expected fold that the new run could not locate fails with the
reason the run gives.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

__all__ = ["FoldMismatch", "assert_folds", "check_rtol", "compare_folds", "load_folds"]

#: Default relative tolerance: the default accuracy gives folds to ~1e-12; 1e-8 leaves room
#: for another machine's round-off and a coarser preset while catching any real change.
DEFAULT_RTOL = 1e-8


class FoldMismatch(AssertionError):
    """Raised by :func:`assert_folds`; the message is the comparison table."""


def _fold_list(data, origin: str, key: str = "folds") -> list[dict]:
    """The point list of ``data``: a list of point objects, or an object with a key ``key``
    (``folds``: the JSON of ``elastocap folds --json``, or a ``branches.json``; ``cusps``:
    the JSON of ``elastocap folds --curve ... --json``)."""
    folds = data.get(key) if isinstance(data, dict) else data
    if not isinstance(folds, list) or not all(
        isinstance(f, dict)
        and isinstance(f.get("value"), int | float)
        and not isinstance(f.get("value"), bool)
        and math.isfinite(f["value"])
        for f in folds
    ):
        raise ValueError(
            f"{origin}; expected a JSON object with a key '{key}' (the output of "
            "`elastocap folds --json`" + (" --curve ...)" if key != "folds" else ")")
            + " or a list of points (objects each with a finite numeric 'value', as "
            "find_folds returns)"
        )
    return folds


def load_folds(path, option: str = "--check", key: str = "folds",
               made_for: dict | None = None) -> list[dict]:
    """Read the fold list of a JSON file: the output of ``elastocap folds --json``, a
    ``branches.json``, or a saved list of folds (``json.dump(find_folds(scene), f)``).

    ``made_for``: e.g. ``{"scene": "supp-fig5", "parameter": "drop.wetted_length"}``; a file
    that records another value of one of these keys is refused (a reference made for
    another scene or parameter compares folds that have nothing to do with each other)."""
    p = Path(path)
    origin = f"{option}: got {str(path)!r}"
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ValueError(f"{origin}; no such file") from None
    except IsADirectoryError:
        raise ValueError(f"{origin}; this is a folder, expected a JSON file") from None
    except OSError as err:
        raise ValueError(f"{origin}; cannot read the file ({err.strerror})") from None
    except UnicodeDecodeError:
        raise ValueError(f"{origin}; not UTF-8 text (expected a JSON file)") from None
    except (json.JSONDecodeError, RecursionError) as err:
        raise ValueError(f"{origin}; not valid JSON ({err})") from None
    if isinstance(data, dict):
        for k, want in (made_for or {}).items():
            if k in data and data[k] != want:
                raise ValueError(f"{origin}; it was made for {k} {data[k]!r}, this run is "
                                 f"{k} {want!r}: give the reference of this {k}")
    return _fold_list(data, origin, key)


def check_rtol(rtol, option: str = "rtol") -> float:
    """``rtol`` as a float, or ValueError unless it is a finite number > 0."""
    if isinstance(rtol, bool) or not isinstance(rtol, int | float) or not (
            math.isfinite(rtol) and rtol > 0):
        raise ValueError(f"{option}: got {rtol!r}; expected a finite number > 0")
    return float(rtol)


def _unstable_modes(change) -> tuple | str:
    """The unstable-mode counts on the two sides of a fold, ``"1->0"`` -> (0, 1): in either
    order, since a branch traced the other way (another rod length, another seed) reads
    the same fold "0->1"."""
    try:
        return tuple(sorted(int(v) for v in str(change).split("->")))
    except ValueError:
        return str(change)


def compare_folds(found, expected, rtol=DEFAULT_RTOL, unlocated=()) -> tuple[bool, str]:
    """Compare two fold lists. Returns (match, table) where table is printable text.

    Each expected fold is paired with the nearest found one (each found fold used once);
    it matches when their relative difference is at most ``rtol`` and, where both record
    it, the fold joins branches with the same unstable-mode counts (in either direction of
    tracing; else ``STABILITY``). An expected fold with no
    match is reported ``UNLOCATED`` (with the reason) when the new run has an unlocated
    point near it (``unlocated``: the ``unlocated`` list of a branch set), else ``MISSING``
    or ``MISMATCH``; a found fold nobody expected is ``UNEXPECTED``.
    """
    rtol = check_rtol(rtol)
    found = sorted(found, key=lambda x: float(x["value"]))
    expected = sorted(expected, key=lambda x: float(x["value"]))
    f = [float(x["value"]) for x in found]
    e = [float(x["value"]) for x in expected]
    unl = [u for u in unlocated if u.get("kind", "fold") in ("fold", "branch_point")]
    free = list(range(len(f)))
    lines = [f"{'#':>3}  {'expected':>20}  {'found':>20}  {'rel. diff':>10}  status"]
    ok = True
    notes = []
    for k, ev in enumerate(e):
        j = min(free, key=lambda i: abs(f[i] - ev), default=None)
        rel = abs(f[j] - ev) / max(abs(ev), 1e-300) if j is not None else math.nan
        if j is not None and rel <= rtol:
            free.remove(j)
            have, want = found[j].get("stability_change"), expected[k].get("stability_change")
            if want is not None and have is not None and _unstable_modes(have) != \
                    _unstable_modes(want):
                ok = False
                lines.append(f"{k:>3}  {ev:>20.12g}  {f[j]:>20.12g}  {rel:>10.2e}  STABILITY")
                notes.append(f"fold {ev:.12g}: the stability changes {have} in this run, "
                             f"{want} in the reference")
                continue
            lines.append(f"{k:>3}  {ev:>20.12g}  {f[j]:>20.12g}  {rel:>10.2e}  ok")
            continue
        ok = False
        near = [u for u in unl if abs(float(u["value"]) - ev) <= 1e-3 * max(1.0, abs(ev))]
        if near:
            u = near[0]
            lines.append(f"{k:>3}  {ev:>20.12g}  {'(not located)':>20}  {'':>10}  UNLOCATED")
            notes.append(f"expected fold {ev:.12g} is not located in this run: "
                         f"{u.get('reason', '')}; {u.get('what_to_try', '')}")
        elif j is not None and rel <= 1e-3:
            free.remove(j)
            lines.append(f"{k:>3}  {ev:>20.12g}  {f[j]:>20.12g}  {rel:>10.2e}  MISMATCH")
        else:
            lines.append(f"{k:>3}  {ev:>20.12g}  {'-':>20}  {'':>10}  MISSING")
    for i in free:
        ok = False
        lines.append(f"{'+':>3}  {'-':>20}  {f[i]:>20.12g}  {'':>10}  UNEXPECTED")
    lines += notes
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
        e.g. ``elastocap.find_folds(scene)`` (also after a JSON round trip).
    expected : list of dict, a dict with a key ``folds``, a BranchSet, or a path to a JSON
        file holding either (see :func:`load_folds`)
    """
    unlocated = ()
    if hasattr(found, "folds"):
        unlocated = getattr(found, "unlocated", ())
        found = found.folds
    if hasattr(expected, "folds"):
        expected = expected.folds
    if isinstance(expected, str | Path):
        expected = load_folds(expected, "expected")
    found = _fold_list(found, "found")
    expected = _fold_list(expected, "expected")
    ok, table = compare_folds(found, expected, rtol, unlocated)
    if not ok:
        raise FoldMismatch("\n" + table)
