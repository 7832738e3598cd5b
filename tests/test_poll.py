"""The tests' one poll loop (tests/poll.py), on a real clock and a real thread."""

from __future__ import annotations

import threading
import time

import pytest

from tests.poll import wait_for


def test_it_returns_the_first_value_that_holds_as_soon_as_it_holds() -> None:
    flag = threading.Event()
    threading.Timer(0.1, flag.set).start()
    started = time.monotonic()
    assert wait_for(lambda: flag.is_set() and "set", 5.0, "the flag") == "set"
    assert 0.1 <= time.monotonic() - started < 1.0  # when it held, not at the deadline


def test_ok_judges_values_that_are_falsy() -> None:
    values = iter([3, 2, 1, 0, -1])
    assert wait_for(lambda: next(values), 5.0, "zero", ok=lambda v: v == 0) == 0


def test_a_timeout_names_what_it_waited_for_and_the_last_value() -> None:
    reads: list[float] = []

    def read() -> int:
        reads.append(time.monotonic())
        return len(reads)

    started = time.monotonic()
    with pytest.raises(AssertionError) as info:
        wait_for(read, 0.2, "a billion reads", ok=lambda n: n >= 1e9)
    assert 0.2 <= time.monotonic() - started < 1.0
    assert str(info.value) == (
        f"timed out after 0.2 s waiting for a billion reads; last value {len(reads)}"
    )
    assert len(reads) >= 5  # it looked again and again (every 10 ms)
    assert reads[-1] - started >= 0.2  # the last look at the deadline


def test_a_lazy_what_is_called_only_on_timeout_and_step_runs_between_looks() -> None:
    named: list[str] = []
    steps: list[float] = []

    def what() -> str:
        named.append("called")
        return "the log's end: tail"

    with pytest.raises(AssertionError, match="waiting for the log's end: tail"):
        wait_for(lambda: False, 0.05, what, step=lambda: steps.append(time.monotonic()))
    assert named == ["called"] and len(steps) >= 2
    assert wait_for(lambda: True, 1.0, what) is True
    assert named == ["called"]
