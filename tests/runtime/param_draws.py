"""Values for a declared parameter, drawn from its own declaration: inside its bounds, just
outside them, with a wrong length, a wrong sign, a wrong type (for the tests that prove a
``Params`` declaration is the whole rule of its module)."""

from __future__ import annotations

import json
import math
import types
from typing import Any, Literal, Union, get_args, get_origin

from hypothesis import strategies as st
from pydantic.fields import FieldInfo

from umbra.connectors.params import Bounds, element_bounds

#: The largest magnitude drawn where a declaration gives no bound.
SPAN = 1e4


def _strip(annotation: Any) -> tuple[Any, bool]:
    """``(annotation without None, whether None is allowed)``."""
    if get_origin(annotation) in (Union, types.UnionType):
        members = [a for a in get_args(annotation) if a is not type(None)]
        return (members[0] if len(members) == 1 else annotation), len(members) < len(
            get_args(annotation)
        )
    return annotation, False


def _base(annotation: Any) -> Any:
    """``int`` / ``float`` / ... under ``Annotated``."""
    while get_origin(annotation) is not None and hasattr(annotation, "__metadata__"):
        annotation = get_args(annotation)[0]
    return annotation


def numbers(kind: type, bounds: Bounds) -> st.SearchStrategy[Any]:
    """Numbers inside ``bounds``."""
    low = bounds.ge if bounds.ge is not None else bounds.gt
    high = bounds.le if bounds.le is not None else bounds.lt
    low = -SPAN if low is None else float(low)
    high = SPAN if high is None else float(high)
    if kind is int:
        lo = math.ceil(low) + (1 if bounds.gt is not None and float(bounds.gt).is_integer() else 0)
        hi = math.floor(high) - (
            1 if bounds.lt is not None and float(bounds.lt).is_integer() else 0
        )
        return st.integers(lo, hi)
    return st.floats(
        low,
        high,
        exclude_min=bounds.gt is not None,
        exclude_max=bounds.lt is not None,
        allow_nan=False,
        allow_infinity=False,
    )


def outside(kind: type, bounds: Bounds) -> list[Any]:
    """The values just outside ``bounds`` (none when unbounded)."""
    found: list[Any] = []
    step = (lambda b, d: b + d) if kind is int else (lambda b, d: math.nextafter(b, d * math.inf))
    if bounds.ge is not None:
        found.append(step(bounds.ge, -1))
    if bounds.gt is not None:
        found.append(bounds.gt)
    if bounds.le is not None:
        found.append(step(bounds.le, 1))
    if bounds.lt is not None:
        found.append(bounds.lt)
    if kind is int:
        found = [int(v) if float(v).is_integer() else v for v in found]
    return found


def draws(field: FieldInfo, keep: bool = False) -> st.SearchStrategy[Any]:
    """Values for ``field``: inside and just outside its bounds, wrong lengths, wrong signs and
    wrong types. ``keep``: its default stands for every value inside (a port, a file)."""
    annotation, optional = _strip(field.annotation)
    default = field.get_default(call_default_factory=True)
    inside: list[st.SearchStrategy[Any]] = [st.just(default)]
    bad: list[Any] = []
    if optional:
        inside.append(st.none())
    kind = _base(annotation)
    origin = get_origin(annotation)
    if get_origin(kind) is Literal:
        inside.append(st.sampled_from(get_args(kind)))
        bad += ["not-a-choice", [1]]
    elif kind is bool:
        inside.append(st.booleans())
        bad += [[1], 2.5]
    elif kind in (int, float):
        bounds = Bounds.of(field.metadata)
        if not keep:
            inside.append(numbers(kind, bounds))
        bad += [*outside(kind, bounds), "fast", True, [1.0]]
        if kind is int:
            bad.append(1.5)
    elif origin in (list, tuple) and get_args(annotation):
        item = _base(get_args(annotation)[0])
        lengths = Bounds.of(field.metadata)
        each = element_bounds(annotation) or Bounds()
        low = lengths.min_length or 0
        given = list(default or [])
        high = lengths.max_length if lengths.max_length is not None else max(low, len(given)) + 2
        if item in (int, float):
            inside.append(st.lists(numbers(item, each), min_size=low, max_size=high))
            sample = given or [item(1)] * max(low, 1)
            bad += [[*sample[:-1], v] for v in outside(item, each)]
            bad += [[*sample[:-1], "x"], "x"]
        else:
            bad += [[1.5], "x"] if item is str else ["x"]
        if low > 0:
            bad.append([item(1) if item in (int, float) else "a"] * (low - 1))
        if lengths.max_length is not None:
            bad.append([item(1) if item in (int, float) else "a"] * (lengths.max_length + 1))
    elif kind is str:
        bad += [[1], 12.5]
    elif origin is dict:
        bad += [[1], "x"]
    return st.one_of(*inside, st.sampled_from(bad)) if bad else st.one_of(*inside)


def yaml_value(value: Any) -> str:
    """``value`` written so the graph loader reads it back as the same value (YAML 1.1 wants a
    dot in a float written with an exponent)."""
    if isinstance(value, float):
        text = repr(value)
        if "e" in text and "." not in text.split("e")[0]:
            mantissa, exponent = text.split("e")
            sign = "" if exponent[0] in "+-" else "+"
            text = f"{mantissa}.0e{sign}{exponent}"
        return text
    if isinstance(value, list | tuple):
        return "[" + ", ".join(yaml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{json.dumps(k)}: {yaml_value(v)}" for k, v in value.items()) + "}"
    return json.dumps(value)
