"""One sample of every message type with a value in every field (none left at its default)."""

from __future__ import annotations

import enum
import typing
from typing import Any

import msgspec
import numpy as np

from umbra.connectors.messages import Message, registered_message_types

#: Fields holding images: big enough that the sample is framed (envelope version 2).
IMAGE_FIELDS = {"pixels", "image_a", "image_b"}


def _value(name: str, typ: Any, i: int) -> Any:
    if typ is np.ndarray:
        if name in IMAGE_FIELDS:
            rng = np.random.default_rng(i)
            return rng.integers(0, 256, (120, 160, 3), dtype=np.uint8)
        if name == "edges":
            return np.array([[0, 1], [1, 2]], dtype=np.int64)
        return np.arange(6, dtype=np.float64).reshape(2, 3) * 0.25 + i
    if typ is float:
        return 0.5 + i
    if typ is bool:
        return True
    if typ is int:
        return 7 + i
    if typ is str:
        return f"{name}-é{i}"
    if isinstance(typ, type) and issubclass(typ, enum.Enum):
        return list(typ)[-1]  # a code, not the default
    if typing.get_origin(typ) is tuple and isinstance(typing.get_args(typ)[0], enum.EnumMeta):
        codes = list(typing.get_args(typ)[0])
        return (codes[-1], codes[0])
    text = repr(typ)
    if text.startswith("tuple[str"):
        return ("a", f"b{i}")
    if text.startswith("dict[str, float]"):
        return {"k": 1.5 + i, "inf": float("inf")}
    raise AssertionError(f"no example value for {name}: {text}")


def every_type() -> dict[str, type[Message]]:
    """The shipped message types (``umbra.connectors.messages`` and the ``umbra.messages`` entry
    points), by name."""
    return registered_message_types()


def example(cls: type[Message], seq: int = 1) -> Message:
    """A ``cls`` with every field set (``seq`` given, stamps and origins distinct)."""
    values = {
        f.name: _value(f.name, f.type, i)
        for i, f in enumerate(msgspec.structs.fields(cls))
        if f.name not in ("seq", "stamp", "origin")
    }
    return cls(seq=seq, stamp=100.25 + seq, origin=99.5 + seq, **values)


def same(decoded: dict, msg: Message) -> list[str]:
    """Fields of ``msg`` that ``decoded`` (field -> value) lacks or holds differently."""
    wrong = []
    for f in msgspec.structs.fields(type(msg)):
        want, got = getattr(msg, f.name), decoded.get(f.name, "<missing>")
        if isinstance(want, np.ndarray):
            ok = isinstance(got, np.ndarray) and got.dtype == want.dtype
            ok = ok and got.shape == want.shape and np.array_equal(got, want)
        elif isinstance(want, tuple):
            ok = list(want) == got
        else:
            ok = want == got
        if not ok:
            wrong.append(f.name)
    return wrong
