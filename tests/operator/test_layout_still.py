"""The station's layout holds still, in real Chromium at 1280x800 and 1920x1080 on a loaded
machine (busy processes this test starts): the live image's box does not change by a pixel, not
even for one painted frame, through an assistance request (its dialog overlays the right column,
never the live image) and a burst of 50 refused clicks (one line, "×50", in a list of bounded
height); every panel of the right column and the live video stay wholly in view. The console
runs in the harness, vsServo's state and the arm's links and joints played by the test."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.operator.browser import chromium, needs_chromium, release_control, take_control
from tests.operator.helpers import stepping
from tests.operator.test_browser_station import SNAKE_REASON, Plant
from umbra.connectors.messages import JointState, Poses
from umbra.modules.operator.console import OperatorConsole
from umbra.modules.world.trial_faults import Overload
from umbra.runtime.harness import ModuleHarness

pytestmark = [pytest.mark.browser, pytest.mark.slow, pytest.mark.heavy, needs_chromium]

ROOT = Path(__file__).resolve().parents[2]
SIZES = ((1280, 800), (1920, 1080))
BURST = 50
#: the Messages list's bound [px] (station.css: #notices max-height)
NOTICES_MAX_PX = 130

#: every shown panel's box and the live image's, as [x, y, width, height] in CSS px
BOXES_JS = """() => {
  const r = (e) => { const b = e.getBoundingClientRect(); return [b.x, b.y, b.width, b.height]; };
  const panels = {};
  for (const p of document.querySelectorAll('section.panel'))
    if (!p.hidden) panels[p.dataset.panel] = r(p);
  return { video: r(document.getElementById('video')), panels,
           column: [...document.querySelectorAll('#col-left > section.panel')]
             .filter((p) => !p.hidden).map((p) => p.dataset.panel) };
}"""

#: from now on, every animation frame: the live image's box when it differs from now's
WATCH_JS = """() => {
  const video = document.getElementById('video');
  const box = () => JSON.stringify(Object.values(video.getBoundingClientRect().toJSON()));
  const still = box();
  window.videoMoves = [];
  const tick = () => {
    const now = box();
    if (now !== still) window.videoMoves.push(now);
    requestAnimationFrame(tick);
  };
  requestAnimationFrame(tick);
}"""


def _inside(box: list[float], size: tuple[int, int]) -> bool:
    x, y, w, h = box
    return w > 0 and h > 0 and x >= 0 and y >= 0 and x + w <= size[0] and y + h <= size[1]


def _settled_video(page: Any, timeout: float = 15.0) -> list[float]:
    """The live image's box once it is the same over 10 reads 0.1 s apart (the page has fitted
    the video to the window and drawn the first states)."""
    end, last, same = time.monotonic() + timeout, None, 0
    while time.monotonic() < end:
        box = page.evaluate(BOXES_JS)["video"]
        same = same + 1 if box == last else 0
        if same >= 10:
            return box
        last = box
        time.sleep(0.1)
    raise AssertionError(f"the live image never settled: last {last}")


def _all_in_view(page: Any, size: tuple[int, int], when: str) -> None:
    """Every panel in view: wholly for the live video and the right column's; the left
    column's panels under the live image (it fills the column's height, the column scrolls)
    show their title at least."""
    boxes = page.evaluate(BOXES_JS)
    assert _inside(boxes["video"], size), (when, boxes["video"])
    assert {"video", "jog", "messages", "health"} <= set(boxes["panels"]), boxes["panels"]
    for name, box in boxes["panels"].items():
        if name in boxes["column"] and name != "video":
            assert box[1] + 24 <= size[1], f"{when}: the {name} panel's title is out of view"
        else:
            assert _inside(box, size), f"{when}: the {name} panel {box} is outside {size}"
    assert page.evaluate("document.scrollingElement.scrollHeight") <= size[1], when


def _notices(page: Any) -> list[str]:
    return page.eval_on_selector_all("#notices > div", "ds => ds.map((d) => d.textContent)")


def _steady(plant: Plant) -> None:
    """The arm's links (the 3-D panel) and six joints (the health panel), as a real graph has."""
    links = np.stack([np.eye(4), np.eye(4)])
    links[0][:3, 3] = [0.0, 0.0, 0.6]
    links[1][:3, 3] = [0.4, 0.0, 0.5]
    plant.steady = {
        "link_poses": Poses(matrices=links, children=["shoulder", "flange"], frame="base"),
        "joints": JointState(
            names=tuple(f"j{i + 1}" for i in range(6)),
            position=np.radians([0.0, 45.6, -182.7, 0.0, -42.9, 0.0]),
            velocity=np.zeros(6),
        ),
    }


