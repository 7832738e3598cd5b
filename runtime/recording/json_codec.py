"""Any message as JSON with a precise JSON schema: samples with no well-known schema.

The object holds every field of the message (``stamp`` [s] and ``seq`` included) under its own
name; a numpy array is a flat list of numbers in row-major order (so a viewer plots
``/servo/twist.vector[2]``; booleans as 0 and 1), and ``_arrays`` gives each array's dtype and
shape so that reading it back restores the exact array. JSON has no NaN or infinity: a non-finite
number is written as ``null`` and read back as NaN.

The schema is derived from the message type's declared fields, so a type added later gets one too.
It keeps to what Foxglove and Lichtblick read (their ``parseJsonSchema``: each property has one
``type`` — boolean, string, number, integer, object with ``properties``, or array whose ``items``
have one of those types — or the viewer refuses the whole channel): a float is ``number``, a
``dict[str, float]`` an object of numbers with no fixed properties, an array a list of numbers. A
field of a type that cannot be said that way is left out of ``properties`` (the schema's
description names it) rather than making the channel unreadable.
"""

from __future__ import annotations

import enum
import math
import types
import typing
from typing import Any

import msgspec
import numpy as np

from umbra.connectors.messages import Message

#: The schema name of a message type ``T`` recorded as JSON is ``umbra.T``.
SCHEMA_PREFIX = "umbra."

_DECODER = msgspec.json.Decoder()
_PRIMITIVE = {float: "number", int: "integer", str: "string", bool: "boolean"}
#: How a non-finite float is spelled in ``_nonfinite`` (and read back).
NONFINITE = {"NaN": float("nan"), "Infinity": float("inf"), "-Infinity": float("-inf")}
NONFINITE_KEY = "_nonfinite"


def _codes(tp: Any) -> list[str] | None:
    """The codes of a string enum (``GuardStage``: ``["passing", "zero"]``), else None."""
    if isinstance(tp, type) and issubclass(tp, enum.Enum) and issubclass(tp, str):
        return [str(m.value) for m in tp]
    return None


def _field_schema(tp: Any) -> dict[str, Any] | None:
    """JSON schema of one field type (``float``, ``tuple[str, ...]``, ``np.ndarray``, a string
    enum...), or None when viewers cannot be told its type."""
    if tp in _PRIMITIVE:
        return {"type": _PRIMITIVE[tp]}
    codes = _codes(tp)
    if codes is not None:  # a code: a string, one of these
        return {"type": "string", "description": f"one of: {', '.join(codes)}"}
    if tp is np.ndarray:
        return {
            "type": "array",
            "items": {"type": "number"},
            "description": "row-major; dtype and shape in `_arrays`",
        }
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin in (types.UnionType, typing.Union):
        kinds = [a for a in args if a is not type(None)]
        return _field_schema(kinds[0]) if len(kinds) == 1 else None  # Optional[X]: X or null
    if origin in (tuple, list):
        items = {a for a in args if a is not Ellipsis}  # tuple[str, ...], list[float]
        item = items.pop() if len(items) == 1 else None
        if _codes(item) is not None:  # codes: strings
            return {"type": "array", "items": _field_schema(item)}
        if item not in _PRIMITIVE:
            return None
        return {"type": "array", "items": {"type": _PRIMITIVE[item]}}
    if origin is dict and len(args) == 2 and args[0] is str and args[1] in _PRIMITIVE:
        return {
            "type": "object",
            "properties": {},
            "additionalProperties": {"type": _PRIMITIVE[args[1]]},
        }
    return None


