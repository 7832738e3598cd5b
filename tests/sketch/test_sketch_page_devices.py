"""The /sketch page's line on the cameras' devices in Debian's Chromium: what a device says is
wrong comes last on its camera's line and turns the lines red; once every device is ok and
still, they are dim again."""

from __future__ import annotations

import pytest

from tests.operator.browser import chromium, needs_chromium
from tests.sketch.test_sketch_page import Stepper
from umbra.connectors.messages import ZoomState
from umbra.connectors.ptu_messages import PtuState
from umbra.modules.sketch_page.sketch_page import SketchPage
from umbra.runtime.harness import ModuleHarness

REFUSED = "refused: tilt beyond its limit"


@pytest.mark.browser
@needs_chromium
def test_a_device_that_is_not_ok_is_said_last_in_red_then_the_line_calms() -> None:
    with (
        ModuleHarness(SketchPage, {"device_silent_s": 30.0}) as h,
        Stepper(h) as stepper,
        chromium() as browser,
    ):
        page = browser.new_page(viewport={"width": 1280, "height": 800})
        page.goto(h.module.url)
        for side, status in (("a", REFUSED), ("b", "ok")):
            stepper.push(h, f"ptu_{side}", PtuState(pan=0.5, tilt=-0.1, status=status))
            stepper.push(h, f"zoom_{side}", ZoomState(zoom=0.3))
        page.wait_for_function(f"$('cameras').textContent.includes({REFUSED!r})", timeout=10000)
        lines = page.inner_text("#cameras").splitlines()
        assert lines[0] == f"a: still, pan 28.6° tilt -5.7°, zoom 0.30 | PTU: {REFUSED}"
        assert lines[1] == "b: still, pan 28.6° tilt -5.7°, zoom 0.30"
        assert page.get_attribute("#cameras", "class") == "trouble"
        assert page.get_attribute("#cameras", "title") == page.inner_text("#cameras")
        stepper.push(h, "ptu_a", PtuState(pan=0.5, tilt=-0.1))
        page.wait_for_function("$('cameras').className === 'dim'", timeout=10000)
        assert "|" not in page.inner_text("#cameras")
