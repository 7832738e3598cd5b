"""A held jog through the console's real websocket: the arm's twist goes on at the keep-alive
period while the dead-man holds the jog, so keep-alives that come late (a page on a loaded
machine) do not zero it between two; a hold whose keep-alives stop, or which the guard (REG_VEL)
holds at zero, is stopped once, the page is told why, and it stays stopped (no burst) until the
page releases it."""

from __future__ import annotations

import time

import numpy as np
import pytest

from tests.operator.helpers import Page, image
from tests.operator.test_console_module import _harness, _operator, _pump
from umbra.connectors.states import GuardReason, GuardStage, GuardState
from umbra.modules.operator.jog import KEEPALIVE_S, JogStop
from umbra.runtime.harness import ModuleHarness

pytestmark = pytest.mark.slow

DEADMAN_S = 0.15
#: the page's keep-alives in this test come this far apart [s]: late (the page's period is
#: KEEPALIVE_S) but within the dead-man's bound
LATE_S = 0.11


def _hold(page: Page, frame: int, held: bool = True) -> None:
    page.send(
        "jog",
        held=held,
        axes=[1, 0, 0, 0] if held else [0, 0, 0, 0],
        jog_frame="camera",
        speed=1.0,
        frame=frame,
    )


def _run(
    h: ModuleHarness, seconds: float, steps: list[float] | None = None
) -> list[tuple[float, bool]]:
    """Step the console every 5 ms (a fresh image each step) for ``seconds`` of wall time:
    (wall time [s], moving) of every jog twist it sent; the wall time of each step is added to
    ``steps``."""
    out: list[tuple[float, bool]] = []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        h.push("image", image())
        sent = h.step(dt=0.005).get("jog", [])
        wall = time.monotonic()
        if steps is not None:
            steps.append(wall)
        out.extend((wall, bool(np.any(twist.vector))) for twist in sent)
        time.sleep(0.005)
    return out


def test_late_keepalives_move_the_arm_in_one_motion_and_silence_stops_it_once() -> None:
    with _harness(deadman_s=DEADMAN_S) as h:
        page = _operator(h)
        try:
            twists: list[tuple[float, bool]] = []
            steps: list[float] = []
            for _ in range(10):  # 1.1 s of keep-alives LATE_S apart
                _hold(page, h.module.image.value.seq)
                twists += _run(h, LATE_S, steps)
            moving = [t for t, m in twists if m]
            assert len(moving) >= 15 and all(
                m for _, m in twists[twists.index((moving[0], True)) :]
            )
            gaps = np.diff(moving)
            # the console's own period fills the late keep-alives' gaps (a step late at most:
            # this loop's own steps come late on a loaded machine)
            step_gap = float(np.diff(steps).max())
            assert gaps.max() <= KEEPALIVE_S + step_gap + 1e-3, (gaps.max(), step_gap)
            assert np.median(gaps) >= 0.02  # still the keep-alive's period, not every step
            # silence past the dead-man: one zero, and the page is told why
            after = [m for _, m in _run(h, 0.4)]
            assert after[-1:] == [False] and after.count(False) == 1, after
            state = h.module.view.state(h.now)
            stopped = state["jog_stopped"]
            assert stopped["code"] == JogStop.SILENT_PAGE, stopped
            assert stopped["words"] == JogStop.SILENT_PAGE.words
            notices = [n.text for n in h.module.board.lines if n.level == "error"]
            assert notices and notices[-1] == stopped["detail"]
            # the same hold's keep-alives, coming again, do not start a second burst
            for _ in range(4):
                _hold(page, h.module.image.value.seq)
                assert not any(m for _, m in _run(h, 0.04))
            assert h.module.summary()["deadman_expired"] == 1
            # released and pressed again: it moves, and the page's line is clear
            _hold(page, h.module.image.value.seq, held=False)
            _pump(h, lambda: h.module.view.state(h.now)["jog_stopped"] is None)
            again: list[tuple[float, bool]] = []

            def moving_again() -> bool:
                if h.module.view.state(h.now)["jog_stopped"]:
                    # a step starved past the dead-man stopped the hold (the page says so; seen
                    # beside ten busy loops): the operator lets go and presses again
                    _hold(page, h.module.image.value.seq, held=False)
                _hold(page, h.module.image.value.seq)  # the held button's keep-alive
                again.extend(_run(h, KEEPALIVE_S))
                return any(m for _, m in again)

            _pump(h, moving_again)
        finally:
            page.close()


def test_a_jog_the_guard_holds_at_zero_stops_once_with_the_guards_words() -> None:
    """REG_VEL zeroes the held jog (its commands came late: a starved console): the console
    stops the hold and says why in the guard's words, instead of starting the arm again at its
    next twist; a zero the guard reported before the hold began does not stop it."""
    zero = GuardState(
        stage=GuardStage.ZERO,
        code=GuardReason.WATCHDOG,
        reason="jog: no new command for 0.127 s (link watchdog 0.100 s)",
        jog=True,
    )
    with _harness(deadman_s=DEADMAN_S) as h:
        page = _operator(h)
        try:
            h.push("guard", zero)  # an old hold's zero
            moving: list[tuple[float, bool]] = []
            for _ in range(8):
                _hold(page, h.module.image.value.seq)
                moving += _run(h, KEEPALIVE_S)
            assert moving and all(m for _, m in moving), moving
            h.push("guard", zero)  # now the guard holds this jog at zero
            after: list[tuple[float, bool]] = []
            for _ in range(8):
                _hold(page, h.module.image.value.seq)
                after += _run(h, KEEPALIVE_S)
            flags = [m for _, m in after]
            assert False in flags and True not in flags[flags.index(False) :], flags
            stopped = h.module.view.state(h.now)["jog_stopped"]
            assert stopped["code"] == JogStop.GUARD, stopped
            assert stopped["detail"] == f"{JogStop.GUARD.words}: {GuardReason.WATCHDOG.words}"
            line = next(n for n in h.module.board.lines if n.text == stopped["detail"])
            assert line.level == "error" and line.detail == zero.reason
        finally:
            page.close()
