"""Recorded samples back as message objects: the primary channel of each recorded output.

``iter_samples`` reads a recording (``runtime.recording.reader``) and decodes every message of a
primary channel (channel metadata ``umbra.role: primary``, type in ``umbra.type``) with the
decoder of its schema; view channels (annotations, calibration, ``/tf_static``) and channels of
other tools are skipped. A message that does not decode is a ``FILE: error:`` naming the channel,
the message and its time.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mcap.records import Channel

from connectors.errors import UserError
from connectors.messages import Message, message_types
from runtime.recording.encoders import decode_primary
from runtime.recording.reader import RecordingScan, read_records
from runtime.recording.writer import META_ROLE, META_TYPE


@dataclass(frozen=True)
class Sample:
    """One recorded sample: topic, tick time it was sent [ns], the message."""

    topic: str
    log_ns: int
    publish_ns: int
    message: Message


def channel_type(channel: Channel) -> type[Message] | None:
    """The message type a primary channel carries, or None (a view, another tool's channel)."""
    meta = channel.metadata or {}
    if meta.get(META_ROLE) != "primary":
        return None
    return message_types().get(meta.get(META_TYPE, ""))


def _decoder(
    path: str | Path, topics: set[str] | None, scan: RecordingScan | None
) -> Iterator[Callable[[], Sample]]:
    """One job per wanted sample, in file order: calling it decodes the sample."""
    types: dict[int, type[Message] | None] = {}
    for channel, schema, msg in read_records(path, scan):
        if topics is not None and channel.topic not in topics:
            continue
        if channel.id not in types:
            types[channel.id] = channel_type(channel)
        msg_type = types[channel.id]
        if msg_type is None or schema is None:
            continue

        def decode(
            channel: Channel = channel, name: str = schema.name, msg: Any = msg, t: Any = msg_type
        ) -> Sample:
            try:
                sample = decode_primary(t, name, msg.data, msg.sequence)
            except ValueError as exc:
                raise UserError(
                    f"{path}: error: message {msg.sequence} on `{channel.topic}` at "
                    f"{msg.log_time / 1e9:.6f} s does not decode as {name}: {exc}"
                ) from None
            return Sample(channel.topic, msg.log_time, msg.publish_time, sample)

        yield decode


def iter_samples(
    path: str | Path, topics: Iterable[str] | None = None, scan: RecordingScan | None = None
) -> Iterator[Sample]:
    """Decoded samples in file order (only ``topics`` when given)."""
    wanted = set(topics) if topics is not None else None
    for decode in _decoder(path, wanted, scan):
        yield decode()


def iter_samples_parallel(
    path: str | Path, topics: Iterable[str] | None = None, workers: int = 2, depth: int = 32
) -> Iterator[Sample]:
    """As :func:`iter_samples`, decoded by ``workers`` threads at most ``depth`` samples ahead
    (JPEG and PNG decoding release the GIL), still in file order."""
    wanted = set(topics) if topics is not None else None
    with ThreadPoolExecutor(workers, thread_name_prefix="umbra-decode") as pool:
        pending: deque[Future[Sample]] = deque()
        try:
            for decode in _decoder(path, wanted, None):
                pending.append(pool.submit(decode))
                if len(pending) >= depth:
                    yield pending.popleft().result()
            while pending:
                yield pending.popleft().result()
        finally:
            for job in pending:
                job.cancel()
