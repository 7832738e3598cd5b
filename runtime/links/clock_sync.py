"""One time base for the processes of a graph: each consumer's offset to every producer's clock.

Stamps and origins are seconds on the producing process's real clock (``time.monotonic()``). Every
process answers clock queries on ``P/_clock/<process>/<its zenoh session id>`` with its clock
reading and its clock's identity (``umbra.runtime.links.clock_identity``: the kernel's boot and the
time namespace). Each consumer asks every producer it reads from, on the key of the producer's
proven session (``umbra.runtime.links.identity``), at start and then every ``PERIOD_S``:

* **one clock**: when the producer's identity is ours (one host, one time namespace), the offset is
  zero by construction, its error zero, and the producer is not asked again until its session
  changes;
* **another clock** (another host, a time namespace), by Cristian's algorithm, as NTP does over
  UDP::

    t1 = local clock before the query        r = the producer's reading
    t4 = local clock when the reply arrives  offset = r - (t1 + t4) / 2, |error| <= (t4 - t1) / 2

  Of the last ``WINDOW`` exchanges the one with the shortest round trip is kept (the tightest
  bound). A sample stamped ``s`` on the producer's clock was stamped ``s - offset`` on ours, and its
  origin is moved by the error as well, towards the past, *always* (however small the offset looks
  beside its bound), so translating can only make data look older than it is, never younger.

Only the producer can answer for its clock: the graph-derived access rules
(``umbra.runtime.links.acl``) let a process declare a clock queryable and reply only under its own
``P/_clock/<process>/``; a reply counts only from the session the producer's proven liveliness
token names; and replies are taken one by one as they arrive (no consolidation, every queryable
asked), so a second queryable on the key can neither hold the true reply back (which would widen
the bound) nor replace it.

Until the first exchange with a producer completes, its samples are held, in order (at most
``HOLD_UNDATED_S`` and ``MAX_UNDATED`` of them), and delivered once its clock is measured; a sample
still undated then goes on with origin ``-inf``, which every guard treats as old (a status sent once
at start would otherwise stay undatable for good). Why a producer cannot be dated
(:meth:`ClockSync.problem`) is logged, reported in the summary (``links.clocks``) and shown by the
operator's station.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import msgspec
import zenoh

from umbra.runtime.links.clock_identity import clock_identity, same_clock
from umbra.runtime.links.log_limit import RateLimitedLog

#: Key chunk of the clock queryables: ``P/_clock/<process>/<session>``.
CLOCK = "_clock"
#: Seconds between two exchanges with a producer once the first has completed.
PERIOD_S = 1.0
#: Exchanges remembered per producer; the shortest round trip among them sets the offset.
WINDOW = 8
#: Longest a clock query may take [s]; a slower answer is no use for a bound.
QUERY_TIMEOUT_S = 0.5
#: Longest a sample waits for its producer's clock to be measured [s], and how many wait.
HOLD_UNDATED_S = 1.0
MAX_UNDATED = 256
#: Largest clock reply decoded [bytes] (a reading and an identity of ~90 characters).
MAX_REPLY_BYTES = 512


class ClockReply(msgspec.Struct, array_like=True, frozen=True):
    """A producer's answer: its clock reading [s] and its clock's identity (empty: unknown)."""

    reading: float
    clock: str = ""


def clock_key(prefix: str, process: str, session: str) -> str:
    """Key of the clock queryable of ``process``'s session ``session`` (its zenoh id)."""
    return f"{prefix}/{CLOCK}/{process}/{session}"


def clock_keys(prefix: str, process: str) -> str:
    """Key expression of every clock queryable ``process`` may declare."""
    return f"{prefix}/{CLOCK}/{process}/**"


@dataclass(frozen=True)
class Offset:
    """A producer's clock minus ours [s], within ``error`` [s] (half the round trip ``rtt``);
    ``same_clock``: the producer reads our very clock (offset and error zero by construction)."""

    offset: float
    error: float
    rtt: float
    exchanges: int
    same_clock: bool = False

    def as_dict(self) -> dict[str, float | int | bool]:
        return {
            "offset_ms": self.offset * 1e3,
            "error_ms": self.error * 1e3,
            "rtt_ms": self.rtt * 1e3,
            "exchanges": self.exchanges,
            "same_clock": self.same_clock,
        }


