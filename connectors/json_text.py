"""JSON that every parser reads: what umbra writes as JSON (run summaries, ``--json`` lines).

Python's ``json`` writes a float that is not a number as ``NaN`` or ``Infinity``, which the JSON
standard (RFC 8259) has not: JavaScript's ``JSON.parse``, ``jq`` and strict decoders refuse the
whole document. Here such a value is written ``null`` (a measurement that was not made: a grasp
that did not happen, an arm that never moved), numpy values as plain numbers and lists.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from typing import Any

import numpy as np


def finite(value: Any) -> Any:
    """``value`` with every float that is not finite replaced by None, through dicts, lists and
    tuples (as lists), numpy arrays (as lists) and numpy scalars (as Python numbers)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [finite(v) for v in value]
    if isinstance(value, np.ndarray):
        return finite(value.tolist())
    if isinstance(value, np.generic):
        return finite(value.item())
    return value


def json_text(
    value: Any, indent: int | None = None, default: Callable[[Any], Any] | None = None
) -> str:
    """``value`` as standard JSON (:func:`finite` first; ``default`` as :func:`json.dumps`'s,
    for what is neither of those, and its result made finite too)."""

    def fallback(obj: Any) -> Any:
        if default is None:
            raise TypeError(f"{type(obj).__name__} is not JSON")
        return finite(default(obj))

    return json.dumps(finite(value), indent=indent, default=fallback, allow_nan=False)
