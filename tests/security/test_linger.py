"""A run's page server serves on after the run's end, and stops once: when its time is up or
when ``end_lingering`` ends every lingering server of the process (``webdoor.linger``)."""

from __future__ import annotations

import threading

from umbra.modules.webdoor.linger import end_lingering, linger


def test_a_lingering_server_stops_once_at_its_time_or_when_lingering_ends() -> None:
    stopped: list[str] = []
    done = threading.Event()

    def stop(name: str) -> None:
        stopped.append(name)
        done.set()

    linger(lambda: stop("now"), 0.0, "t-now")  # no linger: stopped at once, in this thread
    assert stopped == ["now"]
    done.clear()
    linger(lambda: stop("timed"), 0.05, "t-timed")
    assert done.wait(5.0) and stopped == ["now", "timed"]
    linger(lambda: stop("long"), 60.0, "t-long")
    assert stopped == ["now", "timed"]  # still serving
    assert end_lingering() == 1 and stopped == ["now", "timed", "long"]
    assert end_lingering() == 0 and stopped == ["now", "timed", "long"]  # stopped once
    for timer in [t for t in threading.enumerate() if t.name == "t-long"]:
        timer.join(5.0)  # cancelled: its thread ends without calling stop again
        assert not timer.is_alive()
    assert stopped == ["now", "timed", "long"]
