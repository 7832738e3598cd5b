"""The zenoh link transport: publishers, subscribers, liveliness and counters of one process.

Key expressions (``P`` is the graph's key prefix, ``umbra/<graph>`` unless overridden):

* ``P/<module>/<port>`` — samples of one output, one publisher per output whatever the number of
  consumers; a ``delete`` on it marks the end of the stream (the producer stopped cleanly);
* ``P/_alive/<process>/<marker>/<session>/<proof>`` — a liveliness token held by each running
  process of the graph. Zenoh removes it when the process's session ends for any reason (exit,
  crash, kill -9, link lost for longer than the lease), which is how consumers learn that a
  producing process is gone. The marker names a file the process keeps in /dev/shm: a peer that
  sees the file shares this host's shared memory. ``session`` is the zenoh id of the process's
  session, which also stamps every sample it publishes; ``proof`` shows the token was made by a
  holder of the run's credentials (``runtime.links.identity``).

Trust: a consumer accepts a sample only from the live session of the process the graph names as
the link's producer (others are counted as foreign and dropped; a producer declared gone stays
gone until its token comes back, whatever arrives meanwhile), only when its size is within the
link's bound (``runtime.links.bounds``; checked before anything is copied or decoded), and only
with a plausible sequence number, tracked per producer session. A sample that overtakes its
producer's token (a new session's first samples may) is held briefly and let through, in order,
only once the token names its session.

Events never drop: an events link (its output declared ``events``: operator actions, gripper,
paths) publishes with congestion control BLOCK; state (images, contours, poses, joint states,
statuses, twists) is latest-only: DROP, so a congested link loses old samples rather than queueing
them (the consumer's scheduler likewise takes the newest, ``runtime.scheduler``). Frames go at
data priority, everything else above them; all are ``express`` (no batching delay). Large samples
are sent in one of two ways: when every consumer of the output runs on this host and no session
other than the graph's proven processes is connected (``runtime.links.wire``: an observer or a
foreign client gets the sample's bytes), through this process's frame pool
(``runtime.links.pool``: one copy, the consumer reads the shared memory in place, and the small
descriptor is sent with BLOCK so no slot is orphaned);
otherwise through zenoh's shared memory (``runtime.links.shm``), which zenoh turns into bytes for a
consumer on another host. Samples are decoded on zenoh's threads; a sample that does not decode is
counted and dropped with one log line (rate-limited), and the process keeps running.
"""

from __future__ import annotations

import itertools
import logging
import secrets
import threading
import time
from collections import deque
from collections.abc import Callable
from functools import partial
from typing import Any

import numpy as np
import zenoh

from connectors.codec import (
    FRAME_MAGIC,
    FRAMED_MIN_BYTES,
    FRAMED_VERSION,
    Codec,
    DecodeError,
    array_bytes,
    array_fields,
)
from connectors.compact import COMPACT_VERSION
from connectors.messages import Message
from connectors.ports import Sink
from runtime.graph.plan import GraphPlan, LinkPlan
from runtime.links.bounds import max_sample_bytes
from runtime.links.clock_sync import ClockSync
from runtime.links.identity import (
    ALIVE,
    Sessions,
    Token,
    alive_key,
    alive_pattern,
    parse_alive_key,
    proven,
    sign,
)
from runtime.links.pool import (
    DESCRIPTOR_MAGIC,
    FORWARD_MAGIC,
    MAX_CONSUMERS,
    FramePool,
    HostMarker,
    PoolReader,
    is_descriptor,
    is_forward,
    marker_pid,
    pid_alive,
)
from runtime.links.shm import ShmWriter
from runtime.links.stats import PublishStats, SubscribeStats
from runtime.links.wire import only_graph_peers, pool_encoding, sample_encoding

