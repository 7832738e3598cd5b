"""The console page in real Chromium, against the module in the harness (fast: no graph run).

A stepping thread plays the scheduler (camera frames at 30 fps of sim time, steps every 10 ms);
the test drives the page like an operator and checks the module's outputs.
"""

from __future__ import annotations

import threading
import time
from typing import Any

import numpy as np
import pytest

from tests.operator.browser import (
    chromium,
    click_image,
    image_to_screen,
    needs_chromium,
    open_console,
    take_control,
)
from tests.operator.helpers import image, rectangle_contour
from tests.poll import wait_for
from umbra.connectors.messages import Message
from umbra.modules.operator.console import OperatorConsole
from umbra.modules.operator.jog import KEEPALIVE_S
from umbra.runtime.harness import ModuleHarness

pytestmark = [pytest.mark.browser, needs_chromium]


class Stepper(threading.Thread):
    """Steps the console in its own thread; other threads queue pushes through :meth:`push`."""

    def __init__(self, h: ModuleHarness) -> None:
        super().__init__(daemon=True)
        self.h = h
        self.sent: list[tuple[float, str, Message]] = []  # (wall time, output, sample)
        self._pushes: list[tuple[str, Message]] = []
        self._lock = threading.Lock()
        self._halt = threading.Event()

    def push(self, port: str, sample: Message) -> None:
        with self._lock:
            self._pushes.append((port, sample))

    def run(self) -> None:
        k = 0
        while not self._halt.is_set():
            with self._lock:
                pushes, self._pushes = self._pushes, []
            for port, sample in pushes:
                self.h.push(port, sample)
            if k % 3 == 0:
                self.h.push("image", image())
            out = self.h.step(dt=0.01)
            now = time.monotonic()
            for port, samples in out.items():
                self.sent.extend((now, port, s) for s in samples)
            k += 1
            time.sleep(0.01)

    def stop(self) -> None:
        self._halt.set()
        self.join(5)

    def outputs(self, port: str, since: float = 0.0) -> list[tuple[float, Any]]:
        return [(t, s) for t, p, s in list(self.sent) if p == port and t >= since]


def _moving(stepper: Stepper, since: float) -> bool:
    """Whether the console sent a non-zero jog since wall time ``since``."""
    return any(np.any(s.vector) for _, s in stepper.outputs("jog", since))


def _hold_until_moving(page: Any, stepper: Stepper, axis: int, sign: int) -> float:
    """Hold a jog on ``page`` until the console forwards it, as an operator would: a hold the
    console stopped (on a loaded machine the page's picture can be older than the console's
    bound) is released and, once the console has taken the release, pressed again. Returns the
    wall time of the press that moved."""
    hold = f"window.umbra.holdJog({axis}, {sign})"
    pressed, held = time.monotonic(), True
    page.evaluate(hold)

    def again() -> None:
        nonlocal pressed, held
        stopped = page.evaluate("Boolean(window.umbra.state && window.umbra.state.jog_stopped)")
        if stopped and held:
            page.evaluate("window.umbra.releaseJog()")
            held = False
        elif not stopped and not held:
            pressed, held = time.monotonic(), True
            page.evaluate(hold)

    wait_for(lambda: _moving(stepper, pressed), 20.0, "a jog", step=again)
    return pressed


def _spy_keepalives(console: OperatorConsole) -> list[float]:
    """Wall times at which held-jog keep-alives reached the console's dead-man."""
    arrivals: list[float] = []
    update = console.deadman.update

    def spy(session: str, held: bool, *rest: Any) -> None:
        if held:
            arrivals.append(rest[-1])
        update(session, held, *rest)

    console.deadman.update = spy  # type: ignore[method-assign]
    return arrivals


def _pixel(page: Any, u: float, v: float) -> list[int]:
    """RGB of the screen pixel over image pixel (u, v) (the overlay as drawn)."""
    import io

    from PIL import Image as PILImage

    x, y = image_to_screen(page, u, v)
    png = page.screenshot(clip={"x": x - 3, "y": y - 3, "width": 7, "height": 7})
    arr = np.asarray(PILImage.open(io.BytesIO(png)).convert("RGB"))
    return arr.reshape(-1, 3).tolist()


