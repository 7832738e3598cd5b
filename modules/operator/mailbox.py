"""Thread-safe hand-over between a module's ``step`` (scheduler thread) and the web thread.

``step`` must never block: it only takes a lock for a few assignments. The web side is an
asyncio loop; :class:`Latest` can wake it through ``loop.call_soon_threadsafe`` (non-blocking).
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import threading
from typing import Generic, TypeVar

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
