"""The station page in real Chromium at 1280x800 and 1920x1080, against the console module in
the harness (vsServo's and the world's statuses played by the test): seed, start, pause,
resume, abort, an assistance request answered without scrolling, a jog named in the image's
words, and the end of the run by the operator's *Stop* (judged by a real World module) with its
verdict."""

from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.operator.browser import (
    chromium,
    click_image,
    needs_chromium,
    release_control,
    take_control,
)
from tests.operator.helpers import image, rectangle_contour, stepping, stop_stepping
from tests.poll import wait_for
from tests.world.test_attended import FRAMES
from umbra.connectors.messages import Message
from umbra.connectors.states import ServoReason, ServoStage, ServoState
from umbra.connectors.tracking import SnakeCheck
from umbra.modules.operator.console import OperatorConsole
from umbra.modules.world.world import SimWorld
from umbra.runtime.harness import ModuleHarness

pytestmark = [pytest.mark.browser, pytest.mark.slow, needs_chromium]

SNAKE_REASON = (
    "snake failure: no colour edge under 100% of the contour (featureless image); "
    "area changed -63% in one frame"
)
SNAKE_CHECKS = (SnakeCheck.NO_EDGE, SnakeCheck.AREA_CHANGE)
#: vsServo waiting for a seed
WAITING = ServoState(
    stage=ServoStage.ACQUIRE, message="waiting: snake has no contour", code=ServoReason.NOT_SEEDED
)
VERDICT = "stopped by the operator before a grasp"


class Plant(threading.Thread):
    """Steps the console every 10 ms with a 30 fps camera, a tracking contour and the latest
    vsServo status (set by the test); records what the console sends."""

    def __init__(self, h: ModuleHarness) -> None:
        super().__init__(daemon=True)
        self.h = h
        self.servo = WAITING
        self.extra: list[tuple[str, Message]] = []
        self.steady: dict[str, Message] = {}  #: more inputs, pushed with each frame
        self.sent: list[tuple[str, Message]] = []
        self.halt = threading.Event()
        self.lock = threading.Lock()

    def run(self) -> None:
        k = 0
        while not self.halt.is_set():
            with self.lock:
                extra, self.extra = self.extra, []
                if k % 3 == 0:
                    self.h.push("image", image())
                    self.h.push("contour", rectangle_contour())
                    self.h.push("servo", self.servo)
                    for port, sample in self.steady.items():
                        self.h.push(port, sample)
                for port, sample in extra:
                    self.h.push(port, sample)
                out = self.h.step(dt=0.01)
            self.sent.extend((port, s) for port, samples in out.items() for s in samples)
            k += 1
            time.sleep(0.01)

    def stage(self, stage: str, reason: str = "") -> None:
        failed = stage == "assist" and reason == SNAKE_REASON
        self.servo = ServoState(
            stage=ServoStage(stage),
            message=stage,
            reason=reason,
            assist=stage == "assist",
            code=ServoReason.SNAKE_FAILED if failed else ServoReason.NONE,
            checks=SNAKE_CHECKS if failed else (),
        )

    def commands(self) -> list[str]:
        return [str(s.action) for port, s in list(self.sent) if port == "operator"]


def _in_view(page: Any, selector: str, size: tuple[int, int]) -> bool:
    """Whether every element matching ``selector`` is visible and wholly inside the viewport."""
    boxes = [
        page.locator(selector).nth(i).bounding_box() for i in range(page.locator(selector).count())
    ]
    return bool(boxes) and all(
        b is not None
        and b["x"] >= 0
        and b["y"] >= 0
        and b["x"] + b["width"] <= size[0]
        and b["y"] + b["height"] <= size[1]
        for b in boxes
    )


def _command(page: Any, plant: Plant, action: str, stage_before: str) -> None:
    """Click a grab command once the page offers it; vsServo's output gets it."""
    before = len(plant.commands())
    button = f"#commands button[data-action={action}]"
    page.wait_for_function(
        f"window.umbra.state.line.stage === '{stage_before}' && "
        f"!document.querySelector('{button}').disabled",
        timeout=10000,
    )
    page.click(button)
    wait_for(lambda: plant.commands()[before:] == [action], 10.0, f"the {action} command")


def _layout_persists(page: Any) -> None:
    """Only the panels the graph feeds are offered; a hidden one stays hidden after a reload
    (the layout is kept per browser), and the Panels menu shows it again."""
    offered = page.eval_on_selector_all(
        "#panel-list input", "boxes => boxes.map(b => b.dataset.panel)"
    )
    assert "sketch" not in offered and "view3d" not in offered and "zoom" not in offered
    assert {"video", "jog", "messages", "health"} <= set(offered), offered
    page.click("section[data-panel=messages] .hide")
    assert page.is_hidden("section[data-panel=messages]")
    page.reload()
    page.wait_for_function("window.umbra.painted > 2 && window.umbra.state")
    assert page.is_hidden("section[data-panel=messages]")
    page.click("#panel-menu summary")
    page.check("#panel-list input[data-panel=messages]")
    assert page.is_visible("section[data-panel=messages]")
    page.click("#panel-menu summary")