def test_overlay_seeds_control_and_the_dead_man_jog_in_chromium() -> None:
    T = np.eye(4)
    T[:3, 3] = [0, 0, -0.12]
    with ModuleHarness(OperatorConsole, {}, frames={"tool->camera": T}) as h:
        stepper = Stepper(h)
        stepper.start()
        try:
            with chromium() as browser:
                page = open_console(browser, h.module.url)
                watcher = open_console(browser, h.module.url)
                take_control(page)
                # the overlay is drawn in the browser where the snake is
                stepper.push("contour", rectangle_contour())
                page.wait_for_function("window.umbra.state.overlay !== null", timeout=10000)
                page.wait_for_timeout(200)
                top_edge = _pixel(page, 340.0, 200.0)
                assert any(g >= 240 and r <= 40 and b <= 110 for r, g, b in top_edge), top_edge
                offending = _pixel(page, 360.0, 200.0)  # vertex 3 is flagged: red
                assert any(r > 200 and g < 90 and b < 90 for r, g, b in offending), offending
                away = _pixel(page, 100.0, 400.0)
                assert not any(g >= 240 and r <= 40 for r, g, b in away)
                # a viewer without control cannot command; it is told why
                click_image(watcher, 340.0, 230.0)
                watcher.wait_for_function(
                    "window.umbra.notices.some(n => n.text.includes('take control first') ||"
                    " n.text.includes('holds control'))",
                    timeout=10000,
                )
                assert not stepper.outputs("seed")
                watcher.wait_for_function(  # the refusal is counted on every page
                    "document.getElementById('refused').textContent.startsWith('1 refused')",
                    timeout=10000,
                )
                # every page shows who holds control
                holder = page.evaluate("window.umbra.name")
                assert holder in watcher.inner_text("#holder")
                # the operator's click seeds the snake where it was made
                click_image(page, 341.0, 229.0)
                wait_for(lambda: stepper.outputs("seed"), 10.0, "a seed")
                u, v = stepper.outputs("seed")[-1][1].uv
                assert abs(u - 341.0) < 2.0 and abs(v - 229.0) < 2.0
                # dragging a box gives a region seed [u_min, v_min, u_max, v_max]
                page.mouse.move(*image_to_screen(page, 372.0, 256.0))
                page.mouse.down()
                page.mouse.move(*image_to_screen(page, 306.0, 204.0), steps=5)
                page.mouse.up()
                wait_for(lambda: len(stepper.outputs("seed")) == 2, 10.0, "a second seed")
                box = stepper.outputs("seed")[-1][1].uv
                np.testing.assert_allclose(box, [306.0, 204.0, 372.0, 256.0], atol=2.0)
                # control passes: released, taken by the other page, shown on both
                page.click("#release")
                watcher.wait_for_function(
                    "document.getElementById('holder').textContent === 'nobody'", timeout=10000
                )
                take_control(watcher)
                watcher_name = watcher.evaluate("window.umbra.name")
                page.wait_for_function(
                    f"document.getElementById('holder').textContent === {watcher_name!r}",
                    timeout=10000,
                )
                assert page.is_disabled("#take") and page.is_disabled("#release")
                watcher.click("#release")
                take_control(page)
                # dead-man jog: motion only while the button is held, at the keep-alive period
                arrivals = _spy_keepalives(h.module)
                x_plus = page.locator("#jog button", has_text="x+")
                box = x_plus.bounding_box()
                page.mouse.move(box["x"] + 5, box["y"] + 5)
                # pressed again where the console stopped the hold before it moved anything (a
                # busy page's picture older than the console's bound)
                for _ in range(5):
                    pressed = time.monotonic()
                    page.mouse.down()
                    page.wait_for_timeout(600)
                    why = page.evaluate("window.umbra.state.jog_stopped")
                    if not why or _moving(stepper, pressed):
                        break
                    page.mouse.up()
                    wait_for(
                        lambda: not page.evaluate("window.umbra.state.jog_stopped"),
                        10.0,
                        "the release taken",
                        step=lambda: page.wait_for_timeout(20),
                    )
                held = stepper.outputs("jog", pressed)
                assert sum(s.vector[0] > 0.009 for _, s in held) >= 6, held
                kept = [t for t in arrivals if t >= pressed]
                assert kept, "no keep-alive came while the button was held"
                # A held jog stops only where the page's keep-alive came late (a loaded machine
                # can hold the page's timer back): never while they keep coming in time.
                for stop in (t for t, s in held if not s.vector[0] > 0.009):
                    last = max(t for t in [pressed, *kept] if t <= stop)
                    assert stop - last > h.module.params.deadman_s, (stop, last, kept)
                # at each keep-alive or, between two, at the keep-alive period: not every step
                period_bound = (time.monotonic() - pressed) / KEEPALIVE_S + 1
                assert len(held) <= len(kept) + period_bound, (len(held), len(kept))
                page.mouse.up()
                released = time.monotonic()
                page.wait_for_timeout(400)
                assert not _moving(stepper, released + 0.3)
                assert not np.any(stepper.outputs("jog")[-1][1].vector)
                # losing focus releases too, and so does a hidden page
                for release in (
                    "window.dispatchEvent(new Event('blur'))",
                    "Object.defineProperty(document, 'hidden', {value: true, configurable: true});"
                    "document.dispatchEvent(new Event('visibilitychange'));"
                    "delete document.hidden",
                ):
                    _hold_until_moving(page, stepper, 2, 1)
                    page.evaluate(release)
                    stopped = time.monotonic()
                    page.wait_for_timeout(400)
                    assert not _moving(stepper, stopped + 0.3), release
                    assert not np.any(stepper.outputs("jog")[-1][1].vector)
                # a page that hangs mid-jog (its script paused: no keep-alive, socket open): the
                # console forwards the held jog at the keep-alive period only until the dead-man
                # expires (deadman_s after the last keep-alive), then sends zero
                cdp = page.context.new_cdp_session(page)
                cdp.send("Debugger.enable")
                _hold_until_moving(page, stepper, 0, -1)
                expired = h.module.deadman.expired
                cdp.send("Debugger.pause")
                frozen = time.monotonic()
                time.sleep(0.6)  # the page stays frozen this long
                late = [t for t, s in stepper.outputs("jog", frozen) if np.any(s.vector)]
                last_keepalive = max(arrivals)
                deadman_s = h.module.params.deadman_s
                assert len(late) <= deadman_s / KEEPALIVE_S + 2, late
                assert all(t <= last_keepalive + deadman_s + 0.1 for t in late), (
                    late,
                    last_keepalive,
                )
                assert not np.any(stepper.outputs("jog")[-1][1].vector)
                assert h.module.deadman.expired == expired + 1
                cdp.send("Debugger.resume")
                page.evaluate("window.umbra.releaseJog()")
                # a page that vanishes mid-jog: the dead-man stops the jog
                page.evaluate("window.umbra.holdJog(3, 1)")
                page.wait_for_timeout(300)
                page.evaluate("window.umbra.send = () => {}")  # no more keep-alives
                page.evaluate("clearInterval = () => {}")
                page.close()
                gone = time.monotonic()
                time.sleep(0.6)  # a window: the gone page moves nothing
                assert not _moving(stepper, gone + 0.3)
                assert not np.any(stepper.outputs("jog")[-1][1].vector)
        finally:
            stepper.stop()


