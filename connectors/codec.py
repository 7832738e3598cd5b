"""Binary, versioned, typed encoding of messages — for links between processes and for recordings.

Layout: msgpack (msgspec) of ``[MAGIC, VERSION, type_name, fields]``; numpy arrays travel as a
msgpack extension holding dtype, shape and the raw buffer (no pickle, ever). Only plain numeric
dtypes are accepted (bool, integers, floats, complex). Encoding copies an array's buffer once into
the extension and once into the output bytes; decoding does not copy it: the array is a read-only
view on the received bytes (numpy keeps those bytes alive through ``.base``).
"""

from __future__ import annotations

import struct
from typing import Any

import msgspec
import numpy as np

from connectors.messages import Message, message_types

MAGIC = "umbra"
VERSION = 1
_EXT_NDARRAY = 1
_HEADER = struct.Struct("<B")  # length of the dtype string, then dtype, ndim (u1), shape (u8 each)
_NUMERIC_KINDS = "biufc"  # bool, signed, unsigned, float, complex: nothing that runs code or points


def _raw_view(arr: np.ndarray) -> memoryview:
    """The bytes of a C-contiguous array, without copying them."""
    return memoryview(arr.reshape(-1).view(np.uint8))


class DecodeError(ValueError):
    """Bytes that are not a sample this version understands (foreign, truncated, other version)."""


def _enc_hook(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        arr = np.ascontiguousarray(obj)
        if arr.dtype.kind not in _NUMERIC_KINDS:
            raise NotImplementedError(f"cannot encode arrays of dtype {arr.dtype}")
        dtype = arr.dtype.str.encode()
        head = (
            bytes([len(dtype)])
            + dtype
            + bytes([arr.ndim])
            + struct.pack(f"<{arr.ndim}Q", *arr.shape)
        )
        # one copy of the buffer: join reads the array's memory directly (no tobytes())
        return msgspec.msgpack.Ext(_EXT_NDARRAY, b"".join((head, _raw_view(arr))))
    if isinstance(obj, np.generic):
        return obj.item()
    raise NotImplementedError(f"cannot encode {type(obj).__name__}")


def _ext_hook(code: int, data: memoryview) -> Any:
    if code != _EXT_NDARRAY:
        raise DecodeError(f"unknown extension code {code}")
    try:
        n = data[0]
        dtype = np.dtype(bytes(data[1 : 1 + n]).decode())
        if dtype.kind not in _NUMERIC_KINDS:
            raise DecodeError(f"arrays of dtype {dtype} are not accepted")
        ndim = data[1 + n]
        start = 2 + n
        shape = struct.unpack_from(f"<{ndim}Q", data, start)
        offset = start + 8 * ndim
        count = int(np.prod(shape)) if ndim else 1
        if len(data) - offset != count * dtype.itemsize:
            raise DecodeError("array buffer has the wrong length")
        arr = np.frombuffer(data, dtype=dtype, count=count, offset=offset).reshape(shape)
    except (IndexError, struct.error, TypeError, ValueError) as exc:
        raise DecodeError(f"bad array: {exc}") from None
    return arr


def _dec_hook(typ: type, obj: Any) -> Any:
    if typ is np.ndarray and isinstance(obj, np.ndarray):
        return obj
    raise NotImplementedError(f"cannot decode {typ}")


class Codec:
    """Encoder and decoders for every message type (create one per process or thread)."""

    def __init__(self) -> None:
        self._types = message_types()
        self._encoder = msgspec.msgpack.Encoder(enc_hook=_enc_hook)
        self._envelope = msgspec.msgpack.Decoder(tuple[str, int, str, msgspec.Raw])
        self._decoders = {
            name: msgspec.msgpack.Decoder(cls, ext_hook=_ext_hook, dec_hook=_dec_hook)
            for name, cls in self._types.items()
        }

    def encode(self, msg: Message) -> bytes:
        """Bytes for ``msg`` (type name, version and every field, arrays as raw buffers)."""
        return self._encoder.encode((MAGIC, VERSION, type(msg).__name__, msg))

    def decode(self, data: bytes | memoryview, expected: type[Message] | None = None) -> Message:
        """The message in ``data``; DecodeError when it is not one (or not of ``expected``)."""
        try:
            magic, version, name, raw = self._envelope.decode(data)
        except (msgspec.DecodeError, msgspec.ValidationError, TypeError) as exc:
            raise DecodeError(f"not an umbra sample: {exc}") from None
        if magic != MAGIC:
            raise DecodeError(f"not an umbra sample (magic {magic!r})")
        if version != VERSION:
            raise DecodeError(f"encoding version {version}, this build reads {VERSION}")
        decoder = self._decoders.get(name)
        if decoder is None:
            raise DecodeError(f"unknown message type `{name}`")
        if expected is not None and name != expected.__name__:
            raise DecodeError(f"expected {expected.__name__}, found {name}")
        try:
            return decoder.decode(raw)
        except (
            msgspec.DecodeError,
            msgspec.ValidationError,
            DecodeError,
            NotImplementedError,
            TypeError,
            ValueError,
        ) as exc:
            raise DecodeError(f"bad {name}: {exc}") from None
