"""End to end in real Chromium: `umbra run graphs/tool_pickup.yaml` (two processes, zenoh,
real clock) with a person at the console instead of the simulated operator."""

from __future__ import annotations

import io
import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.operator.browser import (
    REPO,
    GraphRun,
    chromium,
    click_image,
    green_patch_centre,
    image_to_screen_map,
    needs_chromium,
    open_console,
    take_control,
)

pytestmark = [pytest.mark.browser, pytest.mark.slow, needs_chromium]
# only the person clicks; no .avi written (CPU for the camera on a shared 2-core machine)
NO_SIM_CLICK = ["--set", "operator.click_delay_s=1000", "--set", 'view.video=""']


def _stage(page: Any) -> str:
    return page.evaluate("window.umbra.state ? window.umbra.state.servo.stage : ''")


def _wait_stage(
    page: Any, stages: tuple[str, ...], run: GraphRun | None = None, timeout_ms: int = 30000
) -> None:
    """Wait until the servo's stage is one of ``stages``; on a timeout, say the stage it was in,
    the page's notices and the run's log (what a loaded CI machine did instead)."""
    try:
        page.wait_for_function(
            f"window.umbra.state && {list(stages)!r}.includes(window.umbra.state.servo.stage)",
            timeout=timeout_ms,
        )
    except Exception as exc:
        notices = page.evaluate("(window.umbra.notices || []).map(n => n.text)")
        log = run.text()[-3000:] if run is not None else ""
        raise AssertionError(
            f"stage {_stage(page)!r}, not one of {stages}; notices {notices[-5:]}\n{log}"
        ) from exc


def _click_patch(page: Any, tries: int = 5) -> tuple[float, float]:
    """Click the patch's centre as a person would: again when the console refuses the click
    as made on a stale image (a loaded machine paints late; the refusal is the safety rule)."""
    notices = "(window.umbra.notices || []).map(n => n.text)"
    for _ in range(tries):
        u, v, n = green_patch_centre(page)
        assert n > 200, f"no patch visible on the page ({n} green pixels)"
        before = len(page.evaluate(notices))
        click_image(page, u, v)
        page.wait_for_timeout(1500)
        if not any("stale page" in t for t in page.evaluate(notices)[before:]):
            return u, v
    raise AssertionError(f"every click was refused as stale: {page.evaluate(notices)[-3:]}")


def _refused_click(page: Any, u: float, v: float, tries: int = 3) -> None:
    """A click by a viewer without control is refused, and the page says who holds control
    (clicked again when no answer came within 8 s: a loaded machine)."""
    said = "window.umbra.notices.some(n => n.text.includes('holds control'))"
    for _ in range(tries):
        click_image(page, u, v)
        try:
            page.wait_for_function(said, timeout=8000)
            return
        except Exception:
            continue
    notices = page.evaluate("window.umbra.notices.map(n => n.text)")
    raise AssertionError(f"no refusal naming the holder; notices: {notices[-5:]}")


#: Wraps the page's event hub: while ``__hold`` is set, states are not drawn, and the overlay
#: last drawn is kept in ``__drawn`` (the test's own script, not the page's).
_HOLD_STATES = """(() => {
  if (window.__holdable) return;
  window.__holdable = true;
  const emit = umbra.emit;
  umbra.emit = (kind, data) => {
    if (kind === "state") {
      if (window.__hold) return;
      window.__drawn = data.overlay ? data.overlay.points : [];
    }
    emit(kind, data);
  };
})()"""


