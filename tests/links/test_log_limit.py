"""One rate-limited log for the link transport: one line per key and period, the rest counted."""

from __future__ import annotations

import logging

from umbra.runtime.links import log_limit
from umbra.runtime.links.log_limit import RateLimitedLog


def test_one_line_per_key_and_period_with_the_held_back_count(monkeypatch, caplog) -> None:
    clock = iter([100.0, 100.1, 100.2, 100.3, 106.0, 106.1])
    monkeypatch.setattr(log_limit.time, "monotonic", lambda: next(clock))
    limited = RateLimitedLog(logging.getLogger("umbra.test"), period=5.0)
    with caplog.at_level(logging.WARNING, logger="umbra.test"):
        said = [
            limited.warning("a", "link `%s`: %s", "a", "first"),  # 100.0: said
            limited.warning("a", "link `%s`: %s", "a", "second"),  # 100.1: held back
            limited.warning("b", "link `%s`: %s", "b", "other key"),  # 100.2: said
            limited.warning("a", "link `%s`: %s", "a", "third"),  # 100.3: held back
            limited.warning("a", "link `%s`: %s", "a", "fourth"),  # 106.0: said, 2 held
            limited.warning("a", "link `%s`: %s", "a", "fifth"),  # 106.1: held back
        ]
    assert said == [True, False, True, False, True, False]
    assert [r.getMessage() for r in caplog.records] == [
        "link `a`: first",
        "link `b`: other key",
        "link `a`: fourth (2 more since the last report)",
    ]
