"""Test-run rules shared by every test folder.

Under pytest-xdist (``-n 2``, as the README and ``.ci/run`` run the suites), the tests that load
the machine by design (``heavy``: overload, floods, whole sim trials), drive a whole run in
Chromium (``browser``), or are slow and not marked ``light`` (whole pick-ups on the real clock,
timing judged) run one at a time on one worker (``--dist loadgroup``), while the other worker
takes the rest: two of them at once would put each above the load its timing was judged at (two
pick-ups at once put two SCHED_FIFO vision processes on the two cores). Without xdist the marks
change nothing.
"""

from __future__ import annotations

import pytest

#: the xdist group of the tests that must not run beside one another
HEAVY_GROUP = "heavy"


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        slow_and_loaded = item.get_closest_marker("slow") and not item.get_closest_marker("light")
        if (
            item.get_closest_marker("heavy")
            or item.get_closest_marker("browser")
            or slow_and_loaded
        ):
            item.add_marker(pytest.mark.xdist_group(HEAVY_GROUP))
