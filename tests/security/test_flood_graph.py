"""The shipped pick-up (console in its own process, `ui`) under a junk flood: the operator's
abort still stops the arm — REG_VEL's twist goes to zero and stays there — about as fast as in
the same run's case without a flood. The measurement is benchmarks/bench_page_flood.py's.

Load needed: the whole graph (three processes) and a flood process; on a loaded machine the
abort's path (console -> vsServo at the camera's rate -> REG_VEL) is slow with or without a
flood, so the bound is the flood-free figure plus 150 ms."""

from __future__ import annotations

from pathlib import Path

import pytest

from benchmarks.bench_page_flood import attempts

pytestmark = [pytest.mark.slow, pytest.mark.heavy]


def test_the_abort_stops_the_arm_under_a_junk_flood(tmp_path: Path) -> None:
    quiet = attempts(tmp_path / "quiet", "ui", "none", aborts=2)
    flooded = attempts(tmp_path / "flood", "ui", "junk", aborts=2)
    assert quiet["aborts_while_moving"] >= 1 and flooded["aborts_while_moving"] >= 1
    assert flooded["closed_abusers"] >= 1  # the flood reached the page, and was closed
    # every abort sent while the arm moved stopped it, within 150 ms of the flood-free case
    assert flooded["aborts_stopped"] == flooded["aborts_while_moving"], flooded
    assert flooded["abort_to_zero_max_ms"] <= quiet["abort_to_zero_max_ms"] + 150.0, (
        quiet,
        flooded,
    )