#: Seconds between the ends of stream and the withdrawal of the liveliness token at close.
END_GRACE = 0.05
#: At most one log line per key and this many seconds about undecodable samples.
ERROR_LOG_PERIOD = 5.0
#: Largest sequence number a sample may carry (2**48: a century at 80 kHz).
MAX_SEQ = 2**48
#: Largest forward jump of sequence numbers within one producer session (2**20 samples lost: an
#: hour at 290 Hz); a larger jump is implausible and dropped, so one sample cannot make every
#: later genuine one look old.
MAX_SEQ_JUMP = 2**20
#: Source ids (publishers) remembered per producer session: a producer has one or two per key.
MAX_SOURCE_IDS = 8
#: Samples a link holds while its producer's token has not arrived yet (a sample may overtake
#: the token on the way): let through, in order, if the token comes within ``MAX_HOLD_S`` and
#: names their session; dropped and counted otherwise.
MAX_HELD = 64
#: Longest a sample waits for its producer's token [s]: a command that waited longer is old.
MAX_HOLD_S = 0.1

__all__ = ["ALIVE", "ZenohTransport", "alive_key"]


class _Trust:
    """The producer session a subscription accepts samples from, and the source ids (its
    publishers' ``zenoh.EntityGlobalId``) already matched to it: the fast path is one set
    lookup."""

    __slots__ = ("ids", "token")

    def __init__(self) -> None:
        self.token: Token | None = None  #: the producer's token these ids were matched under
        self.ids: set[Any] = set()


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
        self._local = threading.local()  # one decoder per zenoh thread
        self._lock = threading.Lock()
        self._producer_of: dict[str, str] = {}
        self._consumers_of: dict[str, set[str]] = {}
        for link in plan.links:
            self._producer_of[link.key] = plan.modules[link.connection.src.module].process
            self._consumers_of.setdefault(link.key, set()).add(
                plan.modules[link.connection.dst.module].process
            )
        #: processes of the graph, indexing the flag columns of frame pools
        self._proc_index = {p: i for i, p in enumerate(sorted(self._graph_processes(plan)))}
        self._pubs: dict[str, tuple[Any, PublishStats]] = {}
        self._subs: dict[str, tuple[Any, SubscribeStats, list[Callable[[Message], None]]]] = {}
        self._arrived: dict[str, list[Callable[[], None]]] = {}
        self._alive: set[str] = set()
        self._peer_pid: dict[str, int] = {}  # processes sharing this host's /dev/shm
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
        self._last_forged_log = -ERROR_LOG_PERIOD
        self.liveliness_flaps = 0
        #: Changes whenever a producer's liveliness or the end of a stream changes (what
        #: ``producer_alive`` answers): the scheduler re-reads link states only then.
        self.state_version: int | None = 0
        self._versions = itertools.count(1)
        self._ended: set[str] = set()
        self._last_error_log: dict[str, tuple[float, int]] = {}
        self._last_refusal_log: dict[str, tuple[float, int]] = {}
        self._marker = HostMarker() if frame_pool else None
        self._pools: dict[str, FramePool] = {}
        self._reader = PoolReader()
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
        if name == self.process or name not in self._proc_index:
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
        if not up and not self._sessions.token_down(token):
            return  # the token of a session that is not (or no longer) the live one
        with self._lock:
            known = name in self._alive
            if up:
                self._alive.add(name)
                pid = marker_pid(marker) if self._marker is not None else None
                if pid is not None:
                    self._peer_pid[name] = pid
            else:
                self._alive.discard(name)
            self._state_changed()
        if up:
            self.clocks.poke()
            for release in self._releasers.get(name, ()):
                release()
        else:
            self.clocks.forget(name)  # a new session of it is measured afresh
        if up and not known:
            self._log.info("process `%s` is up (session %s)", name, session)
        elif not up and known:
            mine = [k for k, p in self._producer_of.items() if p == name and k in self._subs]
            if mine and all(k in self._ended for k in mine):
                self._log.info("process `%s` stopped (its streams ended)", name)
            else:
                self._log.warning("process `%s` is gone (zenoh liveliness lost)", name)

    def _forged(self, token: Token) -> None:
        """Count a token whose proof is wrong; log at most every ``ERROR_LOG_PERIOD`` s."""
        self.forged_tokens += 1
        now = time.monotonic()
        if now - self._last_forged_log >= ERROR_LOG_PERIOD:
            self._last_forged_log = now
            self._log.warning(
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

    # -- producer side --------------------------------------------------------------------------
    def publisher(self, link: LinkPlan) -> Sink:
        """A sink publishing the samples of ``link``'s output (once per output)."""
        if link.key in self._pubs:
            self._pubs[link.key][1].links.append(str(link.connection))
            return _no_sink
        type_name = link.msg_type.__name__
        encoding = sample_encoding(type_name, COMPACT_VERSION)  # docs/wire-format.md
        framed_encoding = sample_encoding(type_name, FRAMED_VERSION)
        pub = self._session.declare_publisher(
            link.key,
            encoding=encoding,
            congestion_control=(
                zenoh.CongestionControl.BLOCK if link.reliable else zenoh.CongestionControl.DROP
            ),
            priority=zenoh.Priority.DATA if link.bulk else zenoh.Priority.DATA_HIGH,
            express=True,
        )
        stats = PublishStats(link.key, [str(link.connection)], link.reliable)
        self._pubs[link.key] = (pub, stats)
        encode = self._codec.compact_writer(link.msg_type)
        source = zenoh.SourceInfo(pub.id, 0)  # this session's id on every sample
        wrap, log = self._shm.payload, self._log

        put = partial(pub.put, source_info=source) if self.checks else pub.put

        counters, threshold = self._shm.counters, self._shm.threshold
        pooled = self._pooled_publish(link, stats) if not link.reliable else None

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

    def _column(self, setter: str, holder: str) -> int:
        """Flag column of a pool slot held by ``holder`` on behalf of ``setter`` (the process
        that published the descriptor)."""
        return self._proc_index[setter] * len(self._proc_index) + self._proc_index[holder]

    def _pooled_publish(
        self, link: LinkPlan, stats: PublishStats
    ) -> Callable[[Message], bool] | None:
        """The frame-pool path of a best-effort output (None when this host has no /dev/shm or
        the graph has too many processes for a pool's flags)."""
        if self._marker is None or self._marker.id == "none":
            return None
        n_columns = len(self._proc_index) ** 2
        if n_columns > MAX_CONSUMERS:
            return None
        consumers = sorted(self._consumers_of.get(link.key, set()))
        columns = [self._column(self.process, c) for c in consumers]
        descriptors = self._session.declare_publisher(
            link.key,
            encoding=pool_encoding(link.msg_type.__name__),
            congestion_control=zenoh.CongestionControl.BLOCK,
            priority=zenoh.Priority.DATA,
            express=True,
        )
        descriptor_source, stamp = zenoh.SourceInfo(descriptors.id, 0), self.checks
        frame, frame_header = self._codec.frame, self._codec.frame_header
        reader, peer_pid = self._reader, self._peer_pid
        # a descriptor only while every connected session is a proven process of the graph
        only_graph = only_graph_peers(self._session, self._sessions.live_sessions)

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
                pool = self._pools.get(link.key)
                if pool is None:
                    pool = self._pools[link.key] = FramePool(size, n_columns)
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
        n = len(self._proc_index)
        for name, holder in self._proc_index.items():
            pid = pids.get(name)
            if pid is not None and not pid_alive(pid):
                pool.release_consumer([setter * n + holder for setter in range(n)])

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
    def _decoder(self) -> Codec:
        """This thread's codec."""
        try:
            return self._local.codec
        except AttributeError:
            codec = self._local.codec = Codec()
            return codec

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
        expected, key, ended = link.msg_type, link.key, self._ended
        put_kind = zenoh.SampleKind.PUT
        producer = self._producer_of.get(link.key)
        column = (
            self._column(producer, self.process)
            if producer in self._proc_index and self.process in self._proc_index
            else 0
        )
        reader, monotonic = self._reader, time.monotonic
        read_compact = self._decoder().compact_reader(expected) or (lambda data: None)
        bound = max_sample_bytes(expected, self._producer_params.get(key))
        stats.max_bytes = bound
        current, gone = self._sessions.current, self._sessions.gone
        date = self.clocks.date

        def hand_over(msg: Message) -> None:
            for d in delivers:
                d(msg)
            for hook in hooks:
                hook()

        trust, refused = _Trust(), self._refused

        held: deque[tuple[float, zenoh.Sample, bool]] = deque()
        holding = threading.Lock()

        def unowned(was_gone: bool, count: int = 1) -> None:
            """Count (``count`` 1) or un-count (-1) a sample that came while no session of the
            producer was live."""
            if was_gone:
                stats.after_gone += count
            else:
                stats.unattributed += count

        def refuse_unowned(was_gone: bool) -> None:
            if was_gone:
                refused(stats, f"`{producer}` was declared gone; only its return revives it")
            else:
                refused(stats, f"`{producer}` has not announced its session yet")

        def attributed(sample: zenoh.Sample) -> bool | None:
            """Whether ``sample`` comes from the live session of the link's producer (counted
            when not); None when it is held for the producer's token (counted as refused until
            the token lets it through)."""
            token = current.get(producer)  # type: ignore[arg-type]
            if token is None:  # not up yet, or declared gone: nobody drives the link now
                was_gone = producer in gone
                unowned(was_gone)
                if len(held) < MAX_HELD:
                    held.append((monotonic(), sample, was_gone))
                    return None
                refuse_unowned(was_gone)
                return False
            info = sample.source_info
            if info is None:
                stats.foreign += 1
                refused(stats, "it names no source session (not from the producer)")
                return False
            source = info.source_id
            zid = str(source.zid)
            if zid != token.session:
                stats.foreign += 1
                refused(stats, f"session {zid} is not `{producer}`'s live session {token.session}")
                return False
            if trust.token is not token:  # a new token of the producer: a new count
                if trust.token is not None:
                    stats.restarts += 1
                stats.last_seq = 0
                trust.token = token
                trust.ids = set()
            if len(trust.ids) < MAX_SOURCE_IDS:
                trust.ids.add(source)
            return True

        checks = self.checks

        def let_go(now: float) -> None:
            """Let the held samples go, oldest first (caller holds ``holding``): those that
            waited too long are dropped; the others are judged again now that a session may be
            live — never reviving anything, only the token does."""
            while held:
                at, sample, was_gone = held[0]
                if current.get(producer) is None and now - at < MAX_HOLD_S:  # type: ignore[arg-type]
                    return  # still waiting for the token
                held.popleft()
                if now - at >= MAX_HOLD_S:
                    refuse_unowned(was_gone)  # counted when it came
                    continue
                unowned(was_gone, -1)  # judged again, as if it came now
                before = stats.received
                handle(sample)
                stats.held += stats.received - before

        def let_go_now() -> None:
            with holding:
                let_go(monotonic())

        if producer is not None:
            self._releasers.setdefault(producer, []).append(let_go_now)

        def on_sample(sample: zenoh.Sample) -> None:
            if held:  # samples wait for the producer's token: they go first, in order
                with holding:
                    let_go(monotonic())
                    handle(sample)
                return
            handle(sample)

        def handle(sample: zenoh.Sample) -> None:
            if checks:
                info = sample.source_info
                if (
                    info is None
                    or info.source_id not in trust.ids
                    or current.get(producer) is not trust.token  # type: ignore[arg-type]
                ) and not attributed(sample):
                    return
            if sample.kind != put_kind:  # end of stream: the producer stopped cleanly
                stats.ended += 1
                ended.add(key)
                self._state_changed()
                return
            payload = sample.payload
            if checks and len(payload) > bound:  # before any copy or decode
                stats.oversize += 1
                refused(stats, f"{len(payload)} bytes, more than the {bound} allowed")
                return
            release: Callable[[], None] | None = None
            try:
                data: Any = payload.to_bytes()
                magic = data[:4]
                if magic == DESCRIPTOR_MAGIC and is_descriptor(data):
                    data, release = reader.open(data, column)
                    if len(data) > bound:
                        release()
                        stats.oversize += 1
                        refused(stats, f"a frame of {len(data)} bytes, more than {bound} allowed")
                        return
                    stats.pool_samples += 1
                    msg = self._decoder().decode(data, expected)
                elif magic == FORWARD_MAGIC and is_forward(data):
                    data, release, header = reader.open_forward(data, column)
                    if len(data) > bound:
                        release()
                        stats.oversize += 1
                        refused(stats, f"a frame of {len(data)} bytes, more than {bound} allowed")
                        return
                    stats.pool_samples += 1
                    msg = self._decoder().decode_placed(header, data, expected)
                else:  # a small sample: the compact reader, else the general path (or its error)
                    msg = read_compact(data)
                    if msg is None:
                        msg = self._decoder().decode(data, expected)
            except Exception as exc:  # DecodeError, or anything a foreign payload provokes
                if release is not None:
                    release()
                self._bad_sample(stats, exc)
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
                self._state_changed()
            date(producer, msg, hand_over)  # on our clock: at once, or once it is measured

        sub = self._session.declare_subscriber(link.key, on_sample)
        self._subs[link.key] = (sub, stats, delivers)

    def _refused(self, stats: SubscribeStats, why: str) -> None:
        """Log a refused sample: at most one line per key every ``ERROR_LOG_PERIOD`` seconds."""
        now = time.monotonic()
        last, quiet = self._last_refusal_log.get(stats.key, (-ERROR_LOG_PERIOD, 0))
        if now - last >= ERROR_LOG_PERIOD:
            more = f" ({quiet} more since the last report)" if quiet else ""
            self._log.warning(
                "link `%s`: refused a sample: %s%s; the link keeps running", stats.key, why, more
            )
            self._last_refusal_log[stats.key] = (now, 0)
        else:
            self._last_refusal_log[stats.key] = (last, quiet + 1)

    def _bad_sample(self, stats: SubscribeStats, exc: Exception) -> None:
        stats.decode_errors += 1
        reason = str(exc) if isinstance(exc, DecodeError) else f"{type(exc).__name__}: {exc}"
        stats.last_error = reason[:300]
        now = time.monotonic()
        last, quiet = self._last_error_log.get(stats.key, (-ERROR_LOG_PERIOD, 0))
        if now - last >= ERROR_LOG_PERIOD:
            more = f" ({quiet} more since the last report)" if quiet else ""
            self._log.warning(
                "link `%s`: dropped a sample that does not decode: %s; "
                "%d dropped so far%s, the link keeps running",
                stats.key,
                stats.last_error,
                stats.decode_errors,
                more,
            )
            self._last_error_log[stats.key] = (now, 0)
        else:
            self._last_error_log[stats.key] = (last, quiet + 1)

    def producer_alive(self, link: LinkPlan) -> bool:
        """Whether the process producing ``link`` is up and has not ended the stream."""
        return self._producer_of.get(link.key) in self._alive and link.key not in self._ended

    def clock_error(self, link: LinkPlan) -> float:
        """The error bound [s] of ``link``'s stamps on this process's clock (inf: unmeasured)."""
        offset = self.clocks.offsets.get(self._producer_of.get(link.key, ""))
        return float("inf") if offset is None else offset.error

    def link_age(self, link: LinkPlan, now: float | None = None) -> float:
        """Seconds since the latest sample of ``link`` arrived (monotonic; inf when none)."""
        entry = self._subs.get(link.key)
        return entry[1].age(now) if entry else float("inf")

    def inputs_ended(self) -> bool:
        """True when no more samples will come: every subscribed stream ended or its producing
        process is gone."""
        alive = self.alive_processes()
        return all(
            key in self._ended or stats.producer not in alive
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
            "clocks": self.clocks.summary(),
        }

    def close(self) -> None:
        """Mark the end of every output stream, undeclare everything, close the session."""
        if self._closed:
            return
        self._closed = True
        for pub, _stats in self._pubs.values():
            try:
                pub.delete(source_info=zenoh.SourceInfo(pub.id, 0))
            except Exception as exc:
                self._log.debug("end of stream on %s failed: %s", pub.key_expr, exc)
        if self._pubs:
            time.sleep(END_GRACE)  # ends of stream first: consumers then see a clean stop
        self.clocks.close()
        try:
            if self._token is not None:
                self._token.undeclare()
        finally:
            self._session.close()
            for pool in self._pools.values():
                pool.close()
            if self._marker is not None:
                self._marker.close()
