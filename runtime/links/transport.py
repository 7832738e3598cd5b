"""The zenoh link transport: publishers, subscribers, liveliness and counters of one process.

Key expressions (``P`` is the graph's key prefix, ``umbra/<graph>`` unless overridden):

* ``P/<module>/<port>`` — samples of one output, one publisher per output whatever the number of
  consumers; a ``delete`` on it marks the end of the stream (the producer stopped cleanly);
* ``P/_alive/<process>/<marker>/<session>/<proof>`` — a liveliness token held by each running
  process of the graph. Zenoh removes it when the process's session ends for any reason (exit,
  crash, kill -9, link lost for longer than the lease), which is how consumers learn that a
  producing process is gone (a process on this host that the OS says lives is only late until
  its link returns: ``umbra.runtime.links.late``). The marker names a file the process keeps in
  /dev/shm: a peer that sees the file shares this host's shared memory and learns its pid.
  ``session`` is the zenoh id of the process's session, which also stamps every sample it
  publishes; ``proof`` shows the token was made by a holder of the run's credentials
  (``umbra.runtime.links.identity``).

The parts: publishing (``umbra.runtime.links.publishing``, large samples through the frame pool:
``umbra.runtime.links.pool_handoff``), receiving (``umbra.runtime.links.receiving``) behind the
producer's trust (``umbra.runtime.links.trust``), counters (``umbra.runtime.links.stats``) and
rate-limited log lines (``umbra.runtime.links.log_limit``). This class ties them to the process's
liveliness: it tracks the graph's processes' tokens, declares its own, and waits for consumers
before producing.
"""

from __future__ import annotations

import itertools
import logging
import secrets
import threading
import time
from collections.abc import Callable
from typing import Any

import zenoh

from umbra.connectors.codec import Codec
from umbra.connectors.messages import Message
from umbra.connectors.ports import Sink
from umbra.runtime.graph.plan import GraphPlan, LinkPlan
from umbra.runtime.links.bounds import max_sample_bytes
from umbra.runtime.links.clock_sync import ClockSync
from umbra.runtime.links.config import LEASE_MS
from umbra.runtime.links.end_ack import END_ACK_S, EndAcks
from umbra.runtime.links.identity import (
    ALIVE,
    Sessions,
    Token,
    alive_key,
    alive_pattern,
    parse_alive_key,
    proven,
    sign,
)
from umbra.runtime.links.late import LatePeers
from umbra.runtime.links.log_limit import RateLimitedLog
from umbra.runtime.links.pool import HostMarker, PoolReader, marker_pid
from umbra.runtime.links.pool_handoff import PoolHandoff
from umbra.runtime.links.publishing import (
    declare_publisher,
    end_stream,
    link_priority,
    publish_sink,
)
from umbra.runtime.links.receiving import Decoders, Receiving, receiver
from umbra.runtime.links.session import close_session
from umbra.runtime.links.shm import ShmWriter
from umbra.runtime.links.stats import PublishStats, SubscribeStats
from umbra.runtime.links.trust import ProducerGate

#: Seconds between the ends of stream and the withdrawal of the liveliness token at close.
END_GRACE = 0.05

__all__ = ["ALIVE", "ZenohTransport", "alive_key"]


def _no_sink(sample: Message, now: float) -> None:
    """Second and later links of one output: the output's publisher already sends the sample."""


