"""Large samples handed to consumers on this host through this process's frame pool.

A best-effort output whose every consumer runs on this host (its liveliness marker names a
``/dev/shm`` file this process sees) and with no session but the graph's proven processes
connected (``umbra.runtime.links.wire.only_graph_peers``: an observer or a foreign client would get
a descriptor it cannot use, so it gets bytes) is sent as a small descriptor: the frame is written
once into a slot of the pool (``umbra.runtime.links.pool``), each consumer reads it in place and
clears its flag. A sample whose arrays all lie in one slot this process holds (a frame it received
and passes on) is forwarded without a copy. The descriptor goes with congestion control BLOCK, so no
slot is orphaned; slots held by a process that died are reclaimed when the pool is full.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Mapping

import numpy as np
import zenoh

from umbra.connectors.codec import FRAMED_MIN_BYTES, Codec, array_bytes, array_fields
from umbra.connectors.messages import Message
from umbra.runtime.graph.plan import LinkPlan
from umbra.runtime.links.pool import MAX_CONSUMERS, FramePool, HostMarker, PoolReader, pid_alive
from umbra.runtime.links.stats import PublishStats
from umbra.runtime.links.wire import only_graph_peers, pool_encoding


class PoolHandoff:
    """The frame pools of one process (one per output key) and their flag columns.

    ``processes``: the graph's processes, indexing the flag columns; ``consumers_of``: consumer
    processes per key; ``peer_pid``: pid of each process seen sharing this host's ``/dev/shm``
    (filled by the transport as tokens come); ``live_sessions``: zenoh ids of the graph's
    processes whose tokens are proven. :attr:`pools` holds the pools it made, by key."""

    def __init__(
        self,
        session: zenoh.Session,
        process: str,
        processes: list[str],
        consumers_of: Mapping[str, set[str]],
        *,
        marker: HostMarker | None,
        codec: Codec,
        reader: PoolReader,
        peer_pid: dict[str, int],
        lock: threading.Lock,
        live_sessions: Callable[[], list[str]],
        stamp: bool,
    ) -> None:
        self._session = session
        self.process = process
        self._index = {p: i for i, p in enumerate(processes)}
        self._consumers_of = consumers_of
        self._marker = marker
        self._codec = codec
        self._reader = reader
        self._peer_pid = peer_pid
        self._lock = lock
        self._live_sessions = live_sessions
        self.pools: dict[str, FramePool] = {}
        self._stamp = stamp

    def column(self, setter: str, holder: str) -> int:
        """Flag column of a pool slot held by ``holder`` on behalf of ``setter`` (the process
        that published the descriptor); 0 when either is not a process of the graph."""
        if setter not in self._index or holder not in self._index:
            return 0
        return self._index[setter] * len(self._index) + self._index[holder]

    def publisher(self, link: LinkPlan, stats: PublishStats) -> Callable[[Message], bool] | None:
        """The frame-pool path of a best-effort output: ``pooled(sample)`` True when it sent the
        sample (None when this host has no /dev/shm or the graph has too many processes for a
        pool's flags)."""
        if self._marker is None or self._marker.id == "none":
            return None
        n_columns = len(self._index) ** 2
        if n_columns > MAX_CONSUMERS:
            return None
        consumers = sorted(self._consumers_of.get(link.key, set()))
        columns = [self.column(self.process, c) for c in consumers]
        descriptors = self._session.declare_publisher(
            link.key,
            encoding=pool_encoding(link.msg_type.__name__),
            congestion_control=zenoh.CongestionControl.BLOCK,
            priority=zenoh.Priority.DATA,
            express=True,
        )
        descriptor_source, stamp = zenoh.SourceInfo(descriptors.id, 0), self._stamp
        frame, frame_header = self._codec.frame, self._codec.frame_header
        reader, peer_pid = self._reader, self._peer_pid
        # a descriptor only while every connected session is a proven process of the graph
        only_graph = only_graph_peers(self._session, self._live_sessions)

        array_names = array_fields(link.msg_type)

        def forward(sample: Message) -> bytes | None:
            """A forward descriptor when every array of ``sample`` lies in one held slot (a
            fresh frame is told apart by its first array, before any header is built)."""
            first = None
            for name in array_names:
                value = getattr(sample, name, None)
                if isinstance(value, np.ndarray):
                    first = value
                    break
            found = reader.slot_of(first) if first is not None else None
            if found is None:
                return None
            pool_slot = found[:2]

            def place(arr: np.ndarray) -> int:
                where = found if arr is first else reader.slot_of(arr)
                if where is None or where[:2] != pool_slot:
                    raise LookupError("not in one pool slot")
                return where[2]

            try:
                header = frame_header(sample, place)
            except LookupError:
                return None
            return reader.forward(*pool_slot, columns, header)

        def pooled(sample: Message) -> bool:
            if array_bytes(sample) < FRAMED_MIN_BYTES:
                return False
            if not all(c in peer_pid for c in consumers):  # a dict read: atomic, no lock
                return False  # a consumer on another host (or not known yet)
            if not only_graph():  # an observer or a foreign client would get a descriptor
                stats.pool_declined += 1
                return False
            descriptor = forward(sample)
            if descriptor is not None:
                size = len(descriptor)  # the frame itself stays where it is
                stats.forwarded += 1
            else:
                head, parts, size = frame(sample)
                pool = self.pools.get(link.key)
                if pool is None:
                    pool = self.pools[link.key] = FramePool(size, n_columns)
                descriptor = pool.write(head, parts, size, columns)
                if descriptor is None:
                    self._reclaim(pool)
                    descriptor = pool.write(head, parts, size, columns)
                    if descriptor is None:
                        stats.pool_full += 1
                        return False
            descriptors.put(descriptor, source_info=descriptor_source if stamp else None)
            stats.sent += 1
            stats.bytes += size
            stats.pool_samples += 1
            return True

        return pooled

    def _reclaim(self, pool: FramePool) -> None:
        """Free the slots held by processes that have died."""
        with self._lock:
            pids = dict(self._peer_pid)
        n = len(self._index)
        for name, holder in self._index.items():
            pid = pids.get(name)
            if pid is not None and not pid_alive(pid):
                pool.release_consumer([setter * n + holder for setter in range(n)])

    def close(self) -> None:
        for pool in self.pools.values():
            pool.close()