def json_schema(msg_type: type[Message]) -> dict[str, Any]:
    """The JSON schema of ``msg_type`` recorded as JSON (title ``umbra.<Type>``)."""
    props: dict[str, Any] = {}
    required = []
    untyped = []
    arrays: dict[str, Any] = {}
    for f in msgspec.structs.fields(msg_type):
        schema = _field_schema(f.type)
        if schema is None:
            untyped.append(f.name)
            continue
        props[f.name] = schema
        if f.type is np.ndarray:
            arrays[f.name] = {
                "type": "object",
                "properties": {
                    "dtype": {"type": "string"},
                    "shape": {"type": "array", "items": {"type": "integer"}},
                },
                "required": ["dtype", "shape"],
            }
        may_be_absent = f.type is float or f.type is np.ndarray or schema["type"] == "object"
        no_default = f.default is msgspec.NODEFAULT and f.default_factory is msgspec.NODEFAULT
        if no_default and not may_be_absent:
            required.append(f.name)
    props["_arrays"] = {
        "type": "object",
        "description": "dtype and shape of each array field",
        "properties": arrays,
    }
    props[NONFINITE_KEY] = {
        "type": "object",
        "description": "fields left out because they hold NaN or an infinity: each as strings "
        '("NaN", "Infinity", "-Infinity" or the number), a whole array row-major, a map\'s value '
        "as <field>.<key>",
        "properties": {},
        "additionalProperties": {"type": "array", "items": {"type": "string"}},
    }
    doc = (msg_type.__doc__ or "").strip().splitlines()
    description = doc[0] if doc else msg_type.__name__
    description += f" A field holding NaN or an infinity is given in `{NONFINITE_KEY}` instead."
    if untyped:
        description += f" Fields of other types, not listed: {', '.join(untyped)}."
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": SCHEMA_PREFIX + msg_type.__name__,
        "description": description,
        "type": "object",
        "properties": props,
        "required": sorted((set(required) | {"seq"}) - set(untyped)),
    }