def _drive(page: Any, plant: Plant, size: tuple[int, int], shot: Path) -> None:
    """One operator's session on the page at ``size``."""
    plant.servo = WAITING
    take_control(page)
    assert page.evaluate("document.scrollingElement.scrollHeight") <= size[1]
    for action in ("start", "pause", "resume", "abort"):
        assert _in_view(page, f"#commands button[data-action={action}]", size), action
    # a click on the patch seeds; the page says the approach then starts by itself
    assert "starts by itself" in page.inner_text("#seed-hint")
    seeds = len([1 for port, _ in plant.sent if port == "seed"])
    click_image(page, 340.0, 230.0)
    wait_for(
        lambda: len([1 for port, _ in plant.sent if port == "seed"]) == seeds + 1,
        10.0,
        "one more seed",
    )
    page.wait_for_function(
        "document.getElementById('line-doing').textContent.includes('click the patch')"
    )
    assert page.is_disabled("#commands button[data-action=start]")  # nothing to start yet
    plant.stage("approach")
    page.wait_for_function(
        "document.getElementById('line-doing').textContent.includes('moving toward the patch')"
    )
    _command(page, plant, "pause", "approach")
    plant.stage("paused")
    _command(page, plant, "resume", "paused")
    plant.stage("approach")
    _command(page, plant, "abort", "approach")
    plant.stage("aborted")
    _command(page, plant, "start", "aborted")
    plant.stage("approach")
    # an assistance request: the dialog and its buttons in view, no scrolling
    plant.stage("assist", SNAKE_REASON)
    page.wait_for_selector("#assist[open]", timeout=10000)
    for selector in ("#assist button[data-action=resume]", "#assist button[data-action=abort]"):
        assert _in_view(page, selector, size), selector
    assert page.evaluate("document.scrollingElement.scrollHeight") <= size[1]
    assert page.inner_text("#assist-reason") == (
        "the tracker lost the patch's edge; the patch's size jumped"
    )
    page.wait_for_function(  # the long reason is one message line, however often it came
        "document.querySelectorAll('#notices div').length >= 1 && [...document.querySelectorAll"
        "('#notices div')].filter(d => d.textContent.includes('asks for you')).length === 1"
    )
    page.screenshot(path=str(shot))
    # hidden, the request can be shown again
    page.click("#assist-hide")
    page.click("#assist-show")
    page.wait_for_selector("#assist[open]")
    before = len(plant.commands())
    page.click("#assist button[data-action=resume]")
    wait_for(lambda: plant.commands()[before:] == ["resume"], 10.0, "the resume command")
    plant.stage("paused")
    page.wait_for_selector("#assist", state="hidden")
    # a jog named in the image's words: tool z- lifts the camera (camera z < 0)
    lift = page.locator("#jog button", has_text="away (lift)")
    assert "tool z-" in lift.inner_text()
    box = lift.bounding_box()
    page.mouse.move(box["x"] + 5, box["y"] + 5)
    page.mouse.down()
    page.wait_for_timeout(500)
    page.mouse.up()
    page.wait_for_timeout(300)
    jogs = [s.vector for port, s in list(plant.sent) if port == "jog"]
    assert any(v[2] < -1e-3 and abs(v[0]) < 1e-9 for v in jogs), jogs[-3:]
    assert not np.any(jogs[-1])  # released: zero


