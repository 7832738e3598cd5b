"""Opening an MCAP chunk without trusting it: its declared size is checked before it is inflated.

The ``mcap`` library inflates a whole chunk whatever it holds, so a 98 kB zstd chunk or a 13 MB
LZ4 one can expand to gigabytes. Here a chunk whose header declares more than
:data:`~umbra.connectors.limits.MAX_RECORDING_RECORD_BYTES` uncompressed is refused unread, and the
inflation itself stops one byte past the declared size: a chunk that inflates to more (or less)
than its header says is refused too. Memory is bounded by the limit whatever the bytes are.

Errors are ``ValueError`` naming what was expected and what was found; the readers add the file
and the byte offset.
"""

from __future__ import annotations

import io
import zlib
from collections.abc import Iterator
from typing import Any, Protocol

import lz4.frame
import zstandard
from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import Channel, Chunk, McapRecord, Message, Schema
from mcap.stream_reader import CRCValidationError

from umbra.connectors.limits import MAX_RECORDING_RECORD_BYTES

#: Compressions a recording's chunks may use (the empty string: stored as is).
COMPRESSIONS = ("", "lz4", "zstd")


def check_chunk_size(uncompressed_size: int, limit: int = MAX_RECORDING_RECORD_BYTES) -> None:
    """ValueError when a chunk header declares more than ``limit`` bytes once inflated."""
    if uncompressed_size > limit:
        raise ValueError(
            f"a chunk declares {uncompressed_size} bytes uncompressed, more than the {limit} "
            "a recording's chunk may hold"
        )


def inflate(chunk: Chunk, limit: int = MAX_RECORDING_RECORD_BYTES) -> bytes | bytearray:
    """The uncompressed bytes of ``chunk``, exactly its declared ``uncompressed_size`` of them;
    ValueError (never more than ``limit`` bytes allocated) when it declares or holds another
    size."""
    declared = chunk.uncompressed_size
    check_chunk_size(declared, limit)
    if chunk.compression not in COMPRESSIONS:
        raise ValueError(
            f"unknown chunk compression {chunk.compression!r} (expected one of lz4, zstd or none)"
        )
    if chunk.compression == "zstd":
        data: bytes | bytearray = _zstd(chunk.data, declared)
    elif chunk.compression == "lz4":
        data = _lz4(chunk.data, declared)
    else:
        data = chunk.data
    if len(data) != declared:
        more = "more" if len(data) > declared else f"{len(data)} bytes,"
        raise ValueError(
            f"a chunk ({chunk.compression or 'stored'}) declares {declared} bytes uncompressed "
            f"but holds {more} than that"
        )
    return data


def _zstd(data: bytes, declared: int) -> bytearray:
    """At most ``declared + 1`` bytes of the zstd frame ``data`` (window bounded too), inflated
    into one buffer (no copy of the whole)."""
    window = 1 << max(20, min(27, declared.bit_length()))  # a writer's window fits its chunk
    dctx = zstandard.ZstdDecompressor(max_window_size=window)
    out = bytearray(declared + 1)
    size = 0
    with dctx.stream_reader(io.BytesIO(data), read_across_frames=False) as reader:
        view = memoryview(out)
        while size <= declared:
            got = reader.readinto(view[size:])
            if not got:
                break
            size += got
        view.release()
    del out[size:]
    return out


def _lz4(data: bytes, declared: int) -> bytes:
    """The LZ4 frame ``data`` inflated, fed a slice at a time and stopped once past ``declared``:
    a slice inflates to at most 255 times its size (and an LZ4 block to at most 4 MiB), so no
    more than ``declared`` plus a quarter of it plus :data:`_LZ4_OVERSHOOT` is ever held.
    (``max_length`` would bound it exactly, but each further call copies the unread input again:
    three times slower on camera chunks.)"""
    step = max(1 << 14, (declared // 4 + _LZ4_OVERSHOOT) // 255)
    dctx = lz4.frame.LZ4FrameDecompressor()
    view = memoryview(data)
    parts: list[bytes] = []
    size = 0
    for at in range(0, len(data), step):
        part = dctx.decompress(view[at : at + step])
        parts.append(part)
        size += len(part)
        if size > declared or dctx.eof:
            break
    return b"".join(parts)


#: Output one slice of LZ4 input may add past a chunk's declared size beyond a quarter of it
#: [bytes] (an LZ4 frame block is at most 4 MiB).
_LZ4_OVERSHOOT = 4 << 20


class _Reader:
    """``read(n)`` over a buffer, a slice at a time (``io.BytesIO`` copies a bytearray whole)."""

    def __init__(self, data: bytes | bytearray) -> None:
        self._view = memoryview(data)
        self._pos = 0

    def read(self, n: int) -> bytes:
        out = bytes(self._view[self._pos : self._pos + n])
        self._pos += len(out)
        return out


class _RecordType(Protocol):
    """A record class that reads its body from a stream (mcap's ``Schema``, ``Channel``)."""

    def read(self, stream: ReadDataStream) -> McapRecord: ...


#: Records a chunk may hold (the MCAP spec); opcodes from 0x80 are private records, skipped.
_IN_CHUNK: dict[int, _RecordType] = {Opcode.SCHEMA: Schema, Opcode.CHANNEL: Channel}
_PRIVATE = 0x80


def chunk_records(chunk: Chunk, validate_crc: bool = True) -> Iterator[McapRecord]:
    """The schemas, channels and messages of ``chunk`` in order (bounded inflation, CRC checked
    before the first is given); ValueError or CRCValidationError on damage."""
    data = inflate(chunk)
    if validate_crc and chunk.uncompressed_crc != 0:
        crc = zlib.crc32(data)
        if crc != chunk.uncompressed_crc:
            raise CRCValidationError(expected=chunk.uncompressed_crc, actual=crc, record=chunk)
    return _records(data)


def _records(data: bytes | bytearray) -> Iterator[McapRecord]:
    stream = ReadDataStream(_Reader(data))  # type: ignore[arg-type]  # it only calls read()
    while stream.count < len(data):
        start = stream.count
        if len(data) - start < 9:
            raise ValueError(f"a chunk ends inside a record header (byte {start})")
        opcode = stream.read1()
        length = stream.read8()
        if length > len(data) - stream.count:
            raise ValueError(
                f"a record at byte {start} of a chunk claims {length} bytes; "
                f"the chunk holds {len(data) - stream.count} more"
            )
        if opcode != Opcode.MESSAGE and opcode not in _IN_CHUNK and opcode < _PRIVATE:
            raise ValueError(
                f"a record with opcode 0x{opcode:02x} at byte {start} of a chunk, which holds only "
                "schemas, channels and messages"
            )
        body = stream.count
        record: Any = None
        if opcode == Opcode.MESSAGE:
            record = Message.read(stream, length)
        elif opcode in _IN_CHUNK:
            record = _IN_CHUNK[opcode].read(stream)
        if stream.count - body > length:
            raise ValueError(f"a record at byte {start} of a chunk runs past its own length")
        stream.read(length - (stream.count - body))
        if record is not None:
            yield record
