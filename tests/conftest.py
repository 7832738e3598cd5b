"""Test-run rules shared by every test folder.

Under pytest-xdist (``-n 2``, as the README and ``.ci/run`` run the suite), the tests that load
the machine by design (``heavy``: overload, floods, whole sim trials) or drive a whole run in
Chromium (``browser``) run one at a time on one worker (``--dist loadgroup``), while the other
worker takes the rest: two of them at once would put each above the load its timing was judged
at. Without xdist the marks change nothing.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest

#: the xdist group of the tests that must not run beside one another
HEAVY_GROUP = "heavy"


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        if item.get_closest_marker("heavy") or item.get_closest_marker("browser"):
            item.add_marker(pytest.mark.xdist_group(HEAVY_GROUP))


@pytest.fixture(autouse=True)
def _no_page_server_outlives_its_test() -> Iterator[None]:
    """A run's page servers serve on after its end until its process ends
    (``umbra.modules.webdoor.linger``); a test's process goes on, so they are stopped when the
    test is over, never in the middle of another test (whose output and heap they would touch)."""
    yield
    from umbra.modules.webdoor.linger import end_lingering

    end_lingering()
