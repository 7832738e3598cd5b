"""A page server that serves on after the run's end, so that its pages learn how the run ended.

A page whose socket was cut just before the run ended (a loaded machine, a network blip) opens
it again within a second or two; the run's page servers (the console's, the 3-D view's) keep
serving the run's last state and its verdict until their process has written its summary and
ends, at most :data:`END_LINGER_S` (the process's end cuts it short: the servers' threads are
daemons).
"""

from __future__ import annotations

import threading
from collections.abc import Callable

#: Longest [s] a run's page server serves on after the run ended (its process writes its
#: summary and ends within seconds, longer under load).
END_LINGER_S = 20.0


def linger(stop: Callable[[], object], linger_s: float, name: str) -> None:
    """Call ``stop`` now (``linger_s`` 0) or after ``linger_s`` [s] in a daemon thread named
    ``name`` (which the process's end cuts short)."""
    if linger_s <= 0:
        stop()
        return
    timer = threading.Timer(linger_s, stop)
    timer.name, timer.daemon = name, True
    timer.start()