def test_zoom_sliders_in_chromium() -> None:
    with ModuleHarness(OperatorConsole, {"zoom_names": ["left", "right"]}) as h:
        stepper = Stepper(h)
        stepper.start()
        try:
            with chromium() as browser:
                page = open_console(browser, h.module.url)
                viewer = open_console(browser, h.module.url)
                take_control(page)
                slider = page.locator("#zoom-left")
                box = slider.bounding_box()
                page.mouse.click(box["x"] + 0.8 * box["width"], box["y"] + box["height"] / 2)
                wait_for(lambda: stepper.outputs("zoom_1"), 10.0, "a zoom")
                assert abs(stepper.outputs("zoom_1")[-1][1].value - 0.8) < 0.06
                assert not stepper.outputs("zoom_2")  # the other camera is left alone
                page.wait_for_function(
                    "document.getElementById('zoom-left-value').textContent.startsWith('0.')"
                )
                # a viewer without control moves the other slider: refused, nothing sent
                box = viewer.locator("#zoom-right").bounding_box()
                viewer.mouse.click(box["x"] + 0.3 * box["width"], box["y"] + box["height"] / 2)
                viewer.wait_for_function(
                    "window.umbra.notices.some(n => n.text.startsWith('refused zoom'))",
                    timeout=10000,
                )
                assert not stepper.outputs("zoom_2")
        finally:
            stepper.stop()


def test_a_run_that_dies_without_a_word_is_not_shown_as_live() -> None:
    """The console's web server goes away without the run's end being sent (a killed process):
    the page disables its commands at once and, after a few seconds without an answer, says the
    run ended or failed instead of "reconnecting" for ever."""
    from umbra.modules.operator.web_server import release_server

    with ModuleHarness(OperatorConsole, {}) as h:
        stepper = Stepper(h)
        stepper.start()
        try:
            with chromium() as browser:
                page = open_console(browser, h.module.url)
                take_control(page)
                assert page.is_enabled("#release")
                stepper.stop()  # the process stops stepping, then its server is gone
                release_server(h.module._server)
                h.module._server = None
                page.wait_for_function("$('conn').textContent !== 'connected'")
                assert page.is_disabled("#release")  # no control over a run that is not there
                assert not page.evaluate("window.umbra.ended")  # nobody said the run ended
                page.wait_for_function(
                    "document.getElementById('conn').textContent.includes('ended or failed')",
                    timeout=15000,
                )
                assert "no answer from the run for" in page.inner_text("#conn")
        finally:
            stepper.stop()
