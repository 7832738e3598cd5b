"""The one poll loop of the tests: wait for a condition, never for a fixed time."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TypeVar

T = TypeVar("T")


def wait_for(
    check: Callable[[], T | None],
    timeout_s: float,
    what: str | Callable[[], str] = "",
    interval_s: float = 0.01,
    *,
    ok: Callable[[T], object] = bool,
    step: Callable[[], object] | None = None,
) -> T:
    """Call ``check()`` until ``ok`` holds for its value (by default: the value is truthy; None
    never counts) and return that value; AssertionError naming ``what`` and the last value after
    ``timeout_s`` [s].
    ``what`` may be a callable, called only then (to add a process's latest output).

    ``step`` runs between two looks (to publish a sample again, or to let Playwright handle a
    page's events: ``step=lambda: page.wait_for_timeout(20)``), then the loop sleeps
    ``interval_s`` [s]. The last look comes at the deadline or just after it.
    """
    deadline = time.monotonic() + timeout_s
    while True:
        value = check()
        if value is not None and ok(value):
            return value
        if time.monotonic() >= deadline:
            named = what() if callable(what) else what
            raise AssertionError(
                f"timed out after {timeout_s} s waiting for {named or 'the condition'}; "
                f"last value {value!r}"
            )
        if step is not None:
            step()
        time.sleep(interval_s)
