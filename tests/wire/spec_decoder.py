"""A reader of umbra samples written from ``docs/wire-format.md`` alone.

It imports nothing of umbra: only msgspec (as a plain msgpack reader) and numpy. What it knows of
the message types (field order, layout tags) it reads from the specification's own tables
(``layouts``), so a wrong table makes decoding fail.
"""

from __future__ import annotations

import re
import struct
from typing import Any

import msgspec
import numpy as np

MAGIC = "umbra"
NUMERIC_KINDS = "biufc"
_HEADING = re.compile(r"^#### (\w+)$")
_TAG = re.compile(r"^Layout tag `(\w+/[0-9a-f]{8})`")
_ROW = re.compile(r"^\| (\d+) \| `(\w+)` \|")


class SpecError(ValueError):
    """Bytes that are not a sample as the specification describes it."""


def layouts(spec_text: str) -> dict[str, tuple[str, list[str]]]:
    """``{type name: (layout tag, field names in wire order)}`` from the spec's tables."""
    found: dict[str, tuple[str, list[str]]] = {}
    name = ""
    for line in spec_text.splitlines():
        if m := _HEADING.match(line):
            name = m.group(1)
            found[name] = ("", [])
        elif name and (m := _TAG.match(line)):
            found[name] = (m.group(1), found[name][1])
        elif name and (m := _ROW.match(line)):
            fields = found[name][1]
            if int(m.group(1)) != len(fields):
                raise SpecError(f"{name}: field {m.group(2)} out of order")
            fields.append(m.group(2))
    return found


def _dtype(text: str) -> np.dtype:
    dtype = np.dtype(text)
    if dtype.kind not in NUMERIC_KINDS:
        raise SpecError(f"dtype {text} is not a plain numeric one")
    return dtype


def _head(data: bytes) -> tuple[np.dtype, tuple[int, ...], int]:
    """Array head of an extension: u8 n, dtype, u8 ndim, ndim x u64 shape; and where it ends."""
    n = data[0]
    dtype = _dtype(data[1 : 1 + n].decode("ascii"))
    ndim = data[1 + n]
    shape = struct.unpack_from(f"<{ndim}Q", data, 2 + n)
    return dtype, tuple(shape), 2 + n + 8 * ndim


def _v3_value(value: Any) -> Any:
    """A version 3 value: arrays are ``[dtype, shape, bin]``."""
    if (
        isinstance(value, list)
        and len(value) == 3
        and isinstance(value[0], str)
        and isinstance(value[1], list)
        and isinstance(value[2], bytes)
    ):
        return np.frombuffer(value[2], _dtype(value[0])).reshape(value[1])
    return value


def decode(payload: bytes, types: dict[str, tuple[str, list[str]]]) -> tuple[str, int, dict]:
    """``(type name, envelope version, {field: value})`` of one sample's payload."""
    if payload[:4] == b"UMB\x02":
        return _decode_v2(payload)
    envelope = msgspec.msgpack.decode(payload, ext_hook=_v1_ext)
    if not (isinstance(envelope, list) and len(envelope) == 4 and envelope[0] == MAGIC):
        raise SpecError("not an umbra envelope")
    _magic, version, name, body = envelope
    if version == 1:
        return name, 1, dict(body)
    if version != 3:
        raise SpecError(f"unknown envelope version {version}")
    type_name = name.partition("/")[0]
    tag, fields = types[type_name]
    if name != tag:
        raise SpecError(f"layout {name}, the spec's is {tag}")
    if len(body) != len(fields):
        raise SpecError(f"{type_name}: {len(body)} values for {len(fields)} fields")
    return type_name, 3, {f: _v3_value(v) for f, v in zip(fields, body, strict=True)}


def _v1_ext(code: int, data: memoryview) -> Any:
    if code != 1:
        raise SpecError(f"extension {code} in a version 1 sample")
    raw = bytes(data)
    dtype, shape, end = _head(raw)
    return np.frombuffer(raw, dtype, offset=end).reshape(shape)


def _decode_v2(payload: bytes) -> tuple[str, int, dict]:
    (length,) = struct.unpack_from("<I", payload, 4)
    header = payload[8 : 8 + length]
    data_start = (8 + length + 63) // 64 * 64

    def ext(code: int, data: memoryview) -> Any:
        if code != 2:
            raise SpecError(f"extension {code} in a version 2 header")
        raw = bytes(data)
        dtype, shape, end = _head(raw)
        offset, size = struct.unpack_from("<QQ", raw, end)
        start = data_start + offset
        if offset % 64 or start + size > len(payload):
            raise SpecError("array outside the sample")
        return np.frombuffer(payload, dtype, size // dtype.itemsize, start).reshape(shape)

    magic, version, name, fields = msgspec.msgpack.decode(header, ext_hook=ext)
    if magic != MAGIC or version != 2:
        raise SpecError("not a version 2 header")
    return name, 2, dict(fields)


def encoding_fields(text: str) -> tuple[str, dict[str, str]]:
    """``("application/x-umbra", {"v": "3", "type": "Twist"})`` of a zenoh encoding string."""
    media, *params = text.split(";")
    return media, dict(p.split("=", 1) for p in params)
