"""Declared, typed, documented module parameters, validated by pydantic before anything starts.

A module declares its parameters as a nested class::

    class Params(Parameters):
        gain: float = param(1.0, "scale applied to the input", unit="1", ge=-100, le=100)
        mode: Literal["grow", "collapse"] = param("grow", "how the snake is seeded")

``param`` takes the default, a one-line doc, an optional unit and pydantic's constraints
(``ge``, ``gt``, ``le``, ``lt``, ``min_length``...). Choices are ``Literal`` types. A list whose
every value is bounded takes a bounded element type (``list[NonNegative]``, ``list[Channel]``).

The declaration is the whole rule: bounds, lengths, signs and checks across parameters live here
(field constraints and model validators) and nowhere else. ``umbra check``, ``run``, ``--set``,
live tuning and the station all validate through the model, and a module's ``start`` builds
what it needs from validated values without judging them again.
Degrees and millimetres appear only in parameters named so (``roll_tolerance_deg``).

Every float is finite (``.inf``, ``nan``, ``1e999``, ``Infinity`` are rejected, in lists too)
unless its declaration says ``allow_inf_nan=True``. A number is never a boolean: ``timeout: true``
or ``max_linear: yes`` is an error, not 1.0 (pydantic alone would take ``true`` for 1).
A check across parameters raises :class:`ParamProblem` naming the parameter at fault, so
``umbra check`` points at its line.
A module whose safety depends on its rate overrides :meth:`Parameters.rate_problem`.
A file the module writes is declared ``RunFile``: a path inside the run folder (or empty: none).

A parameter a viewer may change while the graph runs is declared ``tunable=True`` (``umbra run
--foxglove``: validated exactly as ``--set`` is, by this model, and applied between steps). One
that bounds what reaches the arm (speeds, clamps, timeouts, origin ages, joint limits) is declared
``safety=True`` and can never be tunable: declaring both is an error when the class is defined,
as is any tunable parameter of a safety guard (``Module.SAFETY_GUARD``: every parameter of a
watchdog bounds the arm). Why safety is a mark of its own rather than "not tunable": the mark
says what a parameter *is*, so a later ``tunable=True`` on it fails at import instead of passing
a review.
"""

from __future__ import annotations

import types
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Annotated, Any, Literal, Union, get_args, get_origin

import pydantic
from pydantic import (
    ConfigDict,
    Field,
    ValidationInfo,
    ValidatorFunctionWrapHandler,
    WrapValidator,
)
from pydantic.config import JsonDict
from pydantic.fields import FieldInfo

from umbra.connectors.user_files import OnCommandLine, run_file_problem


class Parameters(pydantic.BaseModel):
    """Base class of every module's ``Params``: unknown names are errors; values are frozen."""

    model_config = ConfigDict(
        extra="forbid", frozen=True, arbitrary_types_allowed=True, allow_inf_nan=False
    )

    @pydantic.field_validator("*", mode="before")
    @classmethod
    def _numbers_are_not_booleans(cls, value: Any, info: ValidationInfo) -> Any:
        """``true``/``false`` where the declaration wants a number is a mistake, not 1 or 0."""
        field = cls.model_fields.get(info.field_name or "")
        if field is not None and _boolean_for_number(value, field.annotation):
            raise ValueError("expected a number, found a boolean (true/false)")
        return value

    def required_frames(self) -> list[tuple[str, str]]:
        """``(parent, child)`` pairs the graph's static frames must join for the module to start
        (``umbra check`` reports the missing ones); none by default."""
        return []

    @classmethod
    def __pydantic_init_subclass__(cls, **kwargs: Any) -> None:
        super().__pydantic_init_subclass__(**kwargs)
        both = [n for n in cls.model_fields if is_tunable(cls, n) and is_safety(cls, n)]
        if both:
            raise TypeError(
                f"{cls.__qualname__}: parameter `{both[0]}` is declared safety and tunable; "
                "a safety parameter is never changed while the graph runs"
            )

    def rate_problem(self, rate_hz: float | None) -> str:
        """Why the module cannot work at graph ``rate`` ``rate_hz`` [Hz] (None: triggered only);
        empty when it can. A watchdog says so when it would tick slower than its timeout."""
        return ""


def _inside_run_folder(value: Any, handler: ValidatorFunctionWrapHandler) -> str:
    path: str = handler(value)
    why = run_file_problem(OnCommandLine(path) if isinstance(value, OnCommandLine) else path)
    if path and why:
        raise ValueError(f"path {path!r} {why}")
    return path


#: A file a module writes, relative to the run's output folder; empty: no file. A path the user
#: typed on the command line may lie outside it (``umbra.connectors.user_files``).
RunFile = Annotated[str, WrapValidator(_inside_run_folder)]

#: Element types with bounds, for lists whose every value is bounded (``list[NonNegative]``):
#: the declaration then holds the sign of each value, and ``umbra describe`` shows it.
NonNegative = Annotated[float, Field(ge=0)]
Positive = Annotated[float, Field(gt=0)]
#: A color channel, 0..255.
Channel = Annotated[int, Field(ge=0, le=255)]


