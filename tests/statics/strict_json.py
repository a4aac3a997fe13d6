"""Strict reading of the JSON the statics writes: numbers are numbers or null.

``loads`` refuses the non-standard constants NaN, Infinity and -Infinity (which
``json.dumps`` writes by default), and :func:`string_numbers` lists every string leaf
that spells a number ("nan", "inf", "3.5"): a number written as a string.
"""

import json


def _refuse(name):
    raise ValueError(f"non-standard JSON constant {name} (JSON numbers are numbers or null)")


def loads(text):
    return json.loads(text, parse_constant=_refuse)


def string_numbers(obj, path="$"):
    """The paths of every string leaf that ``float()`` reads as a number (version strings
    such as "1.1", under a key ending in ``version``, are names, not numbers)."""
    if isinstance(obj, dict):
        for k, v in obj.items():
            if not (str(k).endswith("version") and isinstance(v, str)):
                yield from string_numbers(v, f"{path}.{k}")
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            yield from string_numbers(v, f"{path}[{i}]")
    elif isinstance(obj, str):
        try:
            float(obj)
        except ValueError:
            return
        yield f"{path} = {obj!r}"


def check(text):
    """Parse ``text`` strictly; assert no number is a string; return the data."""
    data = loads(text)
    bad = list(string_numbers(data))
    assert bad == [], bad
    return data
