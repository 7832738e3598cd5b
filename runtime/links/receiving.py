"""The consumer's end of one link: from a zenoh sample to a decoded, dated, in-order message.

Per sample, in this order: trust (``umbra.runtime.links.trust``: only the producer's live session),
the end of stream (a ``delete``), the size bound (``umbra.runtime.links.bounds``, before anything is
copied or decoded), the way it came (a frame-pool descriptor or forward read in place, else the
compact reader, else the general decoder), a plausible sequence number (per producer session),
then the producer's clock (``umbra.runtime.links.clock_sync``: dated on this process's clock) and
the hand-over to every connection of the output. A sample that fails a check is counted in the
link's ``SubscribeStats`` and dropped, with a rate-limited log line; the link keeps running.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import zenoh

from umbra.connectors.codec import Codec, DecodeError
from umbra.connectors.messages import Message
from umbra.runtime.links.log_limit import RateLimitedLog
from umbra.runtime.links.pool import (
    DESCRIPTOR_MAGIC,
    FORWARD_MAGIC,
    PoolReader,
    is_descriptor,
    is_forward,
)
from umbra.runtime.links.stats import SubscribeStats
from umbra.runtime.links.trust import ProducerGate

#: Largest sequence number a sample may carry (2**48: a century at 80 kHz).
MAX_SEQ = 2**48
#: Largest forward jump of sequence numbers within one producer session (2**20 samples lost: an
#: hour at 290 Hz); a larger jump is implausible and dropped, so one sample cannot make every
#: later genuine one look old.
MAX_SEQ_JUMP = 2**20


class Decoders:
    """One codec per thread (zenoh delivers on several)."""

    def __init__(self) -> None:
        self._local = threading.local()

    def __call__(self) -> Codec:
        try:
            codec: Codec = self._local.codec
        except AttributeError:
            codec = self._local.codec = Codec()
        return codec


@dataclass
class Receiving:
    """What every link end of one process shares: the pool reader, the decoders, whether
    checks are on, the links whose stream ended, and how a change of link state is told."""

    reader: PoolReader
    decoders: Decoders
    checks: bool
    ended: set[str]
    state_changed: Callable[[], None]
    log: RateLimitedLog
    #: called with a link's key when its end of stream arrives (after ``state_changed``)
    stream_ended: Callable[[str], None] = lambda key: None

    def refused(self, stats: SubscribeStats, why: str) -> None:
        """Log a refused sample: at most one line per key every period."""
        self.log.warning(
            f"refused:{stats.key}",
            "link `%s`: refused a sample: %s; the link keeps running",
            stats.key,
            why,
        )

    def bad_sample(self, stats: SubscribeStats, exc: Exception) -> None:
        """Count and log a sample that does not decode."""
        stats.decode_errors += 1
        reason = str(exc) if isinstance(exc, DecodeError) else f"{type(exc).__name__}: {exc}"
        stats.last_error = reason[:300]
        self.log.warning(
            f"decode:{stats.key}",
            "link `%s`: dropped a sample that does not decode: %s; "
            "%d dropped so far, the link keeps running",
            stats.key,
            stats.last_error,
            stats.decode_errors,
        )


def receiver(
    shared: Receiving,
    key: str,
    expected: type[Message],
    gate: ProducerGate,
    *,
    column: int,
    bound: int,
    date: Callable[[str | None, Message, Callable[[Message], None]], None],
    hand_over: Callable[[Message], None],
) -> Callable[[zenoh.Sample], None]:
    """The zenoh callback of link ``key`` (messages of type ``expected``, at most ``bound``
    bytes, pool flag ``column``): checks, decodes and dates each sample, then ``hand_over``."""
    stats, producer = gate.stats, gate.producer
    checks, ended, refused = shared.checks, shared.ended, shared.refused
    reader, decoder, monotonic = shared.reader, shared.decoders, time.monotonic
    put_kind = zenoh.SampleKind.PUT
    read_compact = decoder().compact_reader(expected) or (lambda data: None)
    admits = gate.admits

    def handle(sample: zenoh.Sample) -> None:
        if checks and not admits(sample):
            return
        if sample.kind != put_kind:  # end of stream: the producer stopped cleanly
            stats.ended += 1
            ended.add(key)
            shared.state_changed()
            shared.stream_ended(key)
            return
        payload = sample.payload
        if checks and len(payload) > bound:  # before any copy or decode
            stats.oversize += 1
            refused(stats, f"{len(payload)} bytes, more than the {bound} allowed")
            return
        release: Callable[[], None] | None = None
        try:
            data: Any = payload.to_bytes()
            magic, header = data[:4], None
            if magic == DESCRIPTOR_MAGIC and is_descriptor(data):
                data, release = reader.open(data, column)
            elif magic == FORWARD_MAGIC and is_forward(data):
                data, release, header = reader.open_forward(data, column)
            if release is not None:  # a frame in the pool: bounded like any payload
                if len(data) > bound:
                    release()
                    stats.oversize += 1
                    refused(stats, f"a frame of {len(data)} bytes, more than {bound} allowed")
                    return
                stats.pool_samples += 1
                msg = (
                    decoder().decode(data, expected)
                    if header is None
                    else decoder().decode_placed(header, data, expected)
                )
            else:  # a small sample: the compact reader, else the general path (or its error)
                compact = read_compact(data)
                msg = compact if compact is not None else decoder().decode(data, expected)
        except Exception as exc:  # DecodeError, or anything a foreign payload provokes
            if release is not None:
                release()
            shared.bad_sample(stats, exc)
            return
        seq, last = msg.seq, stats.last_seq
        if checks and not (0 <= seq <= MAX_SEQ and (not last or seq - last <= MAX_SEQ_JUMP)):
            if release is not None:
                release()
            stats.implausible += 1
            refused(stats, f"sequence number {seq} after {last} is implausible")
            return
        if last and seq <= last:
            stats.stale_dropped += 1
            return
        if last and seq > last + 1:
            stats.missing += seq - last - 1
        stats.last_seq = seq
        stats.received += 1
        stats.bytes += len(data)
        stats.last_arrival = monotonic()
        if key in ended:
            ended.discard(key)
            shared.state_changed()
        date(producer, msg, hand_over)  # on our clock: at once, or once it is measured

    gate.handle = handle
    return gate.through
