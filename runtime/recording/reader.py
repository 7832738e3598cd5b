"""Reading a recording: every record in file order, with clear errors for files that are not one.

A recording of a run that was killed has no summary and no footer, but every chunk it flushed is
complete: it is read to its last complete record and marked ``finished = False``. A file that is not
MCAP (foreign), that ends inside a record (truncated), or whose chunk fails its CRC or does not
decompress (corrupted) is refused with ``FILE: error: ...`` (a ``UserError``: exit status 2, no
traceback), saying what is wrong and where (byte offset).

Nothing a file declares is allocated unchecked: a record longer than the file or than
:data:`~umbra.connectors.limits.MAX_RECORDING_RECORD_BYTES` is refused before it is read, and a
chunk is inflated by :mod:`umbra.runtime.recording.chunks`, which checks its declared size first and
stops at it (a decompression bomb costs a header check, not gigabytes).

A finished recording can also be read through its summary section (:func:`indexed_scan`: channels,
schemas, statistics, metadata and the chunk index, checked against the summary's CRC, without
reading a chunk); :func:`read_messages` then reads only the chunks that hold the wanted channels,
each checked against its CRC as it is read. That is how replay reads: a long recording starts at
once, and a replay of a few channels does not decompress what it does not feed.
"""

from __future__ import annotations

import os
import re
import struct
import zlib
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mcap.data_stream import ReadDataStream
from mcap.exceptions import EndOfFile, InvalidMagic, RecordLengthLimitExceeded
from mcap.opcode import Opcode
from mcap.reader import SeekingReader
from mcap.records import (
    Attachment,
    Channel,
    Chunk,
    ChunkIndex,
    Footer,
    Header,
    Message,
    Metadata,
    Schema,
    Statistics,
)
from mcap.stream_reader import CRCValidationError, StreamReader

from umbra.connectors.errors import UserError
from umbra.connectors.limits import MAX_RECORDING_RECORD_BYTES
from umbra.runtime.recording.chunks import chunk_records


class _Counting:
    """A file wrapper that remembers where each read started (to tell a clean end from a cut), and
    never asks for more than the file holds (a length field cannot make it allocate gigabytes)."""

    def __init__(self, f: Any, size: int | None = None) -> None:
        self._f = f
        self.pos = f.tell() if size is not None else 0
        self.size = size if size is not None else os.fstat(f.fileno()).st_size
        self.last_start = 0
        self.short = False  # a read came back with less than asked: the file stops mid-record

    def read(self, n: int = -1) -> bytes:
        self.last_start = self.pos
        left = max(0, self.size - self.pos)
        if n < 0 or n > left:
            self.short = self.short or 0 < left < n
            n = left
        data: bytes = self._f.read(n)
        self.pos += len(data)
        if 0 < len(data) < n:
            self.short = True
        return data

    def readinto(self, b: Any) -> int:
        self.last_start = self.pos
        n = self._f.readinto(b)
        self.pos += n or 0
        return n or 0


@dataclass
class RecordingScan:
    """What a pass over a recording found besides its messages."""

    path: Path
    size: int = 0
    profile: str = ""
    library: str = ""
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    attachments: dict[str, Attachment] = field(default_factory=dict)
    #: False when the file has no footer (the run was killed): read up to its last full record
    finished: bool = False
    messages: int = 0
    #: from the summary section (:func:`indexed_scan`), else None and empty
    statistics: Statistics | None = None
    chunk_indexes: list[ChunkIndex] = field(default_factory=list)


def _fail(path: Path, what: str) -> UserError:
    return UserError(f"{path}: error: {what}")


def _damage(what: str, counting: _Counting, scan: RecordingScan) -> str:
    """Truncated (the read ran into the end of the file) or corrupted, with where and what."""
    where = f"near byte {counting.last_start} of {scan.size}, after {scan.messages} messages"
    if counting.short or counting.pos >= scan.size:
        return f"truncated: the file ends inside a record ({where})"
    return f"corrupted: cannot read the record {where}: {what}"


