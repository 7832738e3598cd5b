"""A page server that serves on after the run's end, so that its pages learn how the run ended.

A page whose socket was cut just before the run ended (a loaded machine, a network blip) opens
it again within a second or two; the run's page servers (the console's, the 3-D view's) keep
serving the run's last state and its verdict until their process has written its summary and
ends, at most :data:`END_LINGER_S` (the process's end cuts it short: the servers' threads are
daemons). :func:`end_lingering` stops every lingering server of the process at once (a process
that goes on after its run, such as a test session, calls it when the run is over).
"""

from __future__ import annotations

import threading
from collections.abc import Callable

#: Longest [s] a run's page server serves on after the run ended (its process writes its
#: summary and ends within seconds, longer under load).
END_LINGER_S = 20.0


class _Lingering:
    """The servers of this process serving on after their run: the one deliberate
    process-wide table of them, so that :func:`end_lingering` can stop them. Guarded by a
    lock."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        #: each lingering server's timer -> what stops it
        self.stops: dict[threading.Timer, Callable[[], object]] = {}


_LINGERING = _Lingering()


def linger(stop: Callable[[], object], linger_s: float, name: str) -> None:
    """Call ``stop`` now (``linger_s`` 0) or after ``linger_s`` [s] in a daemon thread named
    ``name`` (which the process's end, or :func:`end_lingering`, cuts short)."""
    if linger_s <= 0:
        stop()
        return

    def stop_once() -> None:
        with _LINGERING.lock:
            if _LINGERING.stops.pop(timer, None) is None:
                return  # end_lingering() stopped it already
        stop()

    timer = threading.Timer(linger_s, stop_once)
    timer.name, timer.daemon = name, True
    with _LINGERING.lock:
        _LINGERING.stops[timer] = stop
    timer.start()


def end_lingering() -> int:
    """Stop every server of this process that still lingers, now; how many there were."""
    with _LINGERING.lock:
        pending = list(_LINGERING.stops.items())
        _LINGERING.stops.clear()
    for timer, stop in pending:
        timer.cancel()
        stop()
    return len(pending)