def test_the_station_at_1280x800_and_1920x1080(tmp_path: Path) -> None:
    T = np.eye(4)
    T[:3, 3] = [0, 0, -0.12]
    h = ModuleHarness(OperatorConsole, {}, frames={"tool->camera": T})
    with stepping(Plant(h)) as plant, chromium() as browser:
        pages = []
        for size in ((1280, 800), (1920, 1080)):
            page = browser.new_page(viewport={"width": size[0], "height": size[1]})
            page.goto(h.module.url)
            page.wait_for_function("window.umbra.painted > 2 && window.umbra.state")
            if not pages:
                _layout_persists(page)
            _drive(page, plant, size, tmp_path / f"station-{size[0]}.png")
            release_control(page)
            pages.append(page)
        # Stop: only the holder may; the world (attended: it would never end the run by
        # itself) ends it, "stopped by the operator", and the pages show the run's end
        viewer = pages[1]
        take_control(pages[0])
        stop = "#commands button[data-action=stop]"
        pages[0].wait_for_function(f"!document.querySelector('{stop}').disabled")
        viewer.wait_for_function("window.umbra.state.control !== ''")
        assert viewer.is_disabled(stop)  # not the holder
        pages[0].click(stop)
        wait_for(
            lambda: (
                [type(s).__name__ for port, s in list(plant.sent) if port == "stop_run"]
                == ["StopRun"]
            ),
            10.0,
            "one StopRun",
        )
        with ModuleHarness(SimWorld, frames=FRAMES, attended=True) as world:
            world.push("operator", next(s for port, s in plant.sent if port == "stop_run"))
            world.step(dt=0.01)
            assert world.stop_request == (VERDICT, 0)
            with plant.lock:
                plant.extra.append(("world", world.output("status")))
        for page in pages:
            page.wait_for_function(
                "document.getElementById('line-verdict').textContent.includes('stopped by')"
            )
        stop_stepping(plant)  # the run's end: the pages see their socket close
        for page in pages:
            page.wait_for_function("window.umbra.ended", timeout=10000)
            assert page.inner_text("#conn") == "run ended"
            assert VERDICT in page.inner_text("#ended")
            assert page.is_disabled("#take")
            assert page.is_disabled("#commands button[data-action=abort]")
        pages[0].screenshot(path=str(tmp_path / "station-ended.png"))


def test_active_sketch_is_a_panel_of_the_station_behind_the_same_door() -> None:
    """With a SketchPage on the console's server, the station offers the Active Sketch panel:
    the /sketch page in a same-origin frame, which knows this browser as the holder of control
    taken on the station."""
    from tests.sketch.test_sketch_page import Stepper as Steppers
    from umbra.modules.sketch_page.sketch_page import SketchPage

    with (
        ModuleHarness(OperatorConsole, {}) as console,
        ModuleHarness(SketchPage, {}) as sketch,
        Steppers(console, sketch) as stepper,
        chromium() as browser,
    ):
        page = browser.new_page(viewport={"width": 1280, "height": 800})
        page.goto(console.module.url)
        for _ in range(5):
            stepper.push(console, "image", image())
        page.wait_for_function("window.umbra.state && window.umbra.state.panels.sketch")
        assert page.is_hidden("section[data-panel=sketch]")  # narrow screen, a grab to run
        take_control(page)
        page.click("#panel-menu summary")
        page.check("#panel-list input[data-panel=sketch]")
        frame = page.frame_locator("#sketch-frame")
        name = page.evaluate("window.umbra.name")
        holder = frame.locator("#holder")
        holder.wait_for(timeout=20000)
        page.wait_for_function(
            "document.getElementById('sketch-frame').contentDocument"
            f".getElementById('holder').textContent === {name + ' (you)'!r}",
            timeout=20000,
        )
        # one holder for the browser: the station page stands for it, the framed page follows
        assert console.module.arbiter.holder == page.evaluate("window.umbra.session")


def _pose(xyz: tuple[float, float, float], down: bool = False) -> np.ndarray:
    """A pose at ``xyz`` [m]; ``down``: its z axis points down (a camera looking at the table)."""
    T = np.diag([1.0, -1.0, -1.0, 1.0]) if down else np.eye(4)
    T[:3, 3] = xyz
    return T


def _green(page: Any) -> int:
    """Pixels of the patch's green (0x22bb44) on the 3-D panel's canvas."""
    import io

    from PIL import Image as PILImage

    shot = page.locator("#view3d canvas").screenshot()
    rgb = np.asarray(PILImage.open(io.BytesIO(shot)).convert("RGB")).astype(int)
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    return int(np.sum((abs(r - 0x22) < 30) & (abs(g - 0xBB) < 40) & (abs(b - 0x44) < 30)))


