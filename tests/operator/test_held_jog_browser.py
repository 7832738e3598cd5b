"""A held jog in real Chromium against `umbra run graphs/tool_pickup.yaml` (three processes,
zenoh, real clock) on a machine loaded by busy processes the test starts: the arm moves in one
motion for the whole hold, or it stops once and the page says why beside the jog pad; it never
moves in bursts (a stopped hold does not start again until it is released)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.operator.browser import GraphRun, chromium, needs_chromium, open_console, take_control
from tests.operator.test_browser_e2e import NO_SIM_CLICK, _graph_recording_the_jog, _hold
from umbra.modules.operator.jog import JogStop
from umbra.modules.world.trial_faults import Overload

pytestmark = [
    pytest.mark.browser,
    pytest.mark.slow,
    pytest.mark.heavy,
    needs_chromium,
    pytest.mark.timeout(600),  # three processes to start on a loaded machine
]

#: how long the operator holds the jog [s]
HOLD_S = 4.0
#: busy processes per core (2 cores: a load of 10)
LOAD_FACTOR = 5
#: the longest the arm may go on after the guard first zeroed the jog [s]: the guard's status
#: reaching the console, which then stops the hold
STOP_LAG_S = 0.3
#: what the jog pad says when a hold cannot go on (the words of the console's code, or the
#: page's own when its picture is past the console's bound)
STOP_WORDS = (*(code.words for code in JogStop), "jogs on a picture older than")

#: samples the jog pad's line every 50 ms into window.__hints (the test's own script)
_SAMPLE_HINTS = """window.__hints = []; setInterval(() =>
  window.__hints.push(document.getElementById('jog-hint').textContent), 50)"""


def _runs(ticks: list[tuple[float, bool]]) -> list[tuple[float, float]]:
    """(start, end) [s] of each run of moving ticks."""
    runs: list[tuple[float, float]] = []
    was_moving = False
    for t, moving in ticks:
        if moving and was_moving:
            runs[-1] = (runs[-1][0], t)
        elif moving:
            runs.append((t, t))
        was_moving = moving
    return runs


def _motion(path: Path) -> tuple[float, float, list[tuple[float, float]]] | None:
    """The hold (the console's first moving jog, its last zero jog) [s] and the runs of moving
    ticks REG_VEL passed, from the run's recording (None: no jog reached the arm's side)."""
    from umbra.runtime.recording.samples import iter_samples

    jogs: list[tuple[float, bool]] = []
    twist: list[tuple[float, bool]] = []
    for sample in iter_samples(path):
        row = (sample.log_ns / 1e9, bool(np.any(sample.message.vector)))
        (jogs if sample.topic == "jog" else twist).append(row)
    if not any(moving for _, moving in jogs):
        return None
    press = next(t for t, moving in jogs if moving)
    release = [t for t, moving in jogs if not moving][-1]
    return press, release, _runs([row for row in twist if press <= row[0] <= release + 0.05])


def test_a_held_jog_under_load_moves_in_one_motion_or_stops_once_and_says_why(
    tmp_path: Path,
) -> None:
    graph = _graph_recording_the_jog(tmp_path)
    run = GraphRun([str(graph), *NO_SIM_CLICK, "--duration", "120"], tmp_path / "run")
    hints: list[str] = []
    try:
        url = run.wait_url()
        with chromium() as browser:
            page: Any = open_console(browser, url, 1920, 1080)
            page.wait_for_function("window.umbra.state.joints.length === 6", timeout=30000)
            take_control(page)
            page.evaluate("document.getElementById('jog-speed').value = '1'")
            with Overload(LOAD_FACTOR):
                page.evaluate(_SAMPLE_HINTS)
                _hold(page, "x+")
                time.sleep(HOLD_S)
                page.mouse.up()
                page.wait_for_function(
                    "!window.umbra.state.jog_stopped", timeout=30000
                )  # released: the hold is no longer stopped
                hints = page.evaluate("window.__hints")
        run.kill()
    finally:
        run.kill()
    said = [h for h in hints if any(w in h for w in STOP_WORDS)]
    motion = _motion(tmp_path / "run" / "jog.mcap")
    if motion is None:  # the console never got the hold (a starved page process): said why
        assert said, hints[-5:]
        print(f"no motion; the page said {said[0]!r}")
        return
    press, release, runs = motion
    smooth = len(runs) == 1 and runs[0][1] >= release - 0.3
    if not smooth:  # stopped: once (the guard's word on its way may let one short run more)
        assert said, (runs, hints[-5:])
        assert len(runs) <= 2 and runs[-1][1] - runs[0][1] <= STOP_LAG_S, runs
    print(f"hold {release - press:.2f} s, runs {runs}, said {said[:1]}")