def read_records(
    path: str | Path, scan: RecordingScan | None = None
) -> Iterator[tuple[Channel, Schema | None, Message]]:
    """Yield ``(channel, schema, message)`` in file order, filling ``scan`` (schemas, channels,
    metadata, attachments, finished) as records pass; UserError for a bad file."""
    path = Path(path)
    scan = scan if scan is not None else RecordingScan(path)
    scan.path = path
    try:
        f = open(path, "rb")  # noqa: SIM115 — closed in finally
    except OSError as exc:
        raise _fail(path, f"cannot read the recording: {exc.strerror}") from None
    try:
        scan.size = os.fstat(f.fileno()).st_size
        if scan.size == 0:
            raise _fail(path, "empty file (0 bytes), not an MCAP recording")
        counting = _Counting(f)
        reader = StreamReader(
            counting,  # type: ignore[arg-type]  # a file in all that mcap calls
            emit_chunks=True,
            validate_crcs=True,
            record_size_limit=_record_limit(scan.size),
        )
        try:
            for record in _unchunked(reader.records, counting, path, scan):
                if isinstance(record, Message):
                    channel = scan.channels.get(record.channel_id)
                    if channel is None:
                        raise _fail(
                            path,
                            f"corrupted: a message at byte {counting.last_start} names channel "
                            f"{record.channel_id}, which was never declared",
                        )
                    scan.messages += 1
                    yield channel, scan.schemas.get(channel.schema_id), record
                elif isinstance(record, Channel):
                    scan.channels[record.id] = record
                elif isinstance(record, Schema):
                    scan.schemas[record.id] = record
                elif isinstance(record, Metadata):
                    scan.metadata[record.name] = dict(record.metadata)
                elif isinstance(record, Attachment):
                    scan.attachments[record.name] = record
                elif isinstance(record, Header):
                    scan.profile, scan.library = record.profile, record.library
                elif isinstance(record, Footer):
                    scan.finished = True
        except InvalidMagic:
            raise _fail(
                path, "not an MCAP file (it does not start with the MCAP magic bytes)"
            ) from None
        except UserError:
            raise
        except EndOfFile:
            if counting.short:
                raise _fail(path, _damage("", counting, scan)) from None
            if counting.last_start >= scan.size and (scan.channels or scan.messages):
                scan.finished = False  # ends on a record boundary: a killed run's file
                return
            if counting.last_start >= scan.size:
                raise _fail(path, "holds no recording (nothing after the MCAP header)") from None
            raise _fail(path, _damage("", counting, scan)) from None
        except CRCValidationError as exc:
            raise _fail(
                path, _damage(f"a checksum does not match ({exc})", counting, scan)
            ) from None
        except RecordLengthLimitExceeded as exc:
            raise _fail(path, _too_long(exc, counting.pos - 9, scan)) from None
        except Exception as exc:  # mcap, struct, lz4 and zstd raise their own types on damage
            raise _fail(path, _damage(f"{type(exc).__name__}: {exc}", counting, scan)) from None
    finally:
        f.close()


def _record_limit(size: int) -> int:
    """The longest record a file of ``size`` bytes can hold and a reader accepts [bytes]."""
    return min(MAX_RECORDING_RECORD_BYTES, size)


def _too_long(exc: RecordLengthLimitExceeded, start: int, scan: RecordingScan) -> str:
    """Why a record whose header claims more than :func:`_record_limit` is refused: truncated
    when it could be a record the file was cut in, else corrupted."""
    found = re.search(r"length (\d+)", str(exc))
    claims = int(found.group(1)) if found else MAX_RECORDING_RECORD_BYTES + 1
    where = f"the record at byte {start} of {scan.size} claims {claims} bytes"
    if claims <= MAX_RECORDING_RECORD_BYTES:
        return f"truncated: the file ends inside a record ({where}, after {scan.messages} messages)"
    return (
        f"corrupted: {where}, more than the {MAX_RECORDING_RECORD_BYTES} a recording's record "
        f"may hold (after {scan.messages} messages)"
    )


def _unchunked(
    records: Iterable[Any], counting: _Counting, path: Path, scan: RecordingScan
) -> Iterator[Any]:
    """``records`` with each chunk replaced by its records, inflated within its declared size."""
    for record in records:
        if not isinstance(record, Chunk):
            yield record
            continue
        start = counting.last_start
        try:
            yield from chunk_records(record)  # damage found while reading it stops here too
        except CRCValidationError as exc:
            raise _fail(
                path, f"corrupted: the chunk near byte {start} fails its checksum ({exc})"
            ) from None
        except Exception as exc:  # lz4, zstd, struct and mcap raise their own types on damage
            raise _fail(
                path, f"corrupted: cannot read the chunk near byte {start} of {scan.size}: {exc}"
            ) from None


def scan_recording(path: str | Path) -> tuple[RecordingScan, list[tuple[str, int]]]:
    """One pass over the file: its scan and ``(topic, log_time_ns)`` of every message."""
    scan = RecordingScan(Path(path))
    times = [(ch.topic, msg.log_time) for ch, _s, msg in read_records(path, scan)]
    return scan, times


#: Footer record: opcode (1), length (8), summary start (8), summary offset start (8), CRC (4).
_FOOTER = 1 + 8 + 8 + 8 + 4
_MAGIC = 8