def test_the_3d_panel_switches_between_the_overview_and_the_graphs_camera() -> None:
    """The 3-D panel offers the view from the graph's camera only once the graph has one; seen
    from the camera 20 cm above the patch, the patch fills a large part of the view (in the
    overview, 2 m away, a few pixels), and the eye is at the camera's pose."""
    from umbra.connectors.messages import Pose, Poses

    frames = {"base->table": _pose((0.0, 0.0, 0.25))}
    h = ModuleHarness(OperatorConsole, {}, frames=frames)
    h.__enter__()
    plant = Plant(h)
    links = np.stack([_pose((0.0, 0.0, 0.3)), _pose((0.3, 0.0, 0.6))])
    plant.steady = {
        "link_poses": Poses(matrices=links, children=["link1", "link2"], frame="base"),
        "patch_pose": Pose(matrix=_pose((0.6, 0.0, 0.03)), parent="table", child="patch"),
    }
    plant.start()
    try:
        with chromium() as browser:
            page = browser.new_page(viewport={"width": 1920, "height": 1080})
            page.goto(h.module.url)
            page.wait_for_function("window.umbra.view3d && window.umbra.view3d.links === 2")
            options = "[...document.querySelectorAll('#view3d-from option')].map(o => o.value)"
            assert page.evaluate(options) == ["overview"]  # no camera in the graph (yet)
            with plant.lock:
                plant.steady["camera_pose"] = Pose(
                    matrix=_pose((0.6, 0.0, 0.23), down=True), parent="table", child="camera"
                )
            page.wait_for_function(f"{options}.includes('camera')")
            assert page.evaluate(options) == ["overview", "camera"]
            page.wait_for_timeout(500)
            overview = _green(page)
            page.select_option("#view3d-from", "camera")
            page.wait_for_function("window.umbra.view3d.from === 'camera'")
            eye = page.evaluate("window.umbra.view3d.eye")
            assert np.allclose(eye, [0.6, 0.0, 0.48], atol=1e-4), eye  # T_base_table @ camera
            page.wait_for_timeout(500)
            seen = _green(page)
            area = page.evaluate(
                "(() => { const c = document.querySelector('#view3d canvas');"
                " return c.clientWidth * c.clientHeight; })()"
            )
            # the patch (6 x 4 cm at 20 cm, 62 deg vertical field): about 3 % of the view
            assert seen > 0.01 * area and seen > 5 * overview, (seen, overview, area)
            page.select_option("#view3d-from", "overview")
            page.wait_for_function("window.umbra.view3d.from === 'overview'")
            assert not np.allclose(page.evaluate("window.umbra.view3d.eye"), eye, atol=0.05)
    finally:
        plant.halt.set()
        plant.join(5)
        h.__exit__(None, None, None)


def _drag(page: Any, x0: float, y0: float, x1: float, y1: float) -> None:
    """Press at (x0, y0), move to (x1, y1) in steps, release (a person's drag)."""
    page.mouse.move(x0, y0)
    page.mouse.down()
    page.mouse.move(x1, y1, steps=8)
    page.mouse.up()


def test_panels_resize_by_drag_and_the_layout_persists_per_browser() -> None:
    """At 1280x800: the columns' splitter and a panel's resize grip, dragged, change the sizes;
    a reload keeps them (localStorage: per browser, another browser has its own); with the
    bigger panels every command and the assistance dialog stay in view without scrolling."""
    size = (1280, 800)
    h = ModuleHarness(OperatorConsole, {})
    h.__enter__()
    plant = Plant(h)
    plant.start()
    try:
        with chromium() as browser:
            context = browser.new_context(viewport={"width": size[0], "height": size[1]})
            page = context.new_page()
            page.goto(h.module.url)
            page.wait_for_function("window.umbra.painted > 2 && window.umbra.state")
            left = page.locator("#col-left").bounding_box()["width"]
            split = page.locator("#split").bounding_box()
            y = split["y"] + split["height"] / 2
            _drag(page, split["x"] + 3, y, 0.45 * size[0], y)
            narrower = page.locator("#col-left").bounding_box()["width"]
            assert narrower < left - 150, (left, narrower)  # 62 % -> 45 % of 1280 px
            messages = page.locator("section[data-panel=messages]")
            box = messages.bounding_box()
            grip = (box["x"] + box["width"] - 3, box["y"] + box["height"] - 3)
            _drag(page, *grip, grip[0], grip[1] + 120)
            taller = messages.bounding_box()["height"]
            assert taller > box["height"] + 100, (box["height"], taller)
            page.reload()
            page.wait_for_function("window.umbra.painted > 2 && window.umbra.state")
            assert abs(page.locator("#col-left").bounding_box()["width"] - narrower) < 3
            assert abs(messages.bounding_box()["height"] - taller) < 3
            # every command and the assistance dialog in view, the page not scrolled
            take_control(page)
            plant.stage("assist", SNAKE_REASON)
            page.wait_for_selector("#assist[open]", timeout=10000)
            for selector in (
                "#commands button[data-action]",
                "#assist button[data-action=resume]",
                "#assist button[data-action=abort]",
                "#release",
            ):
                assert _in_view(page, selector, size), selector
            assert page.evaluate("document.scrollingElement.scrollHeight") <= size[1]
            # another browser (its own storage) starts from the default layout
            other = browser.new_page(viewport={"width": size[0], "height": size[1]})
            other.goto(h.module.url)
            other.wait_for_function("window.umbra.painted > 2 && window.umbra.state")
            assert abs(other.locator("#col-left").bounding_box()["width"] - left) < 3
            height = "document.querySelector('section[data-panel=messages]').style.height"
            assert other.evaluate(height) == ""  # sized by its content, as at first
            assert abs(float(page.evaluate(height)[:-2]) - (taller - 12)) < 1.5  # 2 x 6 px pad
            context.close()
    finally:
        plant.halt.set()
        plant.join(5)
        h.__exit__(None, None, None)