def _boolean_for_number(value: Any, annotation: Any) -> bool:
    """Whether ``value`` holds a boolean where ``annotation`` wants an int or a float (in
    lists, tuples and mapping values too)."""
    origin = get_origin(annotation)
    if annotation in (int, float):
        return isinstance(value, bool)
    if origin is Annotated:
        return _boolean_for_number(value, get_args(annotation)[0])
    if origin in (Union, types.UnionType):
        members = get_args(annotation)
        if bool in members or Any in members:
            return False
        return any(_boolean_for_number(value, m) for m in members)
    args = get_args(annotation)
    if origin in (list, set, frozenset) and args and isinstance(value, list | tuple | set):
        return any(_boolean_for_number(v, args[0]) for v in value)
    if origin is tuple and args and isinstance(value, list | tuple):
        if len(args) == 2 and args[1] is Ellipsis:
            return any(_boolean_for_number(v, args[0]) for v in value)
        return any(_boolean_for_number(v, a) for v, a in zip(value, args, strict=False))
    if origin is dict and len(args) == 2 and isinstance(value, Mapping):
        return any(_boolean_for_number(v, args[1]) for v in value.values())
    return False


class ParamProblem(ValueError):
    """A problem of parameter ``field`` found by a check across parameters (a model validator):
    ``umbra check`` reports it at that parameter's line."""

    def __init__(self, field: str, message: str) -> None:
        super().__init__(f"{field} {message}")
        self.field = field


def param(
    default: Any,
    doc: str,
    *,
    unit: str = "",
    tunable: bool = False,
    safety: bool = False,
    **constraints: Any,
) -> Any:
    """Declare a parameter: ``default``, one-line ``doc``, ``unit``, whether it may be changed
    while the graph runs (``tunable``) or bounds what reaches the arm (``safety``: never tunable),
    and pydantic constraints."""
    marks: JsonDict = {"unit": unit, "tunable": tunable, "safety": safety}
    extra: JsonDict | None = {k: v for k, v in marks.items() if v} or None
    if isinstance(default, list | dict | set):
        frozen_default = default
        return Field(
            default_factory=lambda: type(frozen_default)(frozen_default),
            description=doc,
            json_schema_extra=extra,
            **constraints,
        )
    return Field(default, description=doc, json_schema_extra=extra, **constraints)


def _marks(params_cls: type[Parameters], name: str) -> dict[str, Any]:
    field = params_cls.model_fields.get(name)
    extra = field.json_schema_extra if field is not None else None
    return extra if isinstance(extra, dict) else {}


def is_tunable(params_cls: type[Parameters], name: str) -> bool:
    """Whether parameter ``name`` is declared ``tunable``."""
    return bool(_marks(params_cls, name).get("tunable"))


def is_safety(params_cls: type[Parameters], name: str) -> bool:
    """Whether parameter ``name`` is declared ``safety``."""
    return bool(_marks(params_cls, name).get("safety"))


def with_change(params: Parameters, name: str, value: Any) -> Parameters:
    """``params`` with ``name`` set to ``value``, validated by the same model as the graph file
    and ``--set`` (bounds, types, checks across parameters); ``ValueError`` with one plain
    sentence per problem."""
    cls = type(params)
    values = {key: getattr(params, key) for key in cls.model_fields}
    values[name] = value
    try:
        return cls(**values)
    except pydantic.ValidationError as exc:
        raise ValueError("; ".join(validation_problems(cls, exc))) from None
    except (TypeError, ValueError) as exc:  # a module's own validator
        raise ValueError(str(exc)) from None


@dataclass(frozen=True)
class ParamInfo:
    """What ``umbra describe`` shows of one parameter."""

    name: str
    type: str
    default: Any
    """The default value; meaningless when ``required`` (the user must give one)."""
    unit: str
    doc: str
    constraints: str
    required: bool = False


def describe_params(params_cls: type[Parameters]) -> list[ParamInfo]:
    """Parameter declarations of ``params_cls`` in declaration order."""
    out: list[ParamInfo] = []
    for name, field in params_cls.model_fields.items():
        extra = field.json_schema_extra if isinstance(field.json_schema_extra, dict) else {}
        required = field.is_required()
        default = None if required else field.get_default(call_default_factory=True)
        constraints = _bounds_text(field)
        out.append(
            ParamInfo(
                name=name,
                type=_type_name(field.annotation),
                default=default,
                unit=str(extra.get("unit", "")),
                doc=field.description or "",
                constraints=constraints,
                required=required,
            )
        )
    return out


