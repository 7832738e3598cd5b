"""Samples waiting for one of the live server's encoding threads: the newest of each topic.

A viewer watches the present, so a topic has at most one sample waiting: a newer one takes its
place (the older is dropped and counted) and keeps its turn. Topics are served in the order they
became ready, so a busy stream cannot crowd out another however often it sends: under CPU
starvation every watched topic still gets its newest sample through, at a lower rate. (A
first-in-first-out queue that drops what does not fit served whichever topics happened to put
right after a get: on a loaded machine the arm's joint states got none in 6 s while its link
poses flowed.) The waiting samples are bounded by the number of topics.
"""

from __future__ import annotations

import threading
from typing import Any

#: What :meth:`LatestLane.get` returns once the lane is closed.
CLOSED = object()


class LatestLane:
    """At most one waiting item per topic, served in turn (see the module docstring)."""

    def __init__(self) -> None:
        self._ready = threading.Condition(threading.Lock())
        self._waiting: dict[str, Any] = {}  #: topic -> item; insertion order is the turn
        self._closed = False

    def put(self, topic: str, item: Any) -> bool:
        """Hold ``item`` as ``topic``'s newest; False when it replaced one still waiting (a
        drop). Never waits beyond the lane's lock."""
        with self._ready:
            replaced = topic in self._waiting
            self._waiting[topic] = item  # a replaced key keeps its place in the turn
            self._ready.notify()
        return not replaced

    def get(self, timeout: float) -> Any:
        """The next topic's item, ``None`` after ``timeout`` [s] with nothing waiting, or
        :data:`CLOSED` once :meth:`close` was called."""
        with self._ready:
            if not self._waiting and not self._closed:
                self._ready.wait(timeout)
            if self._closed:
                return CLOSED
            if not self._waiting:
                return None
            topic = next(iter(self._waiting))
            return self._waiting.pop(topic)

    def close(self) -> None:
        """Wake the thread that waits; from now on :meth:`get` returns :data:`CLOSED`."""
        with self._ready:
            self._closed = True
            self._ready.notify_all()

    def __len__(self) -> int:
        with self._ready:
            return len(self._waiting)
