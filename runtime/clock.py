"""Clocks: ``sim`` (virtual time, as fast as the machine goes) and ``real`` (monotonic wall time).

Both read in seconds. The sim clock starts at 0 and jumps to each due time; the real clock reads
``time.monotonic()`` (system-wide on Linux, so stamps from processes on one host compare) and
sleeps until each due time, waking early when a link delivers a sample.
"""

from __future__ import annotations

import threading
import time


class SimClock:
    """Virtual time: ``wait_until`` jumps straight to the due time."""

    kind = "sim"

    def __init__(self, start: float = 0.0) -> None:
        self._now = start

    def now(self) -> float:
        return self._now

    def wait_until(self, t: float, wake: threading.Event | None = None) -> None:
        if t > self._now:
            self._now = t


class RealClock:
    """Monotonic wall time; ``wait_until`` sleeps to an absolute deadline (or a wake-up event)."""

    kind = "real"

    def now(self) -> float:
        return time.monotonic()

    def wait_until(self, t: float, wake: threading.Event | None = None) -> None:
        delay = t - time.monotonic()
        if delay <= 0:
            return
        if wake is None:
            time.sleep(delay)
        else:
            wake.wait(delay)
            wake.clear()


def make_clock(kind: str) -> SimClock | RealClock:
    """The clock named ``kind`` ("sim" or "real")."""
    return SimClock() if kind == "sim" else RealClock()