def _array_hook(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        flat = obj.reshape(-1)
        return (flat.astype(np.uint8) if flat.dtype == bool else flat).tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    raise NotImplementedError(f"cannot write {type(obj).__name__} as JSON")


_FAST = msgspec.json.Encoder(enc_hook=_array_hook)
_ARRAY_FIELDS: dict[type, tuple[str, ...]] = {}


def _array_fields(msg_type: type[Message]) -> tuple[str, ...]:
    names = _ARRAY_FIELDS.get(msg_type)
    if names is None:
        names = _ARRAY_FIELDS[msg_type] = tuple(
            f.name for f in msgspec.structs.fields(msg_type) if f.type is np.ndarray
        )
    return names


def _spelled(x: float) -> str:
    """A float as a string that reads back exactly (``NONFINITE`` spellings for the others)."""
    if x != x:
        return "NaN"
    if x in (float("inf"), float("-inf")):
        return "Infinity" if x > 0 else "-Infinity"
    return repr(float(x))


def _nonfinite(sample: Message) -> dict[str, list[str]]:
    """Each field (or ``field.key`` of a map) of ``sample`` holding a non-finite float."""
    found: dict[str, list[str]] = {}
    for name, kind in _float_fields(type(sample)):
        value = getattr(sample, name)
        if kind == "float":
            if isinstance(value, float) and not math.isfinite(value):
                found[name] = [_spelled(value)]
        elif kind == "array":
            numeric = isinstance(value, np.ndarray) and value.dtype.kind in "fc"
            if numeric and not np.isfinite(value).all():
                found[name] = [_spelled(float(v)) for v in value.reshape(-1).real]
        elif isinstance(value, dict):
            for key, v in value.items():
                if isinstance(v, float) and not math.isfinite(v):
                    found[f"{name}.{key}"] = [_spelled(v)]
    return found


_FLOAT_FIELDS: dict[type, tuple[tuple[str, str], ...]] = {}


def _float_fields(msg_type: type[Message]) -> tuple[tuple[str, str], ...]:
    """``(name, "float" | "array" | "map")`` of the fields that may hold a non-finite float."""
    found = _FLOAT_FIELDS.get(msg_type)
    if found is None:
        kinds = []
        for f in msgspec.structs.fields(msg_type):
            if f.type is float:
                kinds.append((f.name, "float"))
            elif f.type is np.ndarray:
                kinds.append((f.name, "array"))
            elif typing.get_origin(f.type) is dict:
                kinds.append((f.name, "map"))
        found = _FLOAT_FIELDS[msg_type] = tuple(kinds)
    return found


def encode_json(sample: Message) -> bytes:
    """``sample`` as a JSON object (see the module docstring): msgspec writes the fields,
    ``_arrays`` is appended, and a field holding a non-finite value goes to ``_nonfinite``."""
    arrays = {}
    for name in _array_fields(type(sample)):
        value = getattr(sample, name)
        if isinstance(value, np.ndarray):
            arrays[name] = {"dtype": value.dtype.str, "shape": list(value.shape)}
    nonfinite = _nonfinite(sample)
    if not nonfinite:
        body = _FAST.encode(sample)
        return body[:-1] + b',"_arrays":' + _FAST.encode(arrays) + b"}"
    obj = msgspec.structs.asdict(sample)
    for path in nonfinite:
        name, _, key = path.partition(".")
        if key and name in obj and not (isinstance(obj[name], float)):
            obj[name] = {k: v for k, v in obj[name].items() if k != key}
        else:
            obj.pop(path, None)
    obj["_arrays"] = arrays
    obj[NONFINITE_KEY] = nonfinite
    return _FAST.encode(obj)


#: Array kinds a recording may hold: bool, integers, floats, complex (never objects).
_NUMERIC_KINDS = "biufc"


def _array(name: str, value: Any, head: Any) -> np.ndarray:
    """The array ``name`` from its nested list and its ``_arrays`` entry; ValueError if bad."""
    try:
        dtype = np.dtype(head["dtype"])
        shape = tuple(int(n) for n in head["shape"])
        if dtype.kind not in _NUMERIC_KINDS:
            raise ValueError(f"dtype {dtype} is not numeric")
        flat = np.asarray(value, dtype=object).reshape(-1)
        out = np.array([np.nan if v is None else v for v in flat], dtype=dtype)
        return out.reshape(shape)
    except (TypeError, KeyError, ValueError) as exc:
        raise ValueError(f"array `{name}`: {exc}") from None


def _restore_nonfinite(obj: dict[str, Any], nonfinite: Any) -> None:
    """Put the values ``_nonfinite`` holds back into ``obj``; ValueError when malformed."""
    if not isinstance(nonfinite, dict):
        raise ValueError(f"`{NONFINITE_KEY}` must be an object")
    for path, spelled in nonfinite.items():
        if not isinstance(spelled, list) or not all(isinstance(v, str) for v in spelled):
            raise ValueError(f"`{NONFINITE_KEY}.{path}` must be a list of strings")
        try:
            values = [NONFINITE[v] if v in NONFINITE else float(v) for v in spelled]
        except ValueError:
            raise ValueError(f"`{NONFINITE_KEY}.{path}`: not numbers: {spelled[:4]}") from None
        name, _, key = path.partition(".")
        if key:
            target = obj.setdefault(name, {})
            if not isinstance(target, dict):
                raise ValueError(f"`{NONFINITE_KEY}.{path}`: `{name}` is not a map")
            target[key] = values[0] if len(values) == 1 else values
        elif name in obj or path in obj:
            raise ValueError(f"`{path}` is given both as a value and in `{NONFINITE_KEY}`")
        else:
            obj[name] = values


_FIELDS: dict[type, dict[str, Any]] = {}


def _fields(msg_type: type[Message]) -> dict[str, Any]:
    found = _FIELDS.get(msg_type)
    if found is None:  # msgspec resolves annotations on every call: once per type
        found = _FIELDS[msg_type] = {f.name: f for f in msgspec.structs.fields(msg_type)}
    return found


def decode_json(msg_type: type[Message], data: bytes) -> Message:
    """The message of ``msg_type`` encoded by :func:`encode_json`; ValueError when it is not one."""
    try:
        obj = _DECODER.decode(data)
    except msgspec.DecodeError as exc:
        raise ValueError(f"not JSON: {exc}") from None
    if not isinstance(obj, dict):
        raise ValueError(f"expected a JSON object, found {type(obj).__name__}")
    arrays = obj.pop("_arrays", {}) or {}
    _restore_nonfinite(obj, obj.pop(NONFINITE_KEY, {}) or {})
    fields = _fields(msg_type)
    kwargs: dict[str, Any] = {}
    for name, value in obj.items():
        f = fields.get(name)
        if f is None:
            raise ValueError(f"field `{name}` is not a field of {msg_type.__name__}")
        if name in arrays:
            kwargs[name] = _array(name, value, arrays[name])
        elif value is None and f.type is float:  # recordings before `_nonfinite`
            kwargs[name] = float("nan")
        elif f.type is float and isinstance(value, list) and len(value) == 1:
            kwargs[name] = float(value[0])
        elif _codes(f.type) is not None:
            kwargs[name] = f.type(value)  # ValueError for a code the enum does not have
        elif typing.get_origin(f.type) is tuple:
            item = typing.get_args(f.type)[0]
            kwargs[name] = tuple(item(v) for v in value) if _codes(item) else tuple(value)
        elif f.type is float and isinstance(value, int):
            kwargs[name] = float(value)
        else:
            kwargs[name] = value
        if isinstance(kwargs[name], dict):
            kwargs[name] = {k: float("nan") if v is None else v for k, v in kwargs[name].items()}
    try:
        return msg_type(**kwargs)
    except TypeError as exc:
        raise ValueError(f"not a {msg_type.__name__}: {exc}") from None