class ZenohTransport:
    """Links of process ``process`` of ``plan`` over an open zenoh ``session``.

    Order of use: construct (declares the liveliness subscriber), let the scheduler wire
    ``publisher``/``subscribe``, then ``announce()`` (declares this process's liveliness token:
    a token seen means the process's subscriptions exist), ``wait_ready`` (producers wait for
    their consumers, so no sample is lost at start), run, ``close()``.
    """

    def __init__(
        self,
        session: zenoh.Session,
        plan: GraphPlan,
        process: str,
        *,
        log: logging.Logger | None = None,
        shm: ShmWriter | None = None,
        frame_pool: bool = True,
        checks: bool = True,
        token_key: str | None = None,
    ) -> None:
        self._session = session
        self.prefix = plan.key_prefix
        self.process = process
        self._log = log or logging.getLogger("umbra.links")
        self._shm = shm if shm is not None else ShmWriter(log=self._log)
        self._codec = Codec()  # publishing happens on the scheduler's thread only
        self._lock = threading.Lock()
        self._producer_of: dict[str, str] = {}
        self._consumers_of: dict[str, set[str]] = {}
        for link in plan.links:
            self._producer_of[link.key] = plan.modules[link.connection.src.module].process
            self._consumers_of.setdefault(link.key, set()).add(
                plan.modules[link.connection.dst.module].process
            )
        #: processes of the graph (the frame pools' flag columns index them: ``PoolHandoff``)
        self._processes = self._graph_processes(plan)
        self._warn = RateLimitedLog(self._log)
        self._pubs: dict[str, tuple[Any, PublishStats]] = {}
        self._pub_links: dict[str, LinkPlan] = {}  #: the first link of each published output
        self._subs: dict[str, tuple[Any, SubscribeStats, list[Callable[[Message], None]]]] = {}
        self._arrived: dict[str, list[Callable[[], None]]] = {}
        self._alive: set[str] = set()
        self._peer_pid: dict[str, int] = {}  # processes sharing this host's /dev/shm
        #: pid of each process of the graph on this host (its marker names it), pool or not
        self._host_pid: dict[str, int] = {}
        #: processes whose token went while their process lives: late, not gone (``late``)
        self._late = LatePeers(self._declare_gone)
        self._sessions = Sessions()
        #: per producing process: what lets the samples held for its token go (``subscribe``)
        self._releasers: dict[str, list[Callable[[], None]]] = {}
        self._session_id = str(session.zid())
        self._producer_params = {
            link.key: plan.modules[link.connection.src.module].params for link in plan.links
        }
        #: identity and size checks: samples stamped with this session's id, and received ones
        #: checked (off only to measure their cost: ``benchmarks/bench_links.py``)
        self.checks = checks
        #: key proving this process's token and checking the others' (``identity.sign``)
        self._token_key = token_key
        self.forged_tokens = 0
        self.liveliness_flaps = 0
        #: Changes whenever a producer's liveliness or the end of a stream changes (what
        #: ``producer_alive`` answers): the scheduler re-reads link states only then.
        self.state_version: int | None = 0
        self._versions = itertools.count(1)
        self._ended: set[str] = set()
        self._marker = HostMarker() if frame_pool else None
        self._reader = PoolReader()
        self._handoff = PoolHandoff(
            session,
            process,
            sorted(self._processes),
            self._consumers_of,
            marker=self._marker,
            codec=self._codec,
            reader=self._reader,
            peer_pid=self._peer_pid,
            lock=self._lock,
            live_sessions=self._sessions.live_sessions,
            stamp=checks,
        )
        #: the ends of stream read, said to their producers, and this process's own heard
        #: (``end_ack``): ``close`` waits for its consumers' word
        self.end_acks = EndAcks(
            session, self.prefix, process, self._session_id, token_key, self._log
        )
        self._receiving = Receiving(
            self._reader,
            Decoders(),
            checks,
            self._ended,
            self._state_changed,
            self._warn,
            self._stream_ended,
        )
        self._token: Any = None
        self._closed = False
        producers = {
            self._producer_of[link.key]
            for link in plan.links
            if plan.modules[link.connection.dst.module].process == process
        }
        #: the graph's one time base: our offset to each producer's clock (``clock_sync``)
        self.clocks = ClockSync(
            session, self.prefix, process, producers, self._sessions.session_of, log=self._log
        )
        self._alive_sub = session.liveliness().declare_subscriber(
            alive_pattern(self.prefix), self._on_liveliness, history=True
        )

    def _state_changed(self) -> None:
        """Give ``state_version`` a value it never had, after the change is made. Any thread may
        call this: two racing calls still leave a new value, so no change goes unseen (a
        ``+= 1`` could lose one)."""
        self.state_version = next(self._versions)

    @staticmethod
    def _graph_processes(plan: GraphPlan) -> set[str]:
        return {m.process for m in plan.modules.values()}

    # -- liveliness -----------------------------------------------------------------------------
    def _on_liveliness(self, sample: zenoh.Sample) -> None:
        token = parse_alive_key(str(sample.key_expr))
        if token is None:
            return
        name, marker, session, _proof = token
        if name == self.process or name not in self._processes:
            return  # this process, or a name the graph does not have: nobody to track
        up = sample.kind == zenoh.SampleKind.PUT
        if not proven(self._token_key, token):
            if up:
                self._forged(token)
            return
        if up and not self._sessions.token_up(token):
            self._log.warning(
                "a second token of process `%s` (session %s) while its session %s is live: "
                "ignored; only the live session drives its links",
                name,
                session,
                self._sessions.session_of(name),
            )
            return
        if not up:
            if not self._sessions.is_live(token):
                return  # the token of a session that is not (or no longer) the live one
            held = name in self._alive and not self._stopped(name)
            if held and self._late.hold(token, self._host_pid.get(name)):
                self._log.warning(
                    "process `%s` is late: its link was lost (nothing heard for %.1f s) but its "
                    "process lives; declared gone if it dies or stays silent %.0f s",
                    name,
                    LEASE_MS / 1e3,
                    self._late.bound_s,
                )
                return
            self._declare_gone(token)
            return
        late_s = self._late.back(token)
        with self._lock:
            known = name in self._alive
            self._alive.add(name)
            pid = marker_pid(marker)
            if pid is not None:
                self._host_pid[name] = pid
                if self._marker is not None:
                    self._peer_pid[name] = pid
            self._state_changed()
        self.clocks.poke()
        for release in self._releasers.get(name, ()):
            release()
        if late_s is not None:
            self._log.info(
                "process `%s` is back after %.1f s late (session %s)", name, late_s, session
            )
        elif not known:
            self._log.info("process `%s` is up (session %s)", name, session)

    def _stopped(self, name: str) -> bool:
        """Whether every stream of process ``name`` that this process takes has ended (it
        stopped cleanly; False when this process takes none)."""
        mine = [k for k, p in self._producer_of.items() if p == name and k in self._subs]
        return bool(mine) and all(k in self._ended for k in mine)

    def _stream_ended(self, key: str) -> None:
        """A stream's end arrived: once every stream of its producer that this process takes
        has ended, tell the producer (its close waits for that: ``end_ack``)."""
        producer = self._producer_of.get(key)
        if producer is None or not self._stopped(producer):
            return
        session = self._sessions.session_of(producer)
        if session is not None:
            self.end_acks.acknowledge(producer, session)

    def _declare_gone(self, token: Token) -> None:
        """The live ``token`` is gone for good: its process is gone (or stopped)."""
        name = token.process
        if not self._sessions.token_down(token):
            return
        with self._lock:
            known = name in self._alive
            self._alive.discard(name)
            self._state_changed()
        self.clocks.forget(name)  # a new session of it is measured afresh
        if not known:
            return
        if self._stopped(name):
            self._log.info("process `%s` stopped (its streams ended)", name)
        else:
            self._log.warning("process `%s` is gone (zenoh liveliness lost)", name)

    def _forged(self, token: Token) -> None:
        """Count a token whose proof is wrong; log it (rate-limited)."""
        self.forged_tokens += 1
        self._warn.warning(
            "forged",
            "a token of process `%s` (session %s) without a valid proof: ignored (%d so "
            "far); it was not declared by the graph's process",
            token.process,
            token.session,
            self.forged_tokens,
        )

    def announce(self) -> None:
        """Declare this process's liveliness token (after every subscription is declared)."""
        if self._token is None:
            marker = self._marker.id if self._marker is not None else "none"
            if marker == "none":  # no shared /dev/shm: still one marker per start
                marker = f"none-{secrets.token_hex(8)}"
            proof = sign(self._token_key, self.process, marker, self._session_id)
            self._token = self._session.liveliness().declare_token(
                alive_key(self.prefix, self.process, marker, self._session_id, proof)
            )
            self.clocks.start()

    def alive_processes(self) -> set[str]:
        """Other processes of the graph whose liveliness token is visible now."""
        with self._lock:
            return set(self._alive)

    def late_processes(self) -> dict[str, float]:
        """Other processes whose link was lost while their process lives (``late``), and for
        how long [s] each has been late."""
        return self._late.late()

    # -- producer side --------------------------------------------------------------------------
    def publisher(self, link: LinkPlan) -> Sink:
        """A sink publishing the samples of ``link``'s output (once per output)."""
        if link.key in self._pubs:
            self._pubs[link.key][1].links.append(str(link.connection))
            return _no_sink
        pub = declare_publisher(self._session, link)
        stats = PublishStats(link.key, [str(link.connection)], link.reliable)
        self._pubs[link.key] = (pub, stats)
        self._pub_links[link.key] = link
        pooled = self._handoff.publisher(link, stats) if not link.reliable else None
        return publish_sink(
            pub,
            link,
            stats,
            self._codec,
            self._shm,
            stamp=self.checks,
            pooled=pooled,
            log=self._log,
        )

    def consumers_ready(self) -> list[str]:
        """What producers still wait for: one line per output whose consumers are not all up."""
        alive = self.alive_processes()
        waiting = []
        for key, (pub, _stats) in self._pubs.items():
            missing = sorted(self._consumers_of.get(key, set()) - alive)
            status = pub.matching_status
            matching = getattr(status, "matching", status)
            if missing or not matching:
                who = ", ".join(f"`{p}`" for p in missing) or "a subscriber"
                waiting.append(f"{key} (waiting for {who})")
        return waiting

    def wait_ready(
        self, stop: threading.Event, timeout: float | None, report_every: float = 5.0
    ) -> bool:
        """Wait until every consumer process of this process's outputs is up and subscribed.
        False when ``stop`` was set first; TimeoutError after ``timeout`` seconds (None: never)."""
        start = time.monotonic()
        last_report = start - report_every + 1.0  # first word after a second
        while True:
            waiting = self.consumers_ready()
            if not waiting:
                return True
            now = time.monotonic()
            if timeout is not None and now - start > timeout:
                raise TimeoutError("; ".join(waiting))
            if now - last_report >= report_every:
                last_report = now
                self._log.info("waiting for consumers: %s", "; ".join(waiting))
            if stop.wait(0.005):
                return False

    # -- consumer side --------------------------------------------------------------------------
    def subscribe(
        self,
        link: LinkPlan,
        deliver: Callable[[Message], None],
        arrived: Callable[[], None] | None = None,
    ) -> None:
        """Call ``deliver(sample)`` for each decoded, in-order sample of ``link``, then
        ``arrived()`` once per sample (after every connection of the output got it)."""
        if link.key in self._subs:
            _sub, stats, delivers = self._subs[link.key]
            stats.links.append(str(link.connection))
            delivers.append(deliver)
            if arrived is not None and arrived not in self._arrived[link.key]:
                self._arrived[link.key].append(arrived)
            return
        stats = SubscribeStats(
            link.key, self._producer_of.get(link.key, "?"), [str(link.connection)]
        )
        delivers = [deliver]
        hooks = self._arrived[link.key] = [arrived] if arrived is not None else []
        producer = self._producer_of.get(link.key)
        bound = max_sample_bytes(link.msg_type, self._producer_params.get(link.key))
        stats.max_bytes = bound

        def hand_over(msg: Message) -> None:
            for d in delivers:
                d(msg)
            for hook in hooks:
                hook()

        gate = ProducerGate(producer, stats, self._sessions, self._receiving.refused)
        if producer is not None:
            self._releasers.setdefault(producer, []).append(gate.release)
        on_sample = receiver(
            self._receiving,
            link.key,
            link.msg_type,
            gate,
            column=self._handoff.column(producer or "", self.process),
            bound=bound,
            date=self.clocks.date,
            hand_over=hand_over,
        )
        sub = self._session.declare_subscriber(link.key, on_sample)
        self._subs[link.key] = (sub, stats, delivers)

    def producer_alive(self, link: LinkPlan) -> bool:
        """Whether the process producing ``link`` is up and has not ended the stream."""
        return self._producer_of.get(link.key) in self._alive and link.key not in self._ended

    def clock_error(self, link: LinkPlan) -> float:
        """The error bound [s] of ``link``'s stamps on this process's clock (inf: unmeasured)."""
        offset = self.clocks.offsets.get(self._producer_of.get(link.key, ""))
        return float("inf") if offset is None else offset.error

    def clock_problem(self, link: LinkPlan) -> str:
        """Why ``link``'s samples cannot be dated on this process's clock now (empty: they can)."""
        return self.clocks.problem(self._producer_of.get(link.key, ""))

    def link_age(self, link: LinkPlan, now: float | None = None) -> float:
        """Seconds since the latest sample of ``link`` arrived (monotonic; inf when none)."""
        entry = self._subs.get(link.key)
        return entry[1].age(now) if entry else float("inf")

    def inputs_ended(
        self, besides: frozenset[str] = frozenset(), closed: frozenset[str] = frozenset()
    ) -> bool:
        """True when no more samples will come: every subscribed stream ended or its producing
        process is gone (streams of the processes in ``besides`` not counted). The streams of
        the processes in ``closed`` (they ended normally, so each marked the end of its streams)
        count only once their end mark arrived: the samples they sent before it came first,
        while the producer's being gone can be seen before a busy process has read them."""
        alive = self.alive_processes()
        return all(
            key in self._ended
            or (stats.producer not in alive and stats.producer not in closed)
            or (stats.producer in besides and stats.producer not in closed)
            for key, (_s, stats, _d) in self._subs.items()
        )

    # -- summary and shutdown -------------------------------------------------------------------
    def stats(self) -> dict[str, object]:
        """Counters of every link end of this process."""
        return {
            "process": self.process,
            "prefix": self.prefix,
            "publish": [s.as_dict() for _p, s in self._pubs.values()],
            "subscribe": [s.as_dict() for _s, s, _d in self._subs.values()],
            "shm_pool_full": self._shm.counters.pool_full,
            "liveliness_flaps": self.liveliness_flaps,
            "session": self._session_id,
            "token_conflicts": self._sessions.conflicts,
            "forged_tokens": self.forged_tokens,
            "late_held": self._late.held,
            "late_returned": self._late.returned,
            "clocks": self.clocks.summary(),
        }

    def close(self, ack_s: float = END_ACK_S) -> None:
        """Mark the end of every output stream, wait at most ``ack_s`` [s] for the consumers to
        have read them (``end_ack``), undeclare everything, close the session."""
        if self._closed:
            return
        self._closed = True
        self._late.close()
        for key, (pub, _stats) in self._pubs.items():
            try:
                end_stream(self._session, pub, link_priority(self._pub_links[key]))
            except Exception as exc:
                self._log.debug("end of stream on %s failed: %s", key, exc)
        consumers = set().union(*(self._consumers_of.get(k, set()) for k in self._pubs))
        silent = self.end_acks.wait(consumers - {self.process}, self.alive_processes, ack_s)
        if silent:
            self._log.info(
                "closing although %s had not read the ends of stream within %g s",
                ", ".join(f"`{p}`" for p in sorted(silent)),
                ack_s,
            )
        if self._pubs:
            time.sleep(END_GRACE)  # ends of stream first: other readers then see a clean stop
        self.end_acks.close()
        self.clocks.close()
        try:
            if self._token is not None:
                self._token.undeclare()
        finally:
            close_session(self._session, self._log)
            self._handoff.close()
            if self._marker is not None:
                self._marker.close()
