"""The state line in real Chromium at 1280x800: what a click on the patch does now, before and
after a jog (the jog pauses the grab: a click then seeds and the arm waits for Resume), for a
viewer without control, and a tracker failure while paused said in words, not only as the red
outline."""

from __future__ import annotations

import msgspec
import numpy as np
import pytest

from tests.operator.browser import chromium, needs_chromium, take_control
from tests.operator.helpers import rectangle_contour, stepping
from tests.operator.test_frame_age_browser import WallPlant
from umbra.connectors.states import ServoReason, ServoStage, ServoState
from umbra.connectors.tracking import SnakeCheck
from umbra.modules.operator.console import OperatorConsole
from umbra.modules.operator.state_line import CLICK_WITHOUT_CONTROL
from umbra.runtime.harness import ModuleHarness

pytestmark = [pytest.mark.browser, pytest.mark.slow, needs_chromium, pytest.mark.timeout(300)]


def _says(page: object, selector: str, words: str) -> None:
    page.wait_for_function(  # type: ignore[attr-defined]
        f"document.querySelector({selector!r}).textContent.includes({words!r})", timeout=20000
    )


def test_the_line_says_what_a_click_does_after_a_jog_and_a_failed_tracker_in_words() -> None:
    T = np.eye(4)
    T[:3, 3] = [0, 0, -0.12]  # the camera 12 cm behind the tool: tool-frame jogs
    h = ModuleHarness(OperatorConsole, {}, frames={"tool->camera": T})
    plant = WallPlant(h)
    plant.servo = ServoState(
        stage=ServoStage.ACQUIRE, message="waiting", code=ServoReason.NOT_SEEDED
    )
    with stepping(plant), chromium() as browser:
        page = browser.new_page(viewport={"width": 1280, "height": 800})
        page.goto(h.module.url)
        page.wait_for_function("window.umbra.painted > 2 && window.umbra.state", timeout=30000)
        _says(page, "#click-does", CLICK_WITHOUT_CONTROL)  # no control: a click does nothing
        take_control(page)
        _says(page, "#click-does", "seeds the tracker; the approach then starts by itself")
        # a jog: the console pauses the grab, vsServo answers paused
        page.evaluate("window.umbra.holdJog(0, 1)")
        _says(page, "#click-does", "the arm holds until you press Resume")
        page.evaluate("window.umbra.releaseJog()")
        plant.servo = ServoState(stage=ServoStage.PAUSED, message="paused", code=ServoReason.PAUSED)
        _says(page, "#click-does", "seeds the tracker; the arm holds until you press Resume")
        assert "starts by itself" not in page.inner_text("#commands")
        assert page.inner_text("#line-tracker") == ""
        # the tracker fails while paused: said in its checks' words
        plant.contour = msgspec.structs.replace(
            rectangle_contour("failed", "no colour edge under 100% of the contour"),
            checks=(SnakeCheck.NO_EDGE,),
        )
        _says(page, "#line-tracker", "the tracker failed: the tracker lost the patch's edge")
        assert "click the patch to re-seed it" in page.inner_text("#line-tracker")
        assert page.is_visible("#line-tracker")