def _hold_still(page: Any, plant: Plant, size: tuple[int, int], shot: Path) -> None:
    """One page at ``size``: an assistance request and a burst of refusals; nothing moves."""
    plant.stage("approach")
    take_control(page)
    page.wait_for_function("window.umbra.state.line.stage === 'approach'", timeout=10000)
    video = _settled_video(page)
    _all_in_view(page, size, "at the start")
    page.evaluate(WATCH_JS)
    # an assistance request: the dialog overlays the right column's foot, not the live image
    plant.stage("assist", SNAKE_REASON)
    page.wait_for_selector("#assist[open]", timeout=10000)
    dialog = page.locator("#assist").bounding_box()
    vx, vy, vw, vh = video
    assert dialog["x"] >= vx + vw or dialog["y"] >= vy + vh, (dialog, video)  # no overlap
    for button in ("resume", "abort"):
        assert _inside(
            list(page.locator(f"#assist button[data-action={button}]").bounding_box().values()),
            size,
        )
    # a burst: 50 clicks on frames the console no longer has, each refused with its number
    page.evaluate(
        f"""() => {{ for (let i = 0; i < {BURST}; i++)
          umbra.send('click', {{ u: 340, v: 230, frame: umbra.frame + 100000 + i }}); }}"""
    )
    page.wait_for_function(
        "[...document.querySelectorAll('#notices > div')].some((d) =>"
        f" d.textContent.includes('stale page') && d.textContent.includes('×{BURST}'))",
        timeout=20000,
    )
    stale = [t for t in _notices(page) if "stale page" in t]
    assert len(stale) == 1, stale
    assert stale[0].endswith(f"×{BURST}") and "no longer live" in stale[0], stale[0]
    height = page.evaluate("document.getElementById('notices').getBoundingClientRect().height")
    assert 0 < height <= NOTICES_MAX_PX, height
    _all_in_view(page, size, "with the request and the burst")
    page.screenshot(path=str(shot))
    # the request hidden, answered, gone: the live image has not moved once
    page.click("#assist-hide")
    page.click("#assist-show")
    page.click("#assist button[data-action=resume]")
    plant.stage("approach")
    page.wait_for_selector("#assist", state="hidden", timeout=10000)
    page.wait_for_timeout(300)  # a few painted frames after it closed, watched
    moves = page.evaluate("window.videoMoves")
    assert moves == [], f"the live image moved from {video} to {moves[:3]}"
    assert page.evaluate(BOXES_JS)["video"] == video
    _all_in_view(page, size, "after the request")


def test_the_live_image_holds_still_and_every_panel_stays_in_view() -> None:
    T = np.eye(4)
    T[:3, 3] = [0, 0, -0.12]
    plant = Plant(ModuleHarness(OperatorConsole, {}, frames={"tool->camera": T}))
    _steady(plant)
    with stepping(plant), Overload(factor=1), chromium() as browser:
        for size in SIZES:
            page = browser.new_page(viewport={"width": size[0], "height": size[1]})
            page.goto(plant.h.module.url)
            page.wait_for_function("window.umbra.painted > 2 && window.umbra.state")
            shot = ROOT / "docs" / "images" / f"station-layout-{size[0]}x{size[1]}.png"
            _hold_still(page, plant, size, shot)
            release_control(page)
            page.close()
