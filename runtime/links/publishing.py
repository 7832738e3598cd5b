"""The producer's end of one link: one zenoh publisher per output, whatever the number of its
consumers.

Events never drop: an events output (declared ``events``: operator actions, gripper, paths)
publishes with congestion control BLOCK; state (images, contours, poses, joint states, statuses,
twists) is latest-only: DROP, so a congested link loses old samples rather than queueing them.
Frames go at data priority, everything else above them; all are ``express`` (no batching
delay). Large samples go through this process's frame pool when every consumer is on this host
(``umbra.runtime.links.pool_handoff``), otherwise through zenoh's shared memory
(``umbra.runtime.links.shm``), which zenoh turns into bytes for a consumer on another host. Every
sample carries this session's id (zenoh ``source_info``): consumers trust nothing else.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from functools import partial
from typing import Any

import zenoh

from umbra.connectors.codec import FRAME_MAGIC, FRAMED_MIN_BYTES, FRAMED_VERSION, Codec
from umbra.connectors.compact import COMPACT_VERSION
from umbra.connectors.messages import Message
from umbra.connectors.ports import Sink
from umbra.runtime.graph.plan import LinkPlan
from umbra.runtime.links.shm import ShmWriter
from umbra.runtime.links.stats import PublishStats
from umbra.runtime.links.wire import sample_encoding


def link_priority(link: LinkPlan) -> zenoh.Priority:
    """The zenoh priority of ``link``'s samples (and of the end of its stream)."""
    return zenoh.Priority.DATA if link.bulk else zenoh.Priority.DATA_HIGH


def declare_publisher(session: zenoh.Session, link: LinkPlan) -> Any:
    """The zenoh publisher of ``link``'s output, with the link's quality of service."""
    return session.declare_publisher(
        link.key,
        encoding=sample_encoding(link.msg_type.__name__, COMPACT_VERSION),  # docs/wire-format.md
        congestion_control=(
            zenoh.CongestionControl.BLOCK if link.reliable else zenoh.CongestionControl.DROP
        ),
        priority=link_priority(link),
        express=True,
    )


def end_stream(session: zenoh.Session, pub: Any, priority: zenoh.Priority) -> None:
    """Mark the end of ``pub``'s stream: a ``delete`` on its key stamped as its samples are,
    behind them (their ``priority``), and never dropped (``BLOCK``, even where the samples may
    be: a reader that lost it would wait for an end that never comes; wire format section 4)."""
    session.delete(
        pub.key_expr,
        congestion_control=zenoh.CongestionControl.BLOCK,
        priority=priority,
        express=True,
        source_info=zenoh.SourceInfo(pub.id, 0),
    )


def publish_sink(
    pub: Any,
    link: LinkPlan,
    stats: PublishStats,
    codec: Codec,
    shm: ShmWriter,
    *,
    stamp: bool,
    pooled: Callable[[Message], bool] | None,
    log: logging.Logger,
) -> Sink:
    """The sink that publishes each sample of ``link`` on ``pub``: through ``pooled`` when it
    takes the sample, else encoded (compact or framed) in bytes or zenoh shared memory; counted
    in ``stats``, never raising (a failure is counted and logged once)."""
    type_name = link.msg_type.__name__
    encoding = sample_encoding(type_name, COMPACT_VERSION)
    framed_encoding = sample_encoding(type_name, FRAMED_VERSION)
    encode = codec.compact_writer(link.msg_type)
    source = zenoh.SourceInfo(pub.id, 0)  # this session's id on every sample
    wrap = shm.payload
    put = partial(pub.put, source_info=source) if stamp else pub.put
    counters, threshold = shm.counters, shm.threshold

    def publish(sample: Message, now: float) -> None:
        try:
            if pooled is not None and pooled(sample):
                return
            data = encode(sample)
            size = len(data)
            # a framed sample (large arrays) says so in its encoding
            framed = size >= FRAMED_MIN_BYTES and data[:4] == FRAME_MAGIC
            if size < threshold:
                put(data, encoding=framed_encoding) if framed else put(data)
            else:
                before = counters.shm_samples
                put(wrap(data), encoding=framed_encoding if framed else encoding)
                stats.shm_samples += counters.shm_samples - before
        except Exception as exc:  # session closing, or a zenoh error: count, never raise
            stats.put_errors += 1
            if stats.put_errors == 1:
                log.warning("link `%s`: publishing failed: %s", stats.key, exc)
            return
        stats.sent += 1
        stats.bytes += size

    return publish
