"""Plain JSON for results: numpy scalars to Python, non-finite floats to strings.

JSON has no NaN or inf; writing them as the strings "nan", "inf" keeps every output file
valid JSON that any reader parses, and says what the value was.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["jsonable"]


def jsonable(obj):
    """A copy of ``obj`` (dicts, lists, tuples, numbers) that ``json.dumps`` accepts."""
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return str(obj)
    return obj
