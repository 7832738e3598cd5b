"""Recorded samples back as message objects: the primary channel of each recorded output.

``iter_samples`` reads a recording (``umbra.runtime.recording.reader``) and decodes every message of
a primary channel (channel metadata ``umbra.role: primary``, type in ``umbra.type``) with the
decoder of its schema; view channels (annotations, calibration, ``/tf_static``) and channels of
other tools are skipped. A message that does not decode is a ``FILE: error:`` naming the channel,
the message and its time.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mcap.records import Channel

from umbra.connectors.errors import UserError
from umbra.connectors.messages import Image, Message, message_types
from umbra.runtime.recording.encoders import decode_primary
from umbra.runtime.recording.reader import RecordingScan, read_messages
from umbra.runtime.recording.writer import META_ROLE, META_TYPE


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
) -> Iterator[tuple[bool, Callable[[], Sample]]]:
    """One job per wanted sample, in file order: ``(heavy, decode)``; calling ``decode`` decodes
    the sample, ``heavy`` says it is an image (worth a thread of its own)."""
    types: dict[int, type[Message] | None] = {}
    for channel, schema, msg in read_messages(path, topics, scan):
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
            except (ValueError, TypeError) as exc:  # TypeError: fields not of its type
                raise UserError(
                    f"{path}: error: message {msg.sequence} on `{channel.topic}` at "
                    f"{msg.log_time / 1e9:.6f} s does not decode as {name}: {exc}"
                ) from None
            return Sample(channel.topic, msg.log_time, msg.publish_time, sample)

        yield issubclass(msg_type, Image), decode


def iter_samples(
    path: str | Path, topics: Iterable[str] | None = None, scan: RecordingScan | None = None
) -> Iterator[Sample]:
    """Decoded samples in file order (only ``topics`` when given; with a ``scan`` from
    ``reader.indexed_scan``, only the chunks holding them are read)."""
    wanted = set(topics) if topics is not None else None
    for _heavy, decode in _decoder(path, wanted, scan):
        yield decode()


_END = object()


def iter_samples_parallel(
    path: str | Path,
    topics: Iterable[str] | None = None,
    workers: int = 2,
    depth: int = 16,
    scan: RecordingScan | None = None,
) -> Iterator[Sample]:
    """As :func:`iter_samples`, read ahead on a thread of its own and images decoded by
    ``workers`` threads (reading, LZ4, CRC and JPEG decoding release the GIL, so they overlap the
    caller's work), at most ``depth`` samples ahead, still in file order. An error of the file
    is raised here, after the samples before it."""
    wanted = set(topics) if topics is not None else None
    ahead: queue.Queue[Any] = queue.Queue(maxsize=depth)
    stop = threading.Event()
    pool = ThreadPoolExecutor(workers, thread_name_prefix="umbra-decode")

    def put(item: Any) -> bool:
        while not stop.is_set():
            try:
                ahead.put(item, timeout=0.2)
                return True
            except queue.Full:
                continue
        return False

    def read() -> None:
        try:
            for heavy, decode in _decoder(path, wanted, scan):
                if heavy:
                    job: Future[Sample] = pool.submit(decode)
                else:  # a JSON or pose sample decodes in microseconds: not worth a hand-over
                    job = Future()
                    try:
                        job.set_result(decode())
                    except BaseException as exc:
                        job.set_exception(exc)
                if not put(job):
                    return
            put(_END)
        except BaseException as exc:  # handed to the consumer, raised in its thread
            put(exc)

    reader = threading.Thread(target=read, name="umbra-read", daemon=True)
    reader.start()
    try:
        while True:
            item = ahead.get()
            if item is _END:
                return
            if isinstance(item, BaseException):
                raise item
            yield item.result()
    finally:
        stop.set()
        pool.shutdown(wait=False, cancel_futures=True)
