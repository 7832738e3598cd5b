"""Declared, typed, documented module parameters, validated by pydantic before anything starts.

A module declares its parameters as a nested class::

    class Params(Parameters):
        gain: float = param(1.0, "scale applied to the input", unit="1", ge=-100, le=100)
        mode: Literal["grow", "collapse"] = param("grow", "how the snake is seeded")

``param`` takes the default, a one-line doc, an optional unit and pydantic's constraints
(``ge``, ``gt``, ``le``, ``lt``, ``min_length``...). Choices are ``Literal`` types.
Degrees and millimetres appear only in parameters named so (``roll_tolerance_deg``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal, get_args, get_origin

import pydantic
from pydantic import ConfigDict, Field


class Parameters(pydantic.BaseModel):
    """Base class of every module's ``Params``: unknown names are errors; values are frozen."""

    model_config = ConfigDict(extra="forbid", frozen=True, arbitrary_types_allowed=True)


def param(default: Any, doc: str, *, unit: str = "", **constraints: Any) -> Any:
    """Declare a parameter: ``default``, one-line ``doc``, ``unit`` and pydantic constraints."""
    extra = {"unit": unit} if unit else None
    if isinstance(default, list | dict | set):
        frozen_default = default
        return Field(
            default_factory=lambda: type(frozen_default)(frozen_default),
            description=doc,
            json_schema_extra=extra,
            **constraints,
        )
    return Field(default, description=doc, json_schema_extra=extra, **constraints)


@dataclass(frozen=True)
class ParamInfo:
    """What ``umbra describe`` shows of one parameter."""

    name: str
    type: str
    default: Any
    unit: str
    doc: str
    constraints: str


def describe_params(params_cls: type[Parameters]) -> list[ParamInfo]:
    """Parameter declarations of ``params_cls`` in declaration order."""
    out: list[ParamInfo] = []
    for name, field in params_cls.model_fields.items():
        extra = field.json_schema_extra if isinstance(field.json_schema_extra, dict) else {}
        default = field.get_default(call_default_factory=True)
        constraints = []
        for meta in field.metadata:
            for key in ("ge", "gt", "le", "lt", "min_length", "max_length"):
                value = getattr(meta, key, None)
                if value is not None:
                    constraints.append(f"{key}={value}")
        out.append(
            ParamInfo(
                name=name,
                type=_type_name(field.annotation),
                default=default,
                unit=str(extra.get("unit", "")),
                doc=field.description or "",
                constraints=" ".join(constraints),
            )
        )
    return out


def _type_name(annotation: Any) -> str:
    if get_origin(annotation) is Literal:
        return "one of " + "|".join(str(a) for a in get_args(annotation))
    if get_origin(annotation) is not None:
        return repr(annotation).replace("typing.", "")
    text = getattr(annotation, "__name__", None) or repr(annotation)
    return text.replace("typing.", "")