class ClockSync:
    """Answers clock queries for ``process`` and measures the offsets of ``producers``.

    ``session_of(process)`` gives the zenoh id of the producer's live, proven session (None while
    it has none): only that session is asked, and replies from any other are refused.
    ``offsets`` maps a producer to its latest :class:`Offset` (read from any thread: a dict read
    is atomic)."""

    def __init__(
        self,
        session: zenoh.Session,
        prefix: str,
        process: str,
        producers: set[str],
        session_of: Callable[[str], str | None],
        *,
        clock: Callable[[], float] = time.monotonic,
        identity: str | None = None,
        log: logging.Logger | None = None,
    ) -> None:
        """``identity``: this process's clock identity (default: read from the kernel; a test
        gives another to stand for a process on another clock)."""
        self._session = session
        self._prefix = prefix
        self._producers = sorted(producers)
        self._session_of = session_of
        self._clock = clock
        self._identity = clock_identity() if identity is None else identity
        self._log = log or logging.getLogger("umbra.links")
        self._warn = RateLimitedLog(self._log)
        self.offsets: dict[str, Offset] = {}
        #: the latest offset of each producer, kept after its session ends (for the summary)
        self._latest: dict[str, Offset] = {}
        self._history: dict[str, deque[tuple[float, float]]] = {
            p: deque(maxlen=WINDOW) for p in self._producers
        }
        self._exchanges: dict[str, int] = dict.fromkeys(self._producers, 0)
        #: why each producer's clock is not measured now (empty: it is)
        self._why: dict[str, str] = dict.fromkeys(self._producers, "its clock was not asked yet")
        self._undatable_why: dict[str, str] = {}
        self.refused_replies = 0
        #: samples waiting for their producer's clock: (arrival, deliver, sample), in order
        self._undated: dict[str, deque[tuple[float, Callable[[Any], None], Any]]] = {
            p: deque() for p in self._producers
        }
        self._undated_locks = {p: threading.Lock() for p in self._producers}
        self.held_undated = 0
        self.released_undatable = 0
        self._wake = threading.Event()
        self._stop = threading.Event()
        own = clock_key(prefix, process, str(session.zid()))
        self._queryable = session.declare_queryable(own, self._answer)
        self._thread: threading.Thread | None = None

    # -- the producer's side ------------------------------------------------------------------
    def _answer(self, query: zenoh.Query) -> None:
        reply = ClockReply(self._clock(), self._identity)
        query.reply(query.key_expr, msgspec.msgpack.encode(reply))

    # -- the consumer's side ------------------------------------------------------------------
    def start(self) -> None:
        """Measure in a thread of its own: at once, whenever :meth:`poke` is called (a producer
        came up), and every ``PERIOD_S``."""
        if self._producers and self._thread is None:
            self._thread = threading.Thread(target=self._run, name="umbra-clock", daemon=True)
            self._thread.start()

    def poke(self) -> None:
        """Measure again now (a producer's session changed)."""
        self._wake.set()

    def _run(self) -> None:
        while not self._stop.is_set():
            pending = [p for p in self._producers if p not in self.offsets]
            for producer in self._producers:
                if self._stop.is_set():
                    return
                known = self.offsets.get(producer)
                if known is None or not known.same_clock:  # one clock: nothing to measure
                    self.exchange(producer)
                self._release(producer)
            # quickly again while a producer has no offset yet, then every PERIOD_S
            self._wake.wait(0.05 if pending else PERIOD_S)
            self._wake.clear()

    def exchange(self, producer: str) -> Offset | None:
        """One query to ``producer``'s clock; the producer's offset afterwards (None: none yet)."""
        expected = self._session_of(producer)
        if expected is None:
            if producer not in self.offsets:
                self._why[producer] = (
                    f"no live session of process `{producer}` is known (its proven liveliness "
                    "token is not seen)"
                )
            return self.offsets.get(producer)
        refused, malformed, answered = 0, "", False
        t1 = self._clock()
        try:
            replies = self._session.get(
                clock_key(self._prefix, producer, expected),
                target=zenoh.QueryTarget.ALL,
                consolidation=zenoh.ConsolidationMode.NONE,  # each reply as it comes
                timeout=QUERY_TIMEOUT_S,
            )
            for reply in replies:
                t4 = self._clock()
                ok = reply.ok
                if ok is None:
                    continue
                replier = reply.replier_id
                if replier is None or str(replier.zid) != expected:
                    refused += 1
                    continue
                answer = _decoded(ok.payload.to_bytes())
                if answer is None:
                    malformed = "its clock reply was malformed"
                    continue
                self._record(producer, t1, answer, t4)
                answered = True
                break
        except Exception as exc:  # a closing session: no estimate this time
            self._log.debug("clock query to `%s` failed: %s", producer, exc)
        self.refused_replies += refused
        if answered:
            self._why[producer] = ""
        elif producer not in self.offsets:
            why = malformed or (
                f"no clock reply from process `{producer}` (session {expected}) within "
                f"{QUERY_TIMEOUT_S:.1f} s"
            )
            if refused:
                why += (
                    f"; {refused} repl{'y' if refused == 1 else 'ies'} from other sessions refused"
                )
            self._why[producer] = why
        return self.offsets.get(producer)

    def _record(self, producer: str, t1: float, answer: ClockReply, t4: float) -> None:
        rtt = max(t4 - t1, 0.0)
        self._exchanges[producer] += 1
        if same_clock(self._identity, answer.clock):
            found = Offset(0.0, 0.0, rtt, self._exchanges[producer], same_clock=True)
        else:
            history = self._history[producer]
            history.append((rtt, answer.reading - (t1 + t4) / 2.0))
            best_rtt, offset = min(history)
            found = Offset(offset, best_rtt / 2.0, best_rtt, self._exchanges[producer])
        self.offsets[producer] = self._latest[producer] = found

    def problem(self, producer: str) -> str:
        """Why ``producer``'s samples cannot be dated now; empty when its clock is measured."""
        if producer in self.offsets:
            return ""
        return self._why.get(producer, f"process `{producer}` is not a producer of this process")

    def date(self, producer: str | None, sample: Any, deliver: Callable[[Any], None]) -> None:
        """Deliver ``sample`` of ``producer`` with its stamp and origin on our clock: at once
        when the producer's clock is measured (after any held before it), else held until it
        is (``HOLD_UNDATED_S`` at most, then as undatable)."""
        if producer is None:  # a sample that names no producer: as it is
            deliver(translated(sample, None))
            return
        lock = self._undated_locks.get(producer)
        if lock is None:  # not a producer of ours (a test's transport): as it is
            deliver(translated(sample, self.offsets.get(producer)))
            return
        with lock:
            held = self._undated[producer]
            offset = self.offsets.get(producer)
            if offset is None:
                if len(held) >= MAX_UNDATED:
                    _at, first, old = held.popleft()
                    self._undatable(producer)
                    first(translated(old, None))
                held.append((self._clock(), deliver, sample))
                self.held_undated += 1
                self.poke()
                return
            while held:  # in order: what waited goes first
                _at, first, old = held.popleft()
                first(translated(old, offset))
            deliver(translated(sample, offset))

    def _release(self, producer: str) -> None:
        """Deliver what waited for ``producer``'s clock: dated once it is measured; undatable
        once it waited ``HOLD_UNDATED_S``."""
        held, lock = self._undated.get(producer), self._undated_locks.get(producer)
        if not held or lock is None:
            return
        with lock:
            offset = self.offsets.get(producer)
            now = self._clock()
            while held and (offset is not None or now - held[0][0] >= HOLD_UNDATED_S):
                _at, first, old = held.popleft()
                if offset is None:
                    self._undatable(producer)
                first(translated(old, offset))

    def _undatable(self, producer: str) -> None:
        """Count a sample of ``producer`` passed on undatable, and say why (rate-limited)."""
        self.released_undatable += 1
        why = self.problem(producer)
        self._undatable_why[producer] = why
        self._warn.warning(
            f"undatable {producer}",
            "samples of process `%s` cannot be dated on this process's clock (%s): they go on "
            "as old, and guards refuse commands made from them",
            producer,
            why,
        )

    def forget(self, producer: str) -> None:
        """A producer's session ended: a new one is measured afresh (its clock may differ)."""
        self.offsets.pop(producer, None)
        if producer in self._history:
            self._history[producer].clear()
            self._why[producer] = f"process `{producer}` has no live session"

    # -- summary and shutdown -----------------------------------------------------------------
    def summary(self) -> dict[str, object]:
        """Per producer: offset, error bound, best round trip, exchanges, and why it could not
        be dated when that happened (the run summary's ``links.clocks``)."""
        out: dict[str, object] = {}
        for producer in self._producers:
            entry: dict[str, object] = {}
            latest = self._latest.get(producer)
            if latest is not None:
                entry.update(latest.as_dict())
            else:
                entry["measured"] = False
            why = self._undatable_why.get(producer) or (
                "" if latest is not None else self.problem(producer)
            )
            if why:
                entry["undatable_why"] = why
            out[producer] = entry
        if self.refused_replies:
            out["refused_replies"] = self.refused_replies
        if self.held_undated:
            out["held_until_dated"] = self.held_undated
        if self.released_undatable:
            out["undatable"] = self.released_undatable
        return out

    def close(self) -> None:
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout=QUERY_TIMEOUT_S + 0.5)
        try:
            self._queryable.undeclare()
        except Exception as exc:
            self._log.debug("clock queryable: %s", exc)