def indexed_scan(path: str | Path) -> RecordingScan | None:
    """The scan of a finished recording from its summary section alone (no chunk is read), or None
    when it has no usable one: no footer (a killed run), a summary that fails its CRC, no statistics
    or no chunk index (another writer). :func:`read_records` then reads the file through and says
    what is wrong with it, if anything."""
    path = Path(path)
    try:
        with open(path, "rb") as f:
            size = os.fstat(f.fileno()).st_size
            if size < 2 * _MAGIC + _FOOTER:
                return None
            reader = SeekingReader(f, validate_crcs=True, record_size_limit=_record_limit(size))
            f.seek(size - _MAGIC - _FOOTER)
            footer = f.read(_FOOTER)
            if footer[0] != Opcode.FOOTER:
                return None
            start, _offsets, crc = struct.unpack_from("<QQI", footer, 9)
            if start == 0 or start >= size:
                return None
            if crc != 0:
                f.seek(start)
                if zlib.crc32(f.read(size - _MAGIC - 4 - start)) != crc:
                    return None
            summary = reader.get_summary()
            if summary is None or summary.statistics is None or not summary.chunk_indexes:
                return None
            scan = RecordingScan(path, size=size, finished=True)
            f.seek(_MAGIC)
            header = Header.read(ReadDataStream(f)) if f.read(9)[:1] == bytes([1]) else None
            if header is not None:
                scan.profile, scan.library = header.profile, header.library
            scan.schemas = dict(summary.schemas)
            scan.channels = dict(summary.channels)
            scan.statistics = summary.statistics
            scan.messages = summary.statistics.message_count
            scan.chunk_indexes = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
            if any(c.chunk_start_offset + c.chunk_length > start for c in scan.chunk_indexes):
                return None
            scan.metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
            scan.attachments = {a.name: a for a in reader.iter_attachments()}
            return scan
    except OSError as exc:
        raise _fail(path, f"cannot read the recording: {exc.strerror}") from None
    except Exception:  # damage in the summary: the full read says what and where
        return None


def _chunk_messages(
    f: Any, index: ChunkIndex, wanted: set[int] | None, path: Path, scan: RecordingScan
) -> Iterator[Message]:
    """The messages of ``wanted`` channels in the chunk ``index`` points at (CRC checked)."""
    where = f"the chunk at byte {index.chunk_start_offset} of {scan.size}"
    try:
        f.seek(index.chunk_start_offset)
        head = f.read(9)
        if len(head) < 9 or head[0] != Opcode.CHUNK:
            raise ValueError("the chunk index points at no chunk")
        if int.from_bytes(head[1:9], "little") + 9 != index.chunk_length:
            raise ValueError("the chunk's length differs from its index entry")
        if index.uncompressed_size > MAX_RECORDING_RECORD_BYTES:
            raise ValueError(
                f"it declares {index.uncompressed_size} bytes uncompressed, more than the "
                f"{MAX_RECORDING_RECORD_BYTES} a recording's chunk may hold"
            )
        if index.chunk_length > scan.size - index.chunk_start_offset:
            raise ValueError(f"its index claims {index.chunk_length} bytes, past the file's end")
        counting = _Counting(f, scan.size)
        chunk = Chunk.read(ReadDataStream(counting))  # type: ignore[arg-type]  # reads with read()
        for record in chunk_records(chunk, validate_crc=True):
            if isinstance(record, Message) and (wanted is None or record.channel_id in wanted):
                yield record
    except CRCValidationError as exc:
        raise _fail(path, f"corrupted: {where} fails its checksum ({exc})") from None
    except Exception as exc:  # lz4, struct and mcap raise their own types on damage
        raise _fail(path, f"corrupted: cannot read {where}: {type(exc).__name__}: {exc}") from None


def read_messages(
    path: str | Path, topics: Iterable[str] | None = None, scan: RecordingScan | None = None
) -> Iterator[tuple[Channel, Schema | None, Message]]:
    """``(channel, schema, message)`` of ``topics`` (default all) in file order. With a ``scan``
    from :func:`indexed_scan`, only the chunks holding those topics are read, each checked against
    its CRC; otherwise the file is read through (:func:`read_records`). UserError for damage."""
    wanted_topics = set(topics) if topics is not None else None
    if scan is None or not scan.chunk_indexes:
        for channel, schema, msg in read_records(path, scan):
            if wanted_topics is None or channel.topic in wanted_topics:
                yield channel, schema, msg
        return
    path = Path(path)
    wanted = (
        None
        if wanted_topics is None
        else {cid for cid, ch in scan.channels.items() if ch.topic in wanted_topics}
    )
    try:
        f = open(path, "rb")  # noqa: SIM115 — closed in finally
    except OSError as exc:
        raise _fail(path, f"cannot read the recording: {exc.strerror}") from None
    try:
        for index in scan.chunk_indexes:
            if wanted is not None and wanted.isdisjoint(index.message_index_offsets):
                continue
            for msg in _chunk_messages(f, index, wanted, path, scan):
                declared = scan.channels.get(msg.channel_id)
                if declared is None:
                    raise _fail(
                        path,
                        f"corrupted: a message in the chunk at byte {index.chunk_start_offset} "
                        f"names channel {msg.channel_id}, which was never declared",
                    )
                yield declared, scan.schemas.get(declared.schema_id), msg
    finally:
        f.close()
