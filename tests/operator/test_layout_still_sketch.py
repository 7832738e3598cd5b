"""Active Sketch inside the station, in real Chromium at 1280x800 on a loaded machine (busy
processes this test starts), on graphs/active_sketch_page.yaml (umbra, ui and smart processes):
shown, the panel has the left column, the live video goes to the right column, every panel is in
view, and the snapshot images are at least 360 x 270 px. A line placed on the pipe, its macro
played (the cameras slew to watch its goal) and the cameras aimed elsewhere: the panel is the
same page (never reloaded), at the same place, with its snapshot images and the placed line still
drawn in both."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from tests.operator.browser import GraphRun, chromium, needs_chromium, take_control
from tests.operator.test_layout_still import BOXES_JS, _inside
from tests.poll import wait_for
from tests.sketch.test_sketch_browser import Operator
from umbra.modules.world.scene_objects import SketchScene
from umbra.modules.world.trial_faults import Overload

pytestmark = [
    pytest.mark.browser,
    pytest.mark.slow,
    pytest.mark.heavy,
    pytest.mark.timeout(400),
    needs_chromium,
]

ROOT = Path(__file__).resolve().parents[2]
GRAPH = "graphs/active_sketch_page.yaml"
SIZE = (1280, 800)
#: the least size [CSS px] of a snapshot image in the station's panel at 1280x800
MIN_SNAPSHOT_PX = (360, 270)

#: the red pipe in the station's live image (camera a): its pixel count and centre [px]
PIPE_JS = """() => { const c = document.getElementById('video');
  const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
  let su = 0, sv = 0, n = 0;
  for (let y = 0; y < c.height; y += 2) for (let x = 0; x < c.width; x += 2) {
    const i = (y * c.width + x) * 4;
    if (d[i] > 150 && d[i + 1] < 80 && d[i + 2] < 80) { su += x; sv += y; n++; } }
  return [n, n ? su / n : -1, n ? sv / n : -1]; }"""

#: what the panel shows: the same page?, its scroll, where its snapshot image and its list of
#: primitives are on screen, the snapshot, its images loaded and the placed lines drawn
PANEL_JS = """() => ({ mark: window.stationMark || 0, scroll: window.scrollY,
  at: ['view-a', 'primitives'].map((id) => document.getElementById(id).getBoundingClientRect().top),
  snap: window.sketch.state && window.sketch.state.snapshot && window.sketch.state.snapshot.id,
  primitives: window.sketch.state.primitives.map((p) => p.id),
  images: ['a', 'b'].map((s) => document.getElementById('img-' + s).naturalWidth),
  drawn: ['a', 'b'].map((s) =>
    document.querySelectorAll('#svg-' + s + ' polyline.reproj').length) })"""


class FrameOperator(Operator):
    """The /sketch page's operator (tests/sketch/test_sketch_browser.py) inside the station's
    frame: the frame's elements, the station page's mouse."""

    def __init__(self, page: Any, frame: Any) -> None:
        super().__init__(frame)
        self.mouse = page.mouse

    def drag(self, side: str, i: int, uv: Any) -> None:
        self.page.evaluate(f"document.getElementById('view-{side}').scrollIntoView()")
        box = self.page.locator(f"#svg-{side}").bounding_box()
        # the page redraws its handles: the one drawn now
        grip = wait_for(
            lambda: self.page.locator(f"[data-testid=handle-{side}{i}]").bounding_box(),
            5,
            f"handle {side}{i}",
            interval_s=0.2,
        )
        self.mouse.move(grip["x"] + grip["width"] / 2, grip["y"] + grip["height"] / 2)
        self.mouse.down()
        self.mouse.move(
            box["x"] + uv[0] * box["width"] / 640, box["y"] + uv[1] * box["height"] / 480, steps=8
        )
        self.mouse.up()


def _snapshot(frame: Any) -> None:
    """Press Snapshot until one is taken (refused while a PTU still slews: pressed again)."""

    def taken() -> bool:
        if frame.evaluate("!!(window.sketch.state && window.sketch.state.snapshot)"):
            return True
        if not frame.evaluate("window.snapshotAsked || false") or frame.evaluate(
            "document.getElementById('notice').className === 'error'"
        ):
            frame.evaluate("window.snapshotAsked = true")
            frame.click("[data-testid=snapshot]")
        return False

    wait_for(taken, 60, "a snapshot", interval_s=0.2)


def _panels_in_view(page: Any) -> dict[str, Any]:
    boxes = page.evaluate(BOXES_JS)
    assert boxes["column"] == ["sketch"], boxes["column"]  # the video went right
    for name, box in boxes["panels"].items():
        assert _inside(box, SIZE), f"the {name} panel {box} is outside {SIZE}"
    assert _inside(boxes["video"], SIZE)
    assert page.evaluate("document.scrollingElement.scrollHeight") <= SIZE[1]
    return boxes


def test_the_sketch_panel_has_room_and_keeps_its_place_when_the_cameras_move(
    tmp_path: Path,
) -> None:
    run = GraphRun([GRAPH, "--set", "world.randomize=false"], tmp_path)
    try:
        url = run.wait_url()
        with Overload(factor=1), chromium() as browser:
            page = browser.new_page(viewport={"width": SIZE[0], "height": SIZE[1]})
            page.goto(url)
            page.wait_for_function("window.umbra.painted > 2 && window.umbra.state", timeout=60000)
            page.wait_for_function(
                "(() => { const w = document.getElementById('sketch-frame').contentWindow;"
                " return w && w.sketch && w.sketch.state; })()",
                timeout=60000,
            )
            frame = page.locator("#sketch-frame").element_handle().content_frame()
            take_control(page)
            frame.wait_for_function(
                "document.getElementById('holder').textContent.endsWith(' (you)')", timeout=20000
            )
            boxes = _panels_in_view(page)
            view = frame.locator("#view-a").bounding_box()
            assert view["width"] >= MIN_SNAPSHOT_PX[0] and view["height"] >= MIN_SNAPSHOT_PX[1]
            # the script aims the cameras at the pipe; a snapshot once they stand still
            frame.wait_for_function(
                "window.sketch.state.status && "
                "window.sketch.state.status.message.startsWith('aiming')",
                timeout=60000,
            )
            _snapshot(frame)
            frame.wait_for_function(
                "document.getElementById('img-a').naturalWidth > 0", timeout=20000
            )
            op = FrameOperator(page, frame)
            placed = op.place("line", SketchScene.nominal().pipe.ends)
            frame.evaluate("window.stationMark = 42")  # gone if the panel's page reloads
            # scrolled down to the player's buttons and the list of primitives, as to play
            frame.evaluate("window.scrollTo(0, document.documentElement.scrollHeight)")
            before = frame.evaluate(PANEL_JS)
            assert before["primitives"] == [placed["id"]] and before["drawn"] == [1, 1], before
            assert min(before["images"]) > 0 and before["scroll"] > 0
            # the macro: planned, played to its end (the cameras slew to watch its goal); the
            # replies (the placement's, with its warnings, was long) and the verdict change the
            # words around the images, which stay where they were. Pressed where they are (a
            # test's click would first scroll its button into view; a person's does not)
            press = "(id) => document.querySelector(`[data-testid=${id}]`).click()"
            frame.evaluate(press, "macro-grab_pipe")
            frame.wait_for_function(
                "window.sketch.state.path && window.sketch.state.path.macro === 'grab_pipe'"
                " && window.sketch.state.path.ok",
                timeout=30000,
            )
            frame.evaluate(press, "play")
            op.until("window.sketch.state.vcr.mode === 'done'", "play", 120)
            frame.wait_for_function(
                "document.getElementById('verdict').textContent.length > 0", timeout=20000
            )
            played = frame.evaluate(PANEL_JS)
            for key in ("mark", "scroll", "snap", "primitives", "images", "drawn"):
                assert played[key] == before[key], (key, before, played)
            assert played["at"][0] == before["at"][0], (before, played)  # the snapshot image
            # then the cameras aimed 15 cm aside: the pipe moves in the live image, nothing in
            # the panel does
            shown = page.evaluate(PIPE_JS)
            frame.evaluate("send('aim 0.62 0.15 0.3 0.3')")
            moved = wait_for(
                lambda: (
                    (now := page.evaluate(PIPE_JS))[0] > 0
                    and abs(now[1] - shown[1]) + abs(now[2] - shown[2]) > 40
                    and now
                ),
                60,
                "the cameras to slew",
                interval_s=0.2,
            )
            frame.wait_for_function(
                "window.sketch.state.status.message.startsWith('aiming at [0.62, 0.15')",
                timeout=20000,
            )
            page.wait_for_timeout(1000)  # a second of slewed video, watched by the page
            after = frame.evaluate(PANEL_JS)
            assert after == played, (played, after, shown, moved)
            assert page.evaluate(BOXES_JS)["panels"]["sketch"] == boxes["panels"]["sketch"]
            _panels_in_view(page)
            frame.evaluate("document.querySelector('.views').scrollIntoView()")
            page.wait_for_timeout(300)
            page.screenshot(path=str(ROOT / "docs" / "images" / "station-sketch-1280x800.png"))
    finally:
        run.kill()