def _decoded(payload: bytes) -> ClockReply | None:
    """A clock reply, or None when it is too long, malformed or not finite."""
    if len(payload) > MAX_REPLY_BYTES:
        return None
    try:
        answer = msgspec.msgpack.decode(payload, type=ClockReply)
    except msgspec.DecodeError:
        return None
    return answer if math.isfinite(answer.reading) else None


def translated(sample: Any, offset: Offset | None) -> Any:
    """``sample`` with its stamp and origin on our clock (``on_our_clock``)."""
    translate = on_our_clock(offset)
    if translate is None:
        return sample
    stamp, origin = translate(sample.stamp, sample.origin)
    return msgspec.structs.replace(sample, stamp=stamp, origin=origin)


def on_our_clock(offset: Offset | None) -> Callable[[float, float], tuple[float, float]] | None:
    """How to bring ``(stamp, origin)`` of a producer onto our clock: None when nothing is to be
    done (the producer reads our very clock); for an unknown offset the origin becomes ``-inf``
    (cannot be dated); else both shifted, and the origin moved back by the error bound."""
    if offset is None:
        return _undatable
    if offset.same_clock:
        return None
    shift, error = offset.offset, offset.error
    return lambda stamp, origin: (stamp - shift, origin - shift - error)


def _undatable(stamp: float, origin: float) -> tuple[float, float]:
    return stamp, -math.inf
