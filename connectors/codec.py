"""Binary, versioned, typed encoding of messages — for links between processes and for recordings.

Two layouts, both read by ``Codec.decode``; no pickle, ever, and only plain numeric array dtypes
(bool, integers, floats, complex):

* version 1, ``encode``: msgpack (msgspec) of ``[MAGIC, 1, type_name, fields]``; each numpy array
  is a msgpack extension holding dtype, shape and the raw buffer. Used for recordings.
* version 3, ``encode_compact`` (links, small samples): ``[MAGIC, 3, type_tag, values]``, fields
  by position and each array ``[dtype, shape, bytes]``, read and written by msgspec in C; the tag
  is the type name and a fingerprint of its field layout (``umbra.connectors.compact``). A type it
  cannot mirror is written as version 1.
* version 2, ``encode_framed`` (links, samples holding at least ``FRAMED_MIN_BYTES`` of arrays):
  ``b"UMB\\x02"``, the header length (u32 little-endian), the msgpack header
  ``[MAGIC, 2, type_name, fields]`` in which each array is an extension holding dtype, shape, and
  the offset and length of its buffer, then the buffers, each 64-byte aligned. An image is copied
  once to build the sample (version 1 copies it twice).

Decoding never copies an array's buffer: the array is a read-only view on the received bytes
(numpy keeps those bytes alive through ``.base``). A Codec keeps per-call state: use one per thread.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Mapping
from typing import Any, TypeVar, overload

import msgspec
import numpy as np

from umbra.connectors.compact import COMPACT_VERSION, CompactType, compact_type
from umbra.connectors.messages import Message, message_types

MAGIC = "umbra"
VERSION = 1
FRAMED_VERSION = 2
FRAME_MAGIC = b"UMB\x02"
#: Samples whose arrays hold at least this many bytes are framed by ``encode_framed``.
FRAMED_MIN_BYTES = 16 * 1024
_M = TypeVar("_M", bound=Message)
_EXT_NDARRAY = 1  # version 1: dtype, shape, buffer
_EXT_NDARRAY_REF = 2  # version 2: dtype, shape, offset, length
_FRAME_HEAD = struct.Struct("<4sI")
_REF = struct.Struct("<QQ")
_ALIGN = 64
_NUMERIC_KINDS = "biufc"  # bool, signed, unsigned, float, complex: nothing that runs code or points
_SMALL_ARRAY = 4096  # [bytes] arrays up to this size are copied with tobytes (fewer calls)


class DecodeError(ValueError):
    """Bytes that are not a sample this version understands (foreign, truncated, other version)."""


def _aligned(n: int) -> int:
    return (n + _ALIGN - 1) // _ALIGN * _ALIGN


def _raw_view(arr: np.ndarray) -> memoryview:
    """The bytes of a C-contiguous array, without copying them."""
    return arr.reshape(-1).view(np.uint8).data


def _contiguous(obj: np.ndarray) -> np.ndarray:
    arr = np.ascontiguousarray(obj)
    if arr.dtype.kind not in _NUMERIC_KINDS:
        raise NotImplementedError(f"cannot encode arrays of dtype {arr.dtype}")
    return arr


def _array_head(arr: np.ndarray) -> bytes:
    """dtype string length (u1), dtype string, ndim (u1), shape (u8 each)."""
    key = (arr.dtype, arr.shape)
    head = _HEADS.get(key)
    if head is None:
        dtype = arr.dtype.str.encode()
        head = (
            bytes([len(dtype)])
            + dtype
            + bytes([arr.ndim])
            + struct.pack(f"<{arr.ndim}Q", *arr.shape)
        )
        if len(_HEADS) < _CACHE_SIZE:
            _HEADS[key] = head
    return head


#: Array heads by (dtype, shape), and parsed heads by their bytes: samples of one stream repeat
#: the same few shapes, so encoding and decoding an array head is one dictionary lookup.
_CACHE_SIZE = 256
_HEADS: dict[tuple[np.dtype, tuple[int, ...]], bytes] = {}
_PARSED: dict[bytes, tuple[np.dtype, tuple[int, ...], int, int]] = {}


_DTYPES: dict[bytes, np.dtype] = {}


def _dtype(code: bytes) -> np.dtype:
    dtype = _DTYPES.get(code)
    if dtype is None:
        dtype = np.dtype(code.decode())
        if dtype.kind not in _NUMERIC_KINDS:
            raise DecodeError(f"arrays of dtype {dtype} are not accepted")
        if len(_DTYPES) < 64:
            _DTYPES[code] = dtype
    return dtype


def _parse_head(data: memoryview) -> tuple[np.dtype, tuple[int, ...], int, int]:
    """dtype, shape, element count and the offset just after the head."""
    n = data[0]
    ndim = data[1 + n]
    end = 2 + n + 8 * ndim
    key = bytes(data[:end])
    parsed = _PARSED.get(key)
    if parsed is not None:
        return parsed
    if len(key) != end:
        raise DecodeError("truncated array head")
    dtype = _dtype(key[1 : 1 + n])
    shape = struct.unpack_from(f"<{ndim}Q", key, 2 + n)
    count = 1
    for d in shape:
        count *= d
    parsed = (dtype, shape, count, end)
    if len(_PARSED) < _CACHE_SIZE:
        _PARSED[key] = parsed
    return parsed


def _enc_hook(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        plain = obj.flags.c_contiguous and obj.dtype.kind in _NUMERIC_KINDS
        arr = obj if plain else _contiguous(obj)
        if arr.nbytes <= _SMALL_ARRAY:
            return msgspec.msgpack.Ext(_EXT_NDARRAY, _array_head(arr) + arr.tobytes())
        # one copy of the buffer: join reads the array's memory directly (no tobytes())
        return msgspec.msgpack.Ext(_EXT_NDARRAY, b"".join((_array_head(arr), _raw_view(arr))))
    if isinstance(obj, np.generic):
        return obj.item()
    raise NotImplementedError(f"cannot encode {type(obj).__name__}")


def _dec_hook(typ: type, obj: Any) -> Any:
    if typ is np.ndarray and isinstance(obj, np.ndarray):
        return obj
    raise NotImplementedError(f"cannot decode {typ}")


def _check_type(known: Mapping[str, object], name: str, expected: type[Message] | None) -> None:
    """DecodeError when message type ``name`` is not in ``known`` or is not ``expected``."""
    if name not in known:
        raise DecodeError(f"unknown message type `{name}`")
    if expected is not None and name != expected.__name__:
        raise DecodeError(f"expected {expected.__name__}, found {name}")


def array_bytes(msg: Message) -> int:
    """Bytes held in the arrays of ``msg``."""
    names = _ARRAY_FIELDS.get(type(msg))
    if names is None:
        names = _ARRAY_FIELDS[type(msg)] = array_fields(type(msg))
    return _bytes_in(msg, names)


def _bytes_in(msg: Message, names: tuple[str, ...]) -> int:
    """Bytes held in the arrays of fields ``names`` of ``msg``."""
    total = 0
    for name in names:
        value = getattr(msg, name)
        if isinstance(value, np.ndarray):
            total += value.nbytes
    return total


def array_fields(cls: type[Message]) -> tuple[str, ...]:
    """Fields of ``cls`` annotated ``np.ndarray`` (the only ones the decoder accepts arrays in)."""
    return tuple(f.name for f in msgspec.structs.fields(cls) if f.type is np.ndarray)


_ARRAY_FIELDS: dict[type, tuple[str, ...]] = {}


class Codec:
    """Encoders and decoders for every message type (create one per process or thread)."""

    def __init__(self) -> None:
        self._types = message_types()
        self._encoder = msgspec.msgpack.Encoder(enc_hook=_enc_hook)
        self._frame_encoder = msgspec.msgpack.Encoder(enc_hook=self._frame_hook)
        self._envelope = msgspec.msgpack.Decoder(tuple[str, int, str, msgspec.Raw])
        self._decoders = {
            name: msgspec.msgpack.Decoder(cls, ext_hook=self._ext_hook, dec_hook=_dec_hook)
            for name, cls in self._types.items()
        }
        self._direct: dict[
            type[Message], msgspec.msgpack.Decoder[tuple[str, int, str, Message]]
        ] = {}
        self._compact: dict[type[Message], CompactType] = {}
        for cls in self._types.values():
            compact = compact_type(cls)
            if compact is not None:
                self._compact[cls] = compact
        self._readers: dict[type[Message], Callable[[bytes | memoryview], Message | None]] = {}
        self._parts: list[tuple[int, np.ndarray]] = []
        self._place: Callable[[np.ndarray], int] | None = None
        self._size = 0
        self._payload: memoryview | None = None
        self._data_start = 0

    # -- encoding -------------------------------------------------------------------------------
    def encode(self, msg: Message) -> bytes:
        """Version 1 bytes for ``msg`` (type name, version and every field, arrays inline)."""
        return self._encoder.encode((MAGIC, VERSION, type(msg).__name__, msg))

    def encode_compact(self, msg: Message) -> bytes:
        """Version 3 bytes for ``msg`` (version 1 for a type without a wire struct)."""
        compact = self._compact.get(type(msg))
        if compact is None:
            return self.encode(msg)
        return self._encoder.encode((MAGIC, COMPACT_VERSION, compact.tag, compact.to_wire(msg)))

    def _frame_hook(self, obj: Any) -> Any:
        if isinstance(obj, np.ndarray):
            if self._place is not None:
                if not obj.flags.c_contiguous or obj.dtype.kind not in _NUMERIC_KINDS:
                    raise LookupError("only contiguous numeric arrays are referenced in place")
                offset = self._place(obj)  # LookupError when it does not lie in the payload
                return msgspec.msgpack.Ext(
                    _EXT_NDARRAY_REF, _array_head(obj) + _REF.pack(offset, obj.nbytes)
                )
            arr = _contiguous(obj)
            offset = _aligned(self._size)
            self._parts.append((offset, arr))
            self._size = offset + arr.nbytes
            return msgspec.msgpack.Ext(
                _EXT_NDARRAY_REF, _array_head(arr) + _REF.pack(offset, arr.nbytes)
            )
        return _enc_hook(obj)

    def frame(self, msg: Message) -> tuple[bytes, list[tuple[int, np.ndarray]], int]:
        """Version 2 pieces of ``msg``: the head (magic, length, header, padding), its arrays with
        their offsets from the end of the head, and the total size [bytes]. Writing the head and
        then each array at ``len(head) + offset`` gives the bytes of ``encode_framed``."""
        self._parts, self._size = [], 0
        try:
            header = self._frame_encoder.encode((MAGIC, FRAMED_VERSION, type(msg).__name__, msg))
            parts, size = self._parts, self._size
        finally:
            self._parts, self._size = [], 0
        start = _aligned(_FRAME_HEAD.size + len(header))
        head = b"".join(
            (
                _FRAME_HEAD.pack(FRAME_MAGIC, len(header)),
                header,
                bytes(start - _FRAME_HEAD.size - len(header)),
            )
        )
        return head, parts, start + size

    def frame_header(self, msg: Message, place: Callable[[np.ndarray], int]) -> bytes:
        """The version 2 header of ``msg`` with each array referenced where it already lies:
        ``place(array)`` gives its offset [bytes] in the payload ``decode_placed`` will be given,
        or raises LookupError — as this does for an array that is not contiguous and numeric."""
        self._place = place
        try:
            return self._frame_encoder.encode((MAGIC, FRAMED_VERSION, type(msg).__name__, msg))
        finally:
            self._place = None

    def encode_framed(self, msg: Message) -> bytes:
        """Bytes for ``msg`` with its arrays copied once, after the header (version 2); samples
        with little array data are encoded as version 3 (``encode_compact``)."""
        if array_bytes(msg) < FRAMED_MIN_BYTES:
            return self.encode_compact(msg)
        head, parts, _size = self.frame(msg)
        pieces: list[bytes | memoryview] = [head]
        pos = 0
        for offset, arr in parts:
            if offset > pos:
                pieces.append(bytes(offset - pos))
            pieces.append(_raw_view(arr))
            pos = offset + arr.nbytes
        return b"".join(pieces)

    # -- decoding -------------------------------------------------------------------------------
    def _ext_hook(self, code: int, data: memoryview) -> Any:
        try:
            dtype, shape, count, end = _parse_head(data)
            if code == _EXT_NDARRAY:
                if len(data) - end != count * dtype.itemsize:
                    raise DecodeError("array buffer has the wrong length")
                arr = np.frombuffer(data, dtype=dtype, count=count, offset=end)
                return arr if len(shape) == 1 else arr.reshape(shape)
            if code == _EXT_NDARRAY_REF and self._payload is not None:
                offset, length = _REF.unpack_from(data, end)
                start = self._data_start + offset
                if length != count * dtype.itemsize or start + length > len(self._payload):
                    raise DecodeError("array reference out of the sample's bounds")
                return np.frombuffer(self._payload, dtype=dtype, count=count, offset=start).reshape(
                    shape
                )
        except (IndexError, struct.error, TypeError, ValueError) as exc:
            raise DecodeError(f"bad array: {exc}") from None
        raise DecodeError(f"unknown extension code {code}")

    @overload
    def decode(self, data: bytes | memoryview, expected: type[_M]) -> _M: ...
    @overload
    def decode(self, data: bytes | memoryview, expected: None = None) -> Message: ...
    def decode(self, data: bytes | memoryview, expected: type[Message] | None = None) -> Message:
        """The message in ``data`` (either version); DecodeError when it is not one (or not of
        ``expected``)."""
        if bytes(data[:4]) != FRAME_MAGIC:
            if expected is not None:
                read = self.compact_reader(expected)
                msg = read(data) if read is not None else None
                if msg is None:
                    msg = self._decode_direct(data, expected)
                if msg is not None:
                    return msg
            return self._decode(data, VERSION, expected)
        view = memoryview(data)
        if len(view) < _FRAME_HEAD.size:
            raise DecodeError("not an umbra sample: truncated frame")
        _magic, length = _FRAME_HEAD.unpack_from(view)
        end = _FRAME_HEAD.size + length
        if end > len(view):
            raise DecodeError("not an umbra sample: truncated frame header")
        return self.decode_placed(view[_FRAME_HEAD.size : end], view, expected, _aligned(end))

    def decode_placed(
        self,
        header: bytes | memoryview,
        payload: memoryview,
        expected: type[Message] | None = None,
        data_start: int = 0,
    ) -> Message:
        """The message of a version 2 header whose arrays lie in ``payload``, their offsets
        counted from ``data_start`` [bytes] (a ``frame_header`` header: from 0)."""
        self._payload, self._data_start = payload, data_start
        try:
            if expected is not None:
                msg = self._decode_direct(header, expected, FRAMED_VERSION)
                if msg is not None:
                    return msg
            return self._decode(header, FRAMED_VERSION, expected)
        finally:
            self._payload = None

    def compact_reader(
        self, expected: type[Message]
    ) -> Callable[[bytes | memoryview], Message | None] | None:
        """A reader of version 3 samples of ``expected``: the message, or None for anything else
        (``decode`` then reads it or says why it cannot); None when ``expected`` has no compact
        layout. The reader keeps no state between calls: any thread may use it."""
        reader = self._readers.get(expected)
        if reader is not None:
            return reader
        compact = self._compact.get(expected)
        if compact is None or self._types.get(expected.__name__) is not expected:
            return None
        decode = msgspec.msgpack.Decoder(
            tuple[str, int, str, compact.wire]  # type: ignore[name-defined]  # built at run time
        ).decode
        from_wire, tag_wanted = compact.from_wire, compact.tag

        def read(data: bytes | memoryview) -> Message | None:
            try:
                magic, version, name, values = decode(data)
                if magic != MAGIC or version != COMPACT_VERSION or name != tag_wanted:
                    return None
                return from_wire(values)
            except Exception:
                return None

        self._readers[expected] = read
        return read

    def compact_writer(self, cls: type[Message]) -> Callable[[Message], bytes]:
        """``encode_framed`` for samples of type ``cls``, its per-type lookups done once: version 3
        while the sample's arrays hold less than ``FRAMED_MIN_BYTES``, else version 2."""
        compact = self._compact.get(cls)
        if compact is None:
            return self.encode_framed
        encode, to_wire, framed = self._encoder.encode, compact.to_wire, self.encode_framed
        arrays, tag = array_fields(cls), compact.tag

        def write(msg: Message) -> bytes:
            if type(msg) is not cls or _bytes_in(msg, arrays) >= FRAMED_MIN_BYTES:
                return framed(msg)
            return encode((MAGIC, COMPACT_VERSION, tag, to_wire(msg)))

        return write

    def _decode_direct(
        self, data: bytes | memoryview, expected: type[Message], version_wanted: int = VERSION
    ) -> Message | None:
        """One pass for a sample of a known type; None when anything is off (the general path
        then says what)."""
        decoder = self._direct.get(expected)
        if decoder is None:
            if self._types.get(expected.__name__) is not expected:
                return None
            decoder = self._direct[expected] = msgspec.msgpack.Decoder(
                tuple[str, int, str, expected],  # type: ignore[valid-type]  # a run-time type
                ext_hook=self._ext_hook,
                dec_hook=_dec_hook,
            )
        try:
            magic, version, name, msg = decoder.decode(data)
        except Exception:
            return None
        if magic != MAGIC or version != version_wanted or name != expected.__name__:
            return None
        return msg

    def _decode(
        self, data: bytes | memoryview, version_wanted: int, expected: type[Message] | None
    ) -> Message:
        try:
            magic, version, name, raw = self._envelope.decode(data)
        except (msgspec.DecodeError, msgspec.ValidationError, TypeError) as exc:
            raise DecodeError(f"not an umbra sample: {exc}") from None
        if magic != MAGIC:
            raise DecodeError(f"not an umbra sample (magic {magic!r})")
        if version == COMPACT_VERSION and version_wanted == VERSION:
            return self._decode_values(name, raw, expected)
        if version != version_wanted:
            raise DecodeError(
                f"encoding version {version}, this build reads {VERSION}, "
                f"{COMPACT_VERSION} (compact) and {FRAMED_VERSION} (framed)"
            )
        _check_type(self._decoders, name, expected)
        decoder = self._decoders[name]
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

    def _decode_values(self, tag: str, raw: msgspec.Raw, expected: type[Message] | None) -> Message:
        """The message tagged ``tag`` (type name and layout) from the values of a version 3
        sample."""
        name, _, layout = tag.partition("/")
        _check_type(self._types, name, expected)
        compact = self._compact.get(self._types[name])
        if compact is None:
            raise DecodeError(f"{name} has no compact layout in this build")
        if tag != compact.tag:
            mine = compact.tag.partition("/")[2]
            raise DecodeError(
                f"{name} with field layout {layout or '(none)'}, this build's is {mine}: "
                "the producer runs another version of the message types"
            )
        try:
            return compact.from_wire(compact.decode_wire(raw))
        except (msgspec.DecodeError, msgspec.ValidationError, TypeError, ValueError) as exc:
            raise DecodeError(f"bad {name}: {exc}") from None
