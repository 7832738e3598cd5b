"""One time base for the processes of a graph: each consumer's offset to every producer's clock.

Stamps and origins are seconds on the producing process's real clock (``time.monotonic()``). A
consumer brings them onto its own clock with an offset it measures by Cristian's algorithm over a
zenoh query, as NTP does over UDP: every process answers ``P/_clock/<process>`` with its clock
reading, and each consumer asks every producer it reads from, at start and then every
``PERIOD_S``::

    t1 = local clock before the query        r = the producer's reading
    t4 = local clock when the reply arrives  offset = r - (t1 + t4) / 2, |error| <= (t4 - t1) / 2

Of the last ``WINDOW`` exchanges the one with the shortest round trip is kept (the tightest
bound). A sample stamped ``s`` on the producer's clock was stamped ``s - offset`` on ours, give or
take the error; an origin is moved by the error as well, towards the past, so translating can only
make data look older than it is, never younger. On one host every process reads the same
``CLOCK_MONOTONIC`` and the measured offset is within its error bound (a few microseconds over
loopback): samples are then taken as they are. Between hosts, or between time namespaces, the
offset is real and applied. Until the first exchange with a producer completes, its samples are
held, in order (at most ``HOLD_UNDATED_S`` and ``MAX_UNDATED`` of them), and delivered once its
clock is measured; a sample still undated then goes on with origin ``-inf``, which every guard
treats as old (a status sent once at start would otherwise stay undatable for good).

A reply counts only from the zenoh session the producer's proven liveliness token names
(``umbra.runtime.links.identity``), so nobody but the producer can move its clock.
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

#: Key chunk of the clock queryables: ``P/_clock/<process>``.
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


def clock_key(prefix: str, process: str) -> str:
    """Key of ``process``'s clock queryable."""
    return f"{prefix}/{CLOCK}/{process}"


@dataclass(frozen=True)
class Offset:
    """A producer's clock minus ours [s], within ``error`` [s] (half the round trip ``rtt``)."""

    offset: float
    error: float
    rtt: float
    exchanges: int

    @property
    def same_clock(self) -> bool:
        """True when the offset is not told apart from zero (one host's monotonic clock)."""
        return abs(self.offset) <= self.error

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
    it has none): replies from any other session are ignored. ``offsets`` maps a producer to its
    latest :class:`Offset` (read from any thread: a dict read is atomic)."""

    def __init__(
        self,
        session: zenoh.Session,
        prefix: str,
        process: str,
        producers: set[str],
        session_of: Callable[[str], str | None],
        *,
        clock: Callable[[], float] = time.monotonic,
        log: logging.Logger | None = None,
    ) -> None:
        self._session = session
        self._prefix = prefix
        self._producers = sorted(producers)
        self._session_of = session_of
        self._clock = clock
        self._log = log or logging.getLogger("umbra.links")
        self.offsets: dict[str, Offset] = {}
        #: the latest offset of each producer, kept after its session ends (for the summary)
        self._latest: dict[str, Offset] = {}
        self._history: dict[str, deque[tuple[float, float]]] = {
            p: deque(maxlen=WINDOW) for p in self._producers
        }
        self._exchanges: dict[str, int] = dict.fromkeys(self._producers, 0)
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
        self._queryable = session.declare_queryable(clock_key(prefix, process), self._answer)
        self._thread: threading.Thread | None = None

    # -- the producer's side ------------------------------------------------------------------
    def _answer(self, query: zenoh.Query) -> None:
        query.reply(query.key_expr, msgspec.msgpack.encode(self._clock()))

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
                self.exchange(producer)
                self._release(producer)
            # quickly again while a producer has no offset yet, then every PERIOD_S
            self._wake.wait(0.05 if pending else PERIOD_S)
            self._wake.clear()

    def exchange(self, producer: str) -> Offset | None:
        """One query to ``producer``'s clock; the producer's offset afterwards (None: none yet)."""
        expected = self._session_of(producer)
        if expected is None:
            return self.offsets.get(producer)
        t1 = self._clock()
        try:
            replies = self._session.get(clock_key(self._prefix, producer), timeout=QUERY_TIMEOUT_S)
            for reply in replies:
                t4 = self._clock()
                ok = reply.ok
                if ok is None:
                    continue
                replier = reply.replier_id
                if replier is None or str(replier.zid) != expected:
                    self.refused_replies += 1
                    continue
                remote = float(msgspec.msgpack.decode(ok.payload.to_bytes(), type=float))
                if not math.isfinite(remote):
                    self.refused_replies += 1
                    continue
                self._record(producer, t1, remote, t4)
                break
        except Exception as exc:  # a closing session, a malformed reply: no estimate this time
            self._log.debug("clock query to `%s` failed: %s", producer, exc)
        return self.offsets.get(producer)

    def _record(self, producer: str, t1: float, remote: float, t4: float) -> None:
        rtt = max(t4 - t1, 0.0)
        history = self._history[producer]
        history.append((rtt, remote - (t1 + t4) / 2.0))
        self._exchanges[producer] += 1
        best_rtt, offset = min(history)
        found = Offset(offset, best_rtt / 2.0, best_rtt, self._exchanges[producer])
        self.offsets[producer] = self._latest[producer] = found

    def date(self, producer: str, sample: Any, deliver: Callable[[Any], None]) -> None:
        """Deliver ``sample`` of ``producer`` with its stamp and origin on our clock: at once
        when the producer's clock is measured (after any held before it), else held until it
        is (``HOLD_UNDATED_S`` at most, then as undatable)."""
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
                    self.released_undatable += 1
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
                self.released_undatable += offset is None
                first(translated(old, offset))

    def forget(self, producer: str) -> None:
        """A producer's session ended: a new one is measured afresh (its clock may differ)."""
        self.offsets.pop(producer, None)
        if producer in self._history:
            self._history[producer].clear()

    # -- summary and shutdown -----------------------------------------------------------------
    def summary(self) -> dict[str, object]:
        """Per producer: offset, error bound, best round trip, exchanges (the run summary's
        ``links.clocks``)."""
        out: dict[str, object] = {p: o.as_dict() for p, o in sorted(self._latest.items())}
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


def translated(sample: Any, offset: Offset | None) -> Any:
    """``sample`` with its stamp and origin on our clock (``on_our_clock``)."""
    translate = on_our_clock(offset)
    if translate is None:
        return sample
    stamp, origin = translate(sample.stamp, sample.origin)
    return msgspec.structs.replace(sample, stamp=stamp, origin=origin)


def on_our_clock(offset: Offset | None) -> Callable[[float, float], tuple[float, float]] | None:
    """How to bring ``(stamp, origin)`` of a producer onto our clock: None when nothing is to be
    done (one clock); for an unknown offset the origin becomes ``-inf`` (cannot be dated)."""
    if offset is None:
        return _undatable
    if offset.same_clock:
        return None
    shift, error = offset.offset, offset.error
    return lambda stamp, origin: (stamp - shift, origin - shift - error)


def _undatable(stamp: float, origin: float) -> tuple[float, float]:
    return stamp, -math.inf
