"""Large samples in zenoh shared memory: one copy into a shared buffer, a reference on the wire.

A publisher on this host writes a large encoded sample (an image) into a buffer allocated from a
zenoh shared-memory pool and publishes the buffer: a subscriber in another process on the same
host receives a reference to the same memory instead of the bytes over TCP. When the subscriber
cannot map the memory (another host), zenoh sends the bytes instead; nothing changes for us.

Small samples (commands, twists) are sent as plain bytes: below ``threshold`` a shared buffer
costs more than it saves. When the pool is full (subscribers still hold old frames), the sample is
sent as plain bytes and counted, never blocked on.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import zenoh
from zenoh import shm

#: Size of the pool [bytes]: ~34 VGA frames in flight.
DEFAULT_POOL_BYTES = 32 * 1024 * 1024
#: Samples at least this large [bytes] go through shared memory.
DEFAULT_THRESHOLD = 64 * 1024


@dataclass
class ShmCounters:
    """How samples left: through shared memory, or as bytes because the pool was full."""

    shm_samples: int = 0
    pool_full: int = 0


class ShmWriter:
    """Wraps encoded samples for ``Publisher.put``: shared memory when large, else bytes."""

    def __init__(
        self,
        pool_bytes: int = DEFAULT_POOL_BYTES,
        threshold: int = DEFAULT_THRESHOLD,
        log: logging.Logger | None = None,
    ) -> None:
        self.pool_bytes = pool_bytes
        self.threshold = threshold
        self.counters = ShmCounters()
        self._log = log or logging.getLogger("umbra.links")
        self._provider: shm.ShmProvider | None = None
        self._policy = shm.GarbageCollect()  # reclaim freed buffers, never block
        self._broken = False

    def _pool(self) -> shm.ShmProvider | None:
        if self._provider is None and not self._broken:
            try:
                self._provider = shm.ShmProvider.default_backend(self.pool_bytes)
            except Exception as exc:  # no /dev/shm, or too small: plain bytes still work
                self._broken = True
                self._log.warning(
                    "zenoh shared memory unavailable (%s); large samples are sent as bytes", exc
                )
        return self._provider

    def payload(self, data: bytes) -> bytes | zenoh.ZBytes:
        """``data`` ready to publish: a shared-memory buffer holding it when large, else itself."""
        n = len(data)
        if n < self.threshold or n > self.pool_bytes:
            return data
        pool = self._pool()
        if pool is None:
            return data
        try:
            buf = pool.alloc(n, self._policy)
        except zenoh.ZError:
            self.counters.pool_full += 1
            return data
        buf[0:n] = data
        self.counters.shm_samples += 1
        placed: zenoh.ZBytes = zenoh.ZBytes(buf)
        return placed
