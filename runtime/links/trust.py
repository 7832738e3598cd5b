"""Whom a link's consumer trusts: only the live session of the process the graph names as the
link's producer.

Each subscribed link has one :class:`ProducerGate`. A sample is let in when zenoh's
``source_info`` names the producer's live session (the producer's liveliness token,
``umbra.runtime.links.identity``); the source ids (its publishers' ``zenoh.EntityGlobalId``) already
matched are remembered, so the fast path is one set lookup. A sample that comes while no session
of the producer is live (not up yet, or declared gone) is held, up to ``MAX_HELD`` samples and
``MAX_HOLD_S`` seconds, because a new session's first samples may overtake its token: when the
token comes they are judged again, in order; otherwise they are refused and counted. Nothing but
the token revives a producer declared gone.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable
from typing import Any

import zenoh

from umbra.runtime.links.identity import Sessions, Token
from umbra.runtime.links.stats import SubscribeStats

#: Source ids (publishers) remembered per producer session: a producer has one or two per key.
MAX_SOURCE_IDS = 8
#: Samples a link holds while its producer's token has not arrived yet (a sample may overtake
#: the token on the way): let through, in order, if the token comes within ``MAX_HOLD_S`` and
#: names their session; dropped and counted otherwise.
MAX_HELD = 64
#: Longest a sample waits for its producer's token [s]: a command that waited longer is old.
MAX_HOLD_S = 0.1


class ProducerGate:
    """The trust of one link: from ``producer`` (its process name in the graph), counted in
    ``stats``; ``refused(stats, why)`` logs a refusal. Set ``handle`` (the link's sample
    handler) before the first sample: held samples go through it when their token comes."""

    def __init__(
        self,
        producer: str | None,
        stats: SubscribeStats,
        sessions: Sessions,
        refused: Callable[[SubscribeStats, str], None],
    ) -> None:
        self.producer = producer
        self.stats = stats
        self._current, self._gone = sessions.current, sessions.gone
        self._refused = refused
        self.token: Token | None = None  #: the producer's token the ids were matched under
        self.ids: set[Any] = set()
        self.held: deque[tuple[float, zenoh.Sample, bool]] = deque()
        self._holding = threading.Lock()
        self.handle: Callable[[zenoh.Sample], None] = lambda sample: None

    def _live_token(self) -> Token | None:
        """The token of the producer's live session; None when it has none (or no producer)."""
        return None if self.producer is None else self._current.get(self.producer)

    def admits(self, sample: zenoh.Sample) -> bool:
        """Whether ``sample`` comes from the producer's live session (counted when not; a held
        sample is not admitted now, and counted as refused until its token lets it through)."""
        info = sample.source_info
        if info is not None and info.source_id in self.ids and self._live_token() is self.token:
            return True
        return bool(self._attributed(sample))

    def through(self, sample: zenoh.Sample) -> None:
        """Hand ``sample`` to ``handle``, after the held samples whose time has come."""
        if self.held:  # samples wait for the producer's token: they go first, in order
            with self._holding:
                self._let_go(time.monotonic())
                self.handle(sample)
            return
        self.handle(sample)

    def release(self) -> None:
        """The producer's token came: let the held samples go (any thread)."""
        with self._holding:
            self._let_go(time.monotonic())

    def _unowned(self, was_gone: bool, count: int = 1) -> None:
        """Count (``count`` 1) or un-count (-1) a sample that came while no session of the
        producer was live."""
        if was_gone:
            self.stats.after_gone += count
        else:
            self.stats.unattributed += count

    def _refuse_unowned(self, was_gone: bool) -> None:
        if was_gone:
            self._refused(
                self.stats, f"`{self.producer}` was declared gone; only its return revives it"
            )
        else:
            self._refused(self.stats, f"`{self.producer}` has not announced its session yet")

    def _attributed(self, sample: zenoh.Sample) -> bool | None:
        """Whether ``sample`` comes from the live session of the link's producer (counted
        when not); None when it is held for the producer's token."""
        stats, producer = self.stats, self.producer
        token = self._live_token()
        if token is None:  # not up yet, or declared gone: nobody drives the link now
            was_gone = producer in self._gone
            self._unowned(was_gone)
            if len(self.held) < MAX_HELD:
                self.held.append((time.monotonic(), sample, was_gone))
                return None
            self._refuse_unowned(was_gone)
            return False
        info = sample.source_info
        if info is None:
            stats.foreign += 1
            self._refused(stats, "it names no source session (not from the producer)")
            return False
        source = info.source_id
        zid = str(source.zid)
        if zid != token.session:
            stats.foreign += 1
            self._refused(
                stats, f"session {zid} is not `{producer}`'s live session {token.session}"
            )
            return False
        if self.token is not token:  # a new token of the producer: a new count
            if self.token is not None:
                stats.restarts += 1
            stats.last_seq = 0
            self.token = token
            self.ids = set()
        if len(self.ids) < MAX_SOURCE_IDS:
            self.ids.add(source)
        return True

    def _let_go(self, now: float) -> None:
        """Let the held samples go, oldest first (caller holds ``_holding``): those that
        waited too long are dropped; the others are judged again now that a session may be
        live — never reviving anything, only the token does."""
        held, stats = self.held, self.stats
        while held:
            at, sample, was_gone = held[0]
            if self._live_token() is None and now - at < MAX_HOLD_S:
                return  # still waiting for the token
            held.popleft()
            if now - at >= MAX_HOLD_S:
                self._refuse_unowned(was_gone)  # counted when it came
                continue
            self._unowned(was_gone, -1)  # judged again, as if it came now
            before = stats.received
            self.handle(sample)
            stats.held += stats.received - before