def _overlay_green_on_snake(page: Any) -> tuple[int, int]:
    """(hits, probes): vertices of the drawn snake whose screen pixels (within 4 px) have the
    overlay's green, read from one screenshot. The page draws no new state meanwhile (a state
    comes every 0.1 s, and a screenshot under load takes longer), so the overlay on the screen
    is the one whose vertices are read."""
    from PIL import Image as PILImage

    page.evaluate(_HOLD_STATES)
    page.wait_for_function("window.__drawn !== undefined")
    page.evaluate("window.__hold = true")
    try:
        page.wait_for_timeout(100)  # a state being drawn as the hold began is on the screen
        drawn = page.evaluate("window.__drawn")
        shot = np.asarray(PILImage.open(io.BytesIO(page.screenshot())).convert("RGB")).astype(int)
        to_screen = image_to_screen_map(page)  # the layout of the screenshot
    finally:
        page.evaluate("window.__hold = false")
    step = max(1, len(drawn) // 12)
    hits = sum(_stroke_near(shot, *to_screen(u, v)) for u, v in drawn[::step])
    return hits, len(drawn[::step])


def _stroke_near(shot: np.ndarray, x_px: float, y_px: float) -> bool:
    """Whether the overlay's stroke green (0, 255, 64), which the lit patch (about 30, 170, 60)
    never is, lies within 4 px of screen point (x_px, y_px) on the screenshot."""
    x, y = round(x_px), round(y_px)
    win = shot[max(0, y - 4) : y + 5, max(0, x - 4) : x + 5].reshape(-1, 3)
    return bool(np.any((win[:, 1] >= 240) & (win[:, 0] <= 40) & (win[:, 2] <= 110)))


def _overlaps(page: Any, a: str, b: str) -> bool:
    """Whether the boxes of the elements ``a`` and ``b`` intersect on the screen."""
    ba, bb = page.locator(a).bounding_box(), page.locator(b).bounding_box()
    return not (
        ba["x"] + ba["width"] <= bb["x"]
        or bb["x"] + bb["width"] <= ba["x"]
        or ba["y"] + ba["height"] <= bb["y"]
        or bb["y"] + bb["height"] <= ba["y"]
    )


class Operator:
    """Plays the person at the console: whenever the grab asks for help, waits until the patch
    is in full view (a steady count of its pixels: the arm holds still), re-seeds on it and
    resumes."""

    def __init__(self, page: Any) -> None:
        self.page = page
        self.counts: list[int] = []
        self.answered = 0

    def tick(self) -> str:
        """Look once (and answer an assistance request when ready); returns the stage."""
        page = self.page
        stage = _stage(page)
        _, _, n = green_patch_centre(page)
        page.wait_for_timeout(250)
        if stage != "assist":
            self.counts.clear()
            return stage
        self.counts = [*self.counts[-3:], n]
        c = self.counts
        if len(c) < 4 or min(c) < 2000 or max(c) > 1.03 * min(c):
            return stage  # hidden, or still changing
        if page.is_visible("#assist-hide"):
            page.click("#assist-hide")
        try:
            _click_patch(page)
        except AssertionError:  # every click refused as stale (a loaded machine): look again
            self.counts.clear()
            return stage
        page.wait_for_timeout(600)
        if page.evaluate("window.umbra.state.overlay?.status") == "tracking":
            page.click("#commands button[data-action=resume]")
            self.answered += 1
            self.counts.clear()
            page.wait_for_timeout(500)
        return stage

    def until_done(self, run: GraphRun, timeout_s: float = 90.0) -> int:
        """Answer until the run ends; the number of requests answered."""
        deadline = time.monotonic() + timeout_s
        while run.proc.poll() is None and time.monotonic() < deadline:
            try:
                self.tick()
            except Exception:  # the page closed with the run
                break
        return self.answered

    def check_overlay_while_tracking(self, shot: Path, timeout_s: float = 60.0) -> None:
        """While the snake tracks in the approach, the overlay's green is on the snake; then
        a screenshot of the page goes to ``shot``."""
        deadline = time.monotonic() + timeout_s
        result = (0, 0)
        while time.monotonic() < deadline:
            stage = self.tick()
            tracking = self.page.evaluate("window.umbra.state.overlay?.status") == "tracking"
            if stage == "approach" and tracking:
                result = _overlay_green_on_snake(self.page)
                if result[1] >= 8 and result[0] >= 0.5 * result[1]:  # a misplaced overlay: ~0
                    shot.parent.mkdir(parents=True, exist_ok=True)
                    self.page.screenshot(path=str(shot))
                    return
        raise AssertionError(f"overlay not found on the snake: {result[0]} of {result[1]}")


def test_a_person_clicks_the_patch_and_the_grab_completes(tmp_path: Path) -> None:
    run = GraphRun(["graphs/tool_pickup.yaml", *NO_SIM_CLICK], tmp_path / "run")
    try:
        url = run.wait_url()
        with chromium() as browser:
            page = open_console(browser, url)
            second = open_console(browser, url)
            take_control(page)
            _refused_click(second, 600, 400)  # a viewer without control: refused
            _click_patch(page)
            # the seed starts the approach; on a loaded machine the snake may ask for help
            # at once (the person answers that below)
            moving = ("approach", "assist", "final_grab", "done")
            _wait_stage(page, moving, run)
            _wait_stage(second, moving, run)  # the second page sees the same run
            assert page.evaluate("window.umbra.name") in second.inner_text("#holder")
            person = Operator(page)
            person.check_overlay_while_tracking(tmp_path / "console.png")
            person.until_done(run)  # on a loaded machine the snake may ask for help
            code = run.wait(30)
        out = run.text()
        assert code == 0, out[-3000:]
        assert "grasped" in out
        assert "console.sim_seeds: 0" in out
    finally:
        run.kill()


def test_an_occluder_asks_for_help_the_person_reseeds_and_resumes(tmp_path: Path) -> None:
    # the occluder comes 12 s after the camera's first frame: in the approach when the person
    # clicks within 1 .. 10 s of it (opening the page takes a few seconds on a loaded machine)
    fault_at_s = 12.0
    fault = [
        "--set", "camera.fault=occluder", "--set", f"camera.fault_at_s={fault_at_s}",
        "--set", "camera.fault_duration_s=3",
    ]  # fmt: skip
    run = GraphRun(["graphs/tool_pickup.yaml", *NO_SIM_CLICK, *fault], tmp_path / "run")
    try:
        url = run.wait_url()
        with chromium() as browser:
            page = open_console(browser, url)
            take_control(page)
            _click_patch(page)
            clicked_at = page.evaluate("window.umbra.state.t")  # [s] since the console began
            assert clicked_at < fault_at_s - 2.0, f"the page took {clicked_at} s to be clicked"
            try:
                page.wait_for_selector("#assist[open]", timeout=40000)
            except Exception as exc:
                raise AssertionError(f"no assistance dialog:\n{run.text()[-4000:]}") from exc
            reason = page.evaluate("window.umbra.state.assist.reason")
            assert reason.startswith("snake failure"), reason
            assert page.inner_text("#assist-reason")  # in plain words, the exact one a click away
            assert page.evaluate("window.umbra.state.banner").startswith("servo side at zero")
            page.wait_for_function(  # the frame that caused the stop
                "document.getElementById('assist-img').naturalWidth === 1280", timeout=5000
            )
            page.wait_for_timeout(300)
            page.screenshot(path=str(tmp_path / "console_assist.png"))
            # the dialog covers neither the live image nor the banner nor the grab's buttons
            for selector in ("#video", "#banner", "#commands button[data-action=pause]", "#jog"):
                assert not _overlaps(page, "#assist", selector), selector
            page.click("#assist button[data-action=resume]")  # the snake is still failed
            page.wait_for_function(
                "window.umbra.notices.some(n => n.text.includes('resume refused'))", timeout=10000
            )
            assert _stage(page) == "assist"
            assert Operator(page).until_done(run) >= 1
            code = run.wait(30)
        out = run.text()
        assert code == 0, out[-3000:]
        assert "grasped" in out
        assert "occluder" in out
    finally:
        run.kill()


def _graph_recording_the_jog(tmp_path: Path) -> Path:
    """graphs/tool_pickup.yaml plus a Recorder in `smart` of REG_VEL's jog input and output."""
    text = (REPO / "graphs" / "tool_pickup.yaml").read_text()
    recorder = (
        "  rec:\n    type: Recorder\n    process: smart\n"
        "    params: {channels: [jog, twist], path: jog.mcap}\n"
        "connections:\n  - console.jog ~> rec.jog\n  - register.twist -> rec.twist\n"
    )
    assert text.count("\nconnections:\n") == 1
    path = tmp_path / "tool_pickup_jog.yaml"
    path.write_text(text.replace("\nconnections:\n", "\n" + recorder, 1))
    return path


def _hold(page: Any, label: str) -> None:
    box = page.locator("#jog button", has_text=label).bounding_box()
    page.mouse.move(box["x"] + 5, box["y"] + 5)
    page.mouse.down()


def test_the_jog_pad_moves_the_arm_only_while_held(tmp_path: Path) -> None:
    from umbra.runtime.recording.samples import iter_samples

    graph = _graph_recording_the_jog(tmp_path)
    # the test ends the run itself: the duration only bounds it (a loaded machine may take
    # half a minute to start the three processes, and the run's clock runs meanwhile)
    run = GraphRun([str(graph), *NO_SIM_CLICK, "--duration", "120"], tmp_path / "run")
    try:
        url = run.wait_url()
        with chromium() as browser:
            page = open_console(browser, url)
            page.wait_for_function("window.umbra.state.joints.length === 6", timeout=10000)

            def q() -> np.ndarray:
                return np.array(page.evaluate("window.umbra.state.joints.map(j => j.q_deg)"))

            click_image(page, 300, 300)  # before taking control: refused, nothing moves
            take_control(page)
            q0 = q()
            page.wait_for_timeout(700)
            assert np.abs(q() - q0).max() < 0.05  # at rest
            page.evaluate("document.getElementById('jog-speed').value = '1'")  # full speed
            _hold(page, "z+")
            held_at = time.monotonic()
            page.wait_for_timeout(2000)
            page.mouse.up()
            held_s = time.monotonic() - held_at
            page.wait_for_function(  # the joint angles on the page change (they may lag)
                f"Math.max(...window.umbra.state.joints.map((j, i) => Math.abs(j.q_deg - "
                f"{q0.tolist()}[i]))) > 0.3",
                timeout=15000,
            )
            page.wait_for_timeout(1000)
            # the page hangs mid-jog (its script paused: no keep-alive, the socket stays open)
            cdp = page.context.new_cdp_session(page)
            cdp.send("Debugger.enable")
            _hold(page, "x+")
            page.wait_for_timeout(1000)
            cdp.send("Debugger.pause")
            time.sleep(0.8)
            cdp.send("Debugger.resume")
            page.mouse.up()
            page.wait_for_timeout(1000)
            page.click("#commands button[data-action=abort]")
            page.wait_for_timeout(300)
        run.kill()
        summary = json.loads((tmp_path / "run" / "summary-umbra.json").read_text())
        operator = next(m for m in summary["modules"] if m["module"] == "operator")
        assert operator["stepped_aside_at_s"] is not None  # the simulated operator stepped aside
        assert operator["clicked_at_s"] is None
        page_side = json.loads((tmp_path / "run" / "summary-ui.json").read_text())  # own process
        console = next(m for m in page_side["modules"] if m["module"] == "console")
        assert console["deadman_expired"] >= 1  # the hung page's jog
        smart = json.loads((tmp_path / "run" / "summary-smart.json").read_text())
        register = next(m for m in smart["modules"] if m["module"] == "register")
        # REG_VEL passed the jog only while a button was held: 2 s, then 1 s and the hung page
        # (at most its 0.1 s watchdog and the dead-man's 0.15 s), 100 Hz ticks
        assert 100 <= register["jog_ticks"] <= (held_s + 1.0 + 0.25 + 0.6) * 100, (
            register["jog_ticks"],
            held_s,
        )
        # every tick the arm moved, REG_VEL had received a jog (the console forwards one per
        # keep-alive of the page) at most its timeout earlier
        jogs, moving = [], []
        for sample in iter_samples(tmp_path / "run" / "jog.mcap"):
            t = sample.log_ns / 1e9
            if sample.topic == "jog" and np.any(sample.message.vector):
                jogs.append(t)
            elif sample.topic == "twist" and np.any(sample.message.vector):
                moving.append(t)
        assert len(moving) >= 100 and jogs
        waits = [t - max(j for j in jogs if j <= t + 1e-6) for t in moving]
        assert max(waits) <= 0.1 + 0.012, max(waits)  # REG_VEL's timeout and one tick
        gaps = np.diff(jogs)
        assert np.median(gaps) >= 0.02, np.median(gaps)  # keep-alives (40 ms), not 100 Hz
    finally:
        run.kill()


def _inside_viewport(page: Any, selector: str) -> bool:
    size = page.viewport_size
    b = page.locator(selector).bounding_box()
    return (
        b is not None
        and b["x"] >= 0
        and b["y"] >= 0
        and b["x"] + b["width"] <= size["width"]
        and b["y"] + b["height"] <= size["height"]
    )


def _shot_when_plotted(
    viewer: Any,
    shot: Path,
    stop_when: Callable[[], bool] = lambda: False,
    between: Callable[[], object] = lambda: None,
    timeout_s: float = 60.0,
) -> bool:
    """Once the viewer's plot holds more than 20 rows (2 s of servo errors), a screenshot of
    it with the 3-D panel and the plot shown; False when ``stop_when()`` turned true first.
    ``between()`` is called between looks (the person's :meth:`Operator.tick`, say)."""
    plotted = "!!(window.umbra.plot && window.umbra.plot.data[0].length > 20)"
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if viewer.evaluate(plotted):
            assert viewer.is_visible("section[data-panel=view3d]")
            assert viewer.is_visible("#plot canvas")
            viewer.screenshot(path=str(shot))
            return True
        if stop_when():
            return False
        between()
        viewer.wait_for_timeout(250)
    raise AssertionError("the viewer's plot never showed 2 s of servo errors")


def test_the_station_through_a_whole_run_at_1280x800_and_1920x1080(tmp_path: Path) -> None:
    """A person at 1280x800 seeds, answers an assistance request without scrolling and sees
    the run end with its verdict; a viewer at 1920x1080 watches with the 3-D panel open. The
    screenshots are the README's."""
    fault = [
        "--set", "camera.fault=occluder", "--set", "camera.fault_at_s=12",
        "--set", "camera.fault_duration_s=6",  # a seed from a slow page still meets it
        "--duration", "150", "--set", "world.timeout_s=150",  # a loaded page answers late
    ]  # fmt: skip
    run = GraphRun(["graphs/tool_pickup.yaml", *NO_SIM_CLICK, *fault], tmp_path / "run")
    images = REPO / "docs" / "images"
    try:
        url = run.wait_url()
        with chromium() as browser:
            person = open_console(browser, url, 1280, 800)
            take_control(person)
            _click_patch(person)
            viewer = open_console(browser, url, 1920, 1080)
            viewer.wait_for_function("window.umbra.view3d && window.umbra.view3d.links === 6")
            # the viewer's shot wants 2 s of servo errors on its plot; a seed that came late
            # (a loaded page) gives fewer before the occluder, and the rest come after resuming
            shot_1920 = images / "station-1920.png"
            operator = Operator(person)
            taken = _shot_when_plotted(
                viewer, shot_1920, stop_when=lambda: _stage(person) == "assist"
            )
            person.wait_for_selector("#assist[open]", timeout=40000)
            person.wait_for_function(
                "document.getElementById('assist-img').naturalWidth === 1280", timeout=5000
            )
            for selector in (
                "#assist button[data-action=resume]",
                "#assist button[data-action=abort]",
                "#commands button[data-action=pause]",
                "#take",
            ):
                assert _inside_viewport(person, selector), selector
            assert person.evaluate("document.scrollingElement.scrollHeight") <= 800
            person.wait_for_timeout(300)
            person.screenshot(path=str(images / "station-1280.png"))
            if not taken:  # the person answers meanwhile; no shot in 90 s fails the test
                _shot_when_plotted(viewer, shot_1920, between=operator.tick, timeout_s=90)
            assert operator.until_done(run) >= 1, run.text()[-2500:]
            code = run.wait(30)
            for page in (person, viewer):
                page.wait_for_function("window.umbra.ended", timeout=10000)
                assert "grasped" in page.inner_text("#ended"), page.inner_text("#ended")
                assert page.is_disabled("#commands button[data-action=abort]")
            viewer.wait_for_timeout(300)
            viewer.screenshot(path=str(images / "station-ended.png"))
        assert code == 0, run.text()[-3000:]
    finally:
        run.kill()