def validation_problems(params_cls: type[Parameters], exc: pydantic.ValidationError) -> list[str]:
    """One plain sentence per problem of a failed ``params_cls(**values)``, each naming the
    parameter (no pydantic jargon, no URLs): for messages outside a graph file (the harness)."""
    problems = []
    for err in exc.errors():
        loc = err.get("loc") or ()
        name = ".".join(str(part) for part in loc)
        cause = (err.get("ctx") or {}).get("error")
        if err["type"] == "missing":
            problems.append(f"parameter `{name}` is required and was not given")
        elif err["type"] == "extra_forbidden":
            known = ", ".join(params_cls.model_fields) or "none"
            problems.append(f"unknown parameter `{name}` (parameters: {known})")
        elif isinstance(cause, ParamProblem):
            problems.append(
                f"parameter `{cause.field}` {str(cause).removeprefix(cause.field + ' ')}"
            )
        elif cause is not None:
            problems.append(f"parameter `{name}`: {cause}")
        else:
            problems.append(
                f"parameter `{name}`: {err['msg']}, found {short_repr(err.get('input'))}"
            )
    return problems


def short_repr(value: Any) -> str:
    """``repr(value)`` cut to 120 characters (a 5000-digit number is not printed whole)."""
    try:
        text = repr(value)
    except ValueError:  # an int too long for repr
        return "a number too long to print"
    return text if len(text) <= 120 else text[:117] + "..."


@dataclass(frozen=True)
class Bounds:
    """The bounds a declaration puts on a value (``ge``, ``gt``, ``le``, ``lt``) and on a list's
    length (``min_length``, ``max_length``); None: unbounded."""

    ge: float | None = None
    gt: float | None = None
    le: float | None = None
    lt: float | None = None
    min_length: int | None = None
    max_length: int | None = None

    @classmethod
    def of(cls, metadata: list[Any]) -> Bounds:
        """The bounds found in pydantic metadata (a field's, or an ``Annotated`` type's)."""
        found: dict[str, Any] = {}
        flat: list[Any] = []
        for meta in metadata:  # an element's ``Field(...)`` holds its bounds in its metadata
            flat.extend(meta.metadata if isinstance(meta, FieldInfo) else [meta])
        for meta in flat:
            for key in ("ge", "gt", "le", "lt", "min_length", "max_length"):
                value = getattr(meta, key, None)
                if value is not None:
                    found[key] = value
        return cls(**found)

    def text(self) -> str:
        """As ``umbra describe`` shows them: ``in (0, 1]``, ``>= 0``, ``length 3``."""
        parts = []
        low = self.ge if self.ge is not None else self.gt
        high = self.le if self.le is not None else self.lt
        if low is not None and high is not None:
            left, right = "[" if self.ge is not None else "(", "]" if self.le is not None else ")"
            parts.append(f"in {left}{low:g}, {high:g}{right}")
        elif low is not None:
            parts.append(f"{'>=' if self.ge is not None else '>'} {low:g}")
        elif high is not None:
            parts.append(f"{'<=' if self.le is not None else '<'} {high:g}")
        lengths = (self.min_length, self.max_length)
        if lengths[0] is not None and lengths[0] == lengths[1]:
            parts.append(f"length {lengths[0]}")
        elif lengths != (None, None):
            parts.append(f"length {lengths[0] or 0}..{'' if lengths[1] is None else lengths[1]}")
        return ", ".join(parts)


def element_bounds(annotation: Any) -> Bounds | None:
    """The bounds on each element of a list or tuple declared ``list[Annotated[T, Field(...)]]``
    (the aliases below); None when the annotation bounds no element."""
    if get_origin(annotation) in (Union, types.UnionType):
        found = [element_bounds(a) for a in get_args(annotation) if a is not type(None)]
        return next((b for b in found if b is not None), None)
    args = get_args(annotation)
    if get_origin(annotation) not in (list, tuple) or not args:
        return None
    item = args[0]
    if get_origin(item) is not Annotated:
        return None
    bounds = Bounds.of(list(get_args(item)[1:]))
    return bounds if bounds != Bounds() else None


def _bounds_text(field: FieldInfo) -> str:
    """A field's bounds, and its elements' (``each in [0, 255]``), as ``umbra describe`` shows."""
    parts = [Bounds.of(field.metadata).text()]
    each = element_bounds(field.annotation)
    if each is not None:
        parts.append(f"each {each.text()}")
    return ", ".join(p for p in parts if p)


def _type_name(annotation: Any) -> str:
    """A declaration's type as ``umbra describe`` shows it: ``list[float] | None``,
    ``one of a|b`` (element bounds are shown with the bounds, not in the type)."""
    origin = get_origin(annotation)
    if origin is Annotated:
        return _type_name(get_args(annotation)[0])
    if origin is Literal:
        return "one of " + "|".join(str(a) for a in get_args(annotation))
    if origin in (Union, types.UnionType):
        return " | ".join(_type_name(a) for a in get_args(annotation))
    if origin is not None:
        name = getattr(origin, "__name__", repr(origin))
        return f"{name}[{', '.join(_type_name(a) for a in get_args(annotation))}]"
    if annotation is type(None):
        return "None"
    text = getattr(annotation, "__name__", None) or repr(annotation)
    return text.replace("typing.", "")
