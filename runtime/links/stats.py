"""Counters of one link end, for the run summary and for a consumer's view of the link."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any


@dataclass
class PublishStats:
    """Producer side of a key: samples and bytes sent, how, and failures."""

    key: str
    links: list[str] = field(default_factory=list)
    reliable: bool = True
    sent: int = 0
    bytes: int = 0
    shm_samples: int = 0  #: through zenoh shared memory
    pool_samples: int = 0  #: through this process's frame pool (read in place by consumers)
    pool_full: int = 0  #: large samples sent the zenoh way because no pool slot was free
    #: large samples sent the zenoh way because a session other than the graph's processes was
    #: connected (an observer, a foreign client: it gets bytes, never a pool descriptor)
    pool_declined: int = 0
    forwarded: int = 0  #: samples passed on from a pool slot they arrived in, without a copy
    put_errors: int = 0

    def as_dict(self) -> dict[str, Any]:
        return {
            "key": self.key,
            "side": "publish",
            "links": self.links,
            "mode": "reliable/block" if self.reliable else "best-effort/drop",
            "sent": self.sent,
            "bytes": self.bytes,
            "shm_samples": self.shm_samples,
            "pool_samples": self.pool_samples,
            "pool_full": self.pool_full,
            "pool_declined": self.pool_declined,
            "forwarded": self.forwarded,
            "put_errors": self.put_errors,
        }


@dataclass
class SubscribeStats:
    """Consumer side of a key: samples received, what was wrong with the others, and when the
    latest arrived (``time.monotonic()`` seconds)."""

    key: str
    producer: str
    links: list[str] = field(default_factory=list)
    received: int = 0
    bytes: int = 0
    decode_errors: int = 0
    missing: int = 0  #: sequence numbers skipped (samples lost on the way or dropped as old)
    stale_dropped: int = 0  #: samples older than one already delivered (dropped)
    restarts: int = 0  #: a new session of the producer took over (its count starts again)
    foreign: int = 0  #: samples from a session other than the producer's live one (dropped)
    after_gone: int = 0  #: samples while the producer was declared gone (dropped, never revive)
    unattributed: int = 0  #: samples before the producer's token was seen (dropped)
    held: int = 0  #: samples that beat their producer's token, held and then let through
    oversize: int = 0  #: samples larger than ``max_bytes`` (dropped before decoding)
    implausible: int = 0  #: sequence numbers out of range or jumping too far ahead (dropped)
    max_bytes: int = 0  #: the largest sample this link accepts [bytes]
    ended: int = 0  #: end-of-stream markers received (the producer stopped cleanly)
    pool_samples: int = 0  #: samples read in place from the producer's frame pool
    last_seq: int = 0
    last_arrival: float = -math.inf
    last_error: str = ""

    def age(self, now: float | None = None) -> float:
        """Seconds since the latest sample arrived (infinite when none has)."""
        return (time.monotonic() if now is None else now) - self.last_arrival

    def as_dict(self) -> dict[str, Any]:
        return {
            "key": self.key,
            "side": "subscribe",
            "producer": self.producer,
            "links": self.links,
            "received": self.received,
            "bytes": self.bytes,
            "decode_errors": self.decode_errors,
            "missing": self.missing,
            "stale_dropped": self.stale_dropped,
            "restarts": self.restarts,
            "foreign": self.foreign,
            "after_gone": self.after_gone,
            "unattributed": self.unattributed,
            "held": self.held,
            "oversize": self.oversize,
            "implausible": self.implausible,
            "max_bytes": self.max_bytes,
            "ended": self.ended,
            "pool_samples": self.pool_samples,
            "last_seq": self.last_seq,
            "last_error": self.last_error,
        }


def link_lines(stats: dict[str, Any]) -> list[str]:
    """Readable lines for the ``links`` part of a process summary (``ZenohTransport.stats()``)."""
    lines = []
    for s in stats.get("publish", []):
        lines.append(
            f"  link {s['key']} ({s['mode']}): sent {s['sent']}, "
            f"{s['pool_samples']} through the frame pool ({s.get('forwarded', 0)} forwarded "
            f"in place), {s['shm_samples']} through zenoh shared memory, "
            f"{s['put_errors']} errors"
        )
        if s.get("pool_declined"):
            lines[-1] += f"; {s['pool_declined']} sent as bytes (an observer was connected)"
    for s in stats.get("subscribe", []):
        lines.append(
            f"  link {s['key']} (from `{s['producer']}`): received {s['received']}, "
            f"missing {s['missing']}, undecodable {s['decode_errors']}, "
            f"old dropped {s['stale_dropped']}"
        )
        refused = {
            "foreign": s.get("foreign", 0),
            "after gone": s.get("after_gone", 0),
            "unattributed": s.get("unattributed", 0),
            "oversize": s.get("oversize", 0),
            "implausible seq": s.get("implausible", 0),
        }
        if any(refused.values()):
            lines[-1] += "; refused " + ", ".join(f"{k} {v}" for k, v in refused.items() if v)
    return lines
