"""Plain JSON for results: numpy scalars to Python, non-finite floats to ``null``.

JSON has no NaN or inf, and a number written as a string ("nan") is a trap for every
reader. :func:`jsonable` writes every non-finite float as ``null``: for a quantity that
could not be computed (NaN) it means *unknown*, and where the field's documentation says
so an infinite bound (a range open at one end, a step limit that is off) reads *unlimited*.
Loaders map ``null`` back to the documented value (e.g.
:meth:`continuation.ContinuationSettings.from_dict`).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["is_finite_number", "jsonable"]


def is_finite_number(v) -> bool:
    """Whether a value read back from JSON is a finite number (not a bool, None or text)."""
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def jsonable(obj):
    """A copy of ``obj`` (dicts, lists, tuples, numbers) that ``json.dumps(...,
    allow_nan=False)`` accepts: numpy scalars and arrays as Python numbers and lists,
    NaN and +-inf as ``None``."""
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj
