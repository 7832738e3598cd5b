"""Reading a recording: every record in file order, with clear errors for files that are not one.

A recording of a run that was killed has no summary and no footer, but every chunk it flushed is
complete: it is read to its last complete record and marked ``finished = False``. A file that is not
MCAP (foreign), that ends inside a record (truncated), or whose chunk fails its CRC or does not
decompress (corrupted) is refused with ``FILE: error: ...`` (a ``UserError``: exit status 2, no
traceback), saying what is wrong and where (byte offset).
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mcap.exceptions import EndOfFile, InvalidMagic, RecordLengthLimitExceeded
from mcap.records import Attachment, Channel, Footer, Header, Message, Metadata, Schema
from mcap.stream_reader import CRCValidationError, StreamReader

from connectors.errors import UserError

#: Records larger than this are refused (a corrupted length must not allocate gigabytes).
RECORD_LIMIT = 512 * 1024 * 1024


class _Counting:
    """A file wrapper that remembers where each read started (to tell a clean end from a cut)."""

    def __init__(self, f: Any) -> None:
        self._f = f
        self.pos = 0
        self.last_start = 0
        self.short = False  # a read came back with less than asked: the file stops mid-record

    def read(self, n: int = -1) -> bytes:
        self.last_start = self.pos
        data = self._f.read(n)
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
        reader = StreamReader(counting, validate_crcs=True, record_size_limit=RECORD_LIMIT)  # type: ignore[arg-type]
        try:
            for record in reader.records:
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
            raise _fail(
                path,
                _damage(
                    f"a record claims {exc.length} bytes (limit {RECORD_LIMIT})", counting, scan
                ),
            ) from None
        except Exception as exc:  # mcap, struct, lz4 and zstd raise their own types on damage
            raise _fail(path, _damage(f"{type(exc).__name__}: {exc}", counting, scan)) from None
    finally:
        f.close()


def scan_recording(path: str | Path) -> tuple[RecordingScan, list[tuple[str, int]]]:
    """One pass over the file: its scan and ``(topic, log_time_ns)`` of every message."""
    scan = RecordingScan(Path(path))
    times = [(ch.topic, msg.log_time) for ch, _s, msg in read_records(path, scan)]
    return scan, times
