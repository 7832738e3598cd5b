"""Version 3 of the sample encoding: small samples, encoded and decoded by msgspec in C.

``[MAGIC, 3, type_tag, values]``: ``values`` are the message's fields in declaration order (no
field names on the wire), and each numpy array is ``[dtype, shape, bytes]``. Since values go by
position, the type tag carries a fingerprint of the field layout (``"Twist/6c1f03a2"``: names and
types in order): a producer built with another layout of the type is refused with that reason,
never read with its fields shifted. Version 1 puts an
array in a msgpack extension, which msgspec hands to a Python hook on both ends; here every field
has a type msgspec knows, so the whole sample is read and written in C and Python only wraps each
array's bytes (``np.frombuffer``, no copy) and builds the message. On a link, that is most of the
per-sample cost of a 48-byte twist.

Per message type, a *wire struct* mirrors the message with each ``np.ndarray`` field replaced by
``WireArray``; the two converters between a message and its wire struct are generated once per
type from its field names (plain attribute reads and one constructor call: a twist is converted in
well under a microsecond). A type whose fields hide arrays elsewhere (say, a tuple of arrays) has
no wire struct and is encoded as version 1.
"""

from __future__ import annotations

import functools
import hashlib
import keyword
from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated, Any

import msgspec
import numpy as np

from umbra.connectors.messages import Message

COMPACT_VERSION = 3
_NUMERIC_KINDS = "biufc"  # bool, signed, unsigned, float, complex: nothing that runs code or points
_Dim = Annotated[int, msgspec.Meta(ge=0)]


class CompactError(ValueError):
    """A compact sample whose array or fields do not make a message of its type."""


class WireArray(msgspec.Struct, array_like=True, frozen=True):
    """A numpy array on the wire: dtype string (``"<f8"``), shape, C-order bytes."""

    dtype: str
    shape: tuple[_Dim, ...]
    data: bytes


def array_writer() -> Callable[[np.ndarray], WireArray]:
    """A function turning a numeric array into a ``WireArray`` (one copy of its bytes, C order);
    NotImplementedError for any other dtype."""
    codes: dict[np.dtype, str] = {}

    def write(arr: np.ndarray) -> WireArray:
        dtype = arr.dtype
        code = codes.get(dtype)
        if code is None:
            if dtype.kind not in _NUMERIC_KINDS:
                raise NotImplementedError(f"cannot encode arrays of dtype {dtype}")
            code = dtype.str
            if len(codes) < 64:
                codes[dtype] = code
        return WireArray(code, arr.shape, arr.tobytes())

    return write


class _Dtypes:
    """Numeric dtypes by their wire string (a foreign sample cannot grow it past ``limit``)."""

    def __init__(self, limit: int = 64) -> None:
        self._known: dict[str, np.dtype] = {}
        self._limit = limit

    def __call__(self, code: str) -> np.dtype:
        dtype = self._known.get(code)
        if dtype is None:
            try:
                dtype = np.dtype(code)
            except TypeError as exc:
                raise CompactError(f"bad array dtype {code!r}: {exc}") from None
            if dtype.kind not in _NUMERIC_KINDS:
                raise CompactError(f"arrays of dtype {dtype} are not accepted")
            if len(self._known) < self._limit:
                self._known[code] = dtype
        return dtype


def array_reader() -> Callable[[WireArray], np.ndarray]:
    """A function turning a ``WireArray`` into a read-only array viewing its bytes."""
    dtype_of = _Dtypes()
    frombuffer = np.frombuffer

    def read(w: WireArray) -> np.ndarray:
        shape = w.shape
        try:
            arr = frombuffer(w.data, dtype_of(w.dtype))
            if len(shape) == 1 and arr.shape == shape:
                return arr
            return arr.reshape(shape)
        except ValueError as exc:
            raise CompactError(f"bad array {w.dtype} {shape}: {exc}") from None

    return read


@dataclass(frozen=True)
class CompactType:
    """How one message type is written and read in version 3."""

    cls: type[Message]
    #: ``"<type name>/<layout fingerprint>"``, the type slot of a version 3 sample
    tag: str
    wire: type[msgspec.Struct]
    #: msgpack bytes of a wire struct -> the wire struct (msgspec's decoder: any thread may use it)
    decode_wire: Callable[[bytes | memoryview], msgspec.Struct]
    to_wire: Callable[[Message], msgspec.Struct]
    from_wire: Callable[[msgspec.Struct], Message]


@functools.cache
def compact_type(cls: type[Message]) -> CompactType | None:
    """The wire struct and converters of ``cls``, or None when msgspec cannot handle its fields
    once its top-level arrays are replaced (then the type is encoded as version 1). Built once
    per type and shared by every codec (the converters keep no per-call state): a link's first
    sample on a new zenoh thread does not wait for the layouts of every type to be generated."""
    fields = msgspec.structs.fields(cls)
    names = [f.name for f in fields]
    if not all(n.isidentifier() and not keyword.iskeyword(n) for n in names):
        return None
    arrays = {f.name for f in fields if f.type is np.ndarray}
    wire = msgspec.defstruct(
        f"{cls.__name__}Wire",
        [(f.name, WireArray if f.name in arrays else f.type) for f in fields],
        array_like=True,
        frozen=True,
    )
    try:
        decoder = msgspec.msgpack.Decoder(wire)
    except TypeError:
        return None  # an array (or another unsupported type) inside a field
    to_values = ", ".join(f"A(m.{n})" if n in arrays else f"m.{n}" for n in names)
    to_fields = ", ".join(f"{n}=R(w.{n})" if n in arrays else f"{n}=w.{n}" for n in names)
    source = (
        f"def to_wire(m):\n    return W({to_values})\n"
        f"def from_wire(w):\n    return C({to_fields})\n"
    )
    space: dict[str, Any] = {"W": wire, "C": cls, "A": array_writer(), "R": array_reader()}
    exec(compile(source, f"<compact {cls.__name__}>", "exec"), space)  # names checked above
    return CompactType(
        cls, layout_tag(cls), wire, decoder.decode, space["to_wire"], space["from_wire"]
    )


def layout_tag(cls: type[Message]) -> str:
    """``"<name>/<8 hex digits>"``: the type's name and a fingerprint of its fields' names and
    types, in order (what a version 3 reader must agree on with the writer)."""
    layout = ";".join(f"{f.name}:{_type_name(f.type)}" for f in msgspec.structs.fields(cls))
    return f"{cls.__name__}/{hashlib.blake2b(layout.encode(), digest_size=4).hexdigest()}"


def _type_name(typ: Any) -> str:
    """``float``, ``ndarray``, ``tuple[str, ...]``: the same on every Python we support."""
    return typ.__name__ if isinstance(typ, type) else repr(typ)
