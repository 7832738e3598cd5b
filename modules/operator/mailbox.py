"""Thread-safe hand-over between a module's ``step`` (scheduler thread) and the web thread.

``step`` must never block: it only takes a lock for a few assignments. The web side is an
asyncio loop; :class:`Latest` can wake it through ``loop.call_soon_threadsafe`` (non-blocking).
"""

from __future__ import annotations

import collections
import contextlib
import threading
from typing import TYPE_CHECKING, Generic, TypeVar

if TYPE_CHECKING:  # imported where used: checking a graph loads this file without it
    import asyncio

T = TypeVar("T")


class Latest(Generic[T]):
    """The latest value with a version counter: a writer never waits, stale values are dropped."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._value: T | None = None
        self._version = 0
        self._waiters: list[tuple[asyncio.AbstractEventLoop, asyncio.Event]] = []

    def put(self, value: T) -> None:
        """Replace the value and wake every asyncio waiter (non-blocking)."""
        with self._lock:
            self._value = value
            self._version += 1
            waiters = list(self._waiters)
        for loop, event in waiters:
            with contextlib.suppress(RuntimeError):  # a closed loop: the server is stopping
                loop.call_soon_threadsafe(event.set)

    def get(self) -> tuple[int, T | None]:
        """``(version, value)``; version 0 means nothing was put yet."""
        with self._lock:
            return self._version, self._value

    async def wait_newer(self, version: int, timeout: float) -> tuple[int, T | None]:
        """Wait (in the web loop) until the version exceeds ``version`` or ``timeout`` [s]."""
        import asyncio

        event = asyncio.Event()
        entry = (asyncio.get_running_loop(), event)
        with self._lock:
            self._waiters.append(entry)
        try:
            current = self.get()
            if current[0] > version:
                return current
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(event.wait(), timeout)
            return self.get()
        finally:
            with self._lock:
                self._waiters.remove(entry)


class Inbox(Generic[T]):
    """A bounded FIFO from the web thread to ``step``; when full, the newest item is refused."""

    def __init__(self, capacity: int = 256) -> None:
        self._lock = threading.Lock()
        self._items: collections.deque[T] = collections.deque()
        self.capacity = capacity
        self.dropped = 0

    def put(self, item: T) -> bool:
        """Queue ``item``; False (and counted) when the inbox is full."""
        with self._lock:
            if len(self._items) >= self.capacity:
                self.dropped += 1
                return False
            self._items.append(item)
            return True

    def drain(self) -> list[T]:
        """Every queued item, oldest first, leaving the inbox empty."""
        with self._lock:
            items = list(self._items)
            self._items.clear()
        return items


class Lanes(Generic[T]):
    """From the web thread to ``step``, in lanes so that nothing a page sends can hold back the
    operator's commands or a page's arrival and departure.

    - membership (a page joined, a page left): never refused; one join and one leave per
      connection, and connections are bounded by the server;
    - the holder's lane: messages of the sessions ``step`` last said hold control
      (:meth:`set_holders`), taken whole at every drain;
    - one small lane per other session (at most ``per_session`` waiting; beyond, refused), taken
      in turns, at most ``budget`` per drain.

    :meth:`drain` gives joins first, then the holder's messages, then the others' in turns, then
    leaves: a page's last command (abort, then the page closes) is handled before its leave.
    """

    def __init__(self, per_session: int = 8, budget: int = 64, holder_capacity: int = 256) -> None:
        self._lock = threading.Lock()
        self._joins: collections.deque[T] = collections.deque()
        self._leaves: collections.deque[T] = collections.deque()
        self._holder: collections.deque[T] = collections.deque()
        self._others: dict[str, collections.deque[T]] = {}
        self._holders: frozenset[str] = frozenset()
        self.per_session = per_session
        self.budget = budget
        self.holder_capacity = holder_capacity
        self.dropped = 0

    def joined(self, item: T) -> None:
        with self._lock:
            self._joins.append(item)

    def left(self, session: str, item: T) -> None:
        """The session's page left: its waiting messages (not the holder's) go with it."""
        with self._lock:
            self._others.pop(session, None)
            self._leaves.append(item)

    def put(self, session: str, item: T) -> bool:
        """Queue a message of ``session``; False (and counted) when its lane is full."""
        with self._lock:
            if session in self._holders:
                lane, capacity = self._holder, self.holder_capacity
            else:
                lane = self._others.setdefault(session, collections.deque())
                capacity = self.per_session
            if len(lane) >= capacity:
                self.dropped += 1
                return False
            lane.append(item)
            return True

    def set_holders(self, sessions: frozenset[str]) -> None:
        """The sessions that hold control now (called by ``step``)."""
        with self._lock:
            if sessions == self._holders:
                return
            self._holders = sessions
            for session in sessions:  # a new holder's waiting messages move to its lane
                self._holder.extend(self._others.pop(session, ()))

    def drain(self) -> list[T]:
        """Joins, the holder's messages, up to ``budget`` of the others' in turns, leaves."""
        with self._lock:
            items = list(self._joins)
            self._joins.clear()
            items.extend(self._holder)
            self._holder.clear()
            taken = 0
            while self._others and taken < self.budget:
                for session in list(self._others):
                    lane = self._others[session]
                    items.append(lane.popleft())
                    taken += 1
                    if not lane:
                        del self._others[session]
                    if taken >= self.budget:
                        break
            items.extend(self._leaves)
            self._leaves.clear()
        return items
