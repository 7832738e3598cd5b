"""``--publish-all``: a process publishes every output of its modules for observers.

Links publish only the outputs that cross processes. With this option, a process also publishes
each other output of its modules on its key ``P/<module>/<port>`` (``docs/wire-format.md``), in
the same envelope and encoding, so an observer (``umbra topics``, a Foxglove bridge) sees every
output of the run. A slow observer never holds a process back: these publishers drop what zenoh
cannot send at once (congestion control DROP, low priority). A sample is encoded only while some
subscriber matches its key (zenoh's matching status, followed by a listener): an output nobody
watches costs one attribute read per sample, a watched one its encoding on the producer's thread.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable
from typing import Any, cast

import zenoh

from umbra.connectors.codec import FRAME_MAGIC, FRAMED_MIN_BYTES, FRAMED_VERSION, Codec
from umbra.connectors.compact import COMPACT_VERSION
from umbra.connectors.messages import Message
from umbra.connectors.module import Module
from umbra.runtime.graph.plan import GraphPlan
from umbra.runtime.links.acl import output_key
from umbra.runtime.links.publishing import end_stream
from umbra.runtime.links.wire import sample_encoding

#: Priority of the samples sent for observers only: below every link of the graph.
OBSERVED_PRIORITY = zenoh.Priority.DATA_LOW


class _Watched:
    """Whether a publisher has a matching subscriber now (set by zenoh's listener thread)."""

    __slots__ = ("matching",)

    def __init__(self) -> None:
        self.matching = False

    def __call__(self, status: Any) -> None:
        self.matching = bool(getattr(status, "matching", status))


class AllOutputs:
    """Publishers of every output of ``process``'s modules whose key is not in ``skip``."""

    def __init__(
        self,
        session: zenoh.Session,
        plan: GraphPlan,
        process: str,
        modules: dict[str, Module[Any]],
        skip: Iterable[str],
        log: logging.Logger | None = None,
    ) -> None:
        self._log = log or logging.getLogger("umbra.links")
        self._session = session
        self._codec = Codec()  # used by the scheduler's ticks only, which never overlap
        self._pubs: list[tuple[Any, Any, zenoh.SourceInfo]] = []
        self.sent = 0
        self.errors = 0
        skipped = set(skip)
        for name in plan.modules_in(process):
            for port, out in modules[name].outputs.items():
                key = output_key(plan.key_prefix, name, port)
                if key not in skipped:
                    out.sinks.append(self._publisher(session, key, out.msg_type))

    @property
    def keys(self) -> list[str]:
        """Keys published by this object."""
        return [str(pub.key_expr) for pub, _l, _s in self._pubs]

    def _publisher(self, session: zenoh.Session, key: str, msg_type: type[Message]) -> Any:
        name = msg_type.__name__
        framed_encoding = sample_encoding(name, FRAMED_VERSION)
        pub = session.declare_publisher(
            key,
            encoding=sample_encoding(name, COMPACT_VERSION),
            congestion_control=zenoh.CongestionControl.DROP,
            priority=OBSERVED_PRIORITY,
            express=True,
        )
        watched = _Watched()
        listener = pub.declare_matching_listener(watched)
        # zenoh 1.x's stub says bool; the property gives a MatchingStatus
        status = cast(zenoh.MatchingStatus, pub.matching_status)
        watched.matching = bool(status.matching)
        source = zenoh.SourceInfo(pub.id, 0)
        self._pubs.append((pub, listener, source))
        encode = self._codec.compact_writer(msg_type)

        def publish(sample: Message, now: float) -> None:
            if not watched.matching:
                return
            try:
                data = encode(sample)
                if len(data) >= FRAMED_MIN_BYTES and data[:4] == FRAME_MAGIC:
                    pub.put(data, encoding=framed_encoding, source_info=source)
                else:
                    pub.put(data, source_info=source)
                self.sent += 1
            except Exception as exc:  # the session closing, a zenoh error: never the graph's
                self.errors += 1
                if self.errors == 1:
                    self._log.warning("publishing `%s` for observers failed: %s", key, exc)

        return publish

    def close(self) -> None:
        """End every stream (a DELETE per key, ``docs/wire-format.md`` section 4), undeclare."""
        for pub, listener, _source in self._pubs:
            try:
                end_stream(self._session, pub, OBSERVED_PRIORITY)
                listener.undeclare()
                pub.undeclare()
            except Exception as exc:
                self._log.debug("closing `%s` failed: %s", pub.key_expr, exc)
        self._pubs.clear()
