"""Real Chromium (Debian's, via Playwright) for the console's browser tests; never downloads one."""

from __future__ import annotations

import re
import subprocess
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from tests.browser import launch, needs_chromium  # noqa: F401 - re-exported for the tests

REPO = Path(__file__).resolve().parents[2]


@contextmanager
def chromium() -> Iterator[Any]:
    """A headless Chromium browser."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        browser = launch(p)
        try:
            yield browser
        finally:
            browser.close()


def open_console(browser: Any, url: str, width: int = 1500, height: int = 950) -> Any:
    """A page on the console, once it painted a few frames."""
    page = browser.new_page(viewport={"width": width, "height": height})
    page.goto(url)
    page.wait_for_function("window.umbra.painted > 2 && window.umbra.state", timeout=20000)
    return page


def take_control(page: Any, timeout_ms: float = 10000) -> None:
    """Click *Take control* and wait until the console names this page the holder."""
    page.click("#take")
    page.wait_for_function(
        "window.umbra.state && window.umbra.state.control_session === window.umbra.session",
        timeout=timeout_ms,
    )


def release_control(page: Any) -> None:
    """Click *Release control* and wait until the console says nobody holds it."""
    page.click("#release")
    page.wait_for_function("!window.umbra.state.control")


def image_to_screen_map(page: Any) -> Callable[[float, float], tuple[float, float]]:
    """The live video's image pixel (u, v) -> screen coordinates, as the page is laid out now
    (read once: a state arriving later may move the video by a line)."""
    box = page.locator("#video").bounding_box()
    w, h = page.evaluate("window.umbra.size")
    return lambda u, v: (box["x"] + u / w * box["width"], box["y"] + v / h * box["height"])


def image_to_screen(page: Any, u: float, v: float) -> tuple[float, float]:
    """Screen coordinates of image pixel (u, v) on the live video."""
    return image_to_screen_map(page)(u, v)


def click_image(page: Any, u: float, v: float) -> None:
    page.mouse.click(*image_to_screen(page, u, v))


def green_patch_centre(page: Any) -> tuple[float, float, int]:
    """Centre [px] and pixel count of the green patch in the painted frame (read from the
    canvas: what the operator sees)."""
    return tuple(
        page.evaluate(
            """() => { const c = document.getElementById('video');
      const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
      let su = 0, sv = 0, n = 0;
      for (let y = 0; y < c.height; y += 2) for (let x = 0; x < c.width; x += 2) {
        const i = (y * c.width + x) * 4;
        if (d[i + 1] > 120 && d[i] < 90 && d[i + 2] < 110) { su += x; sv += y; n++; } }
      return [n ? su / n : -1, n ? sv / n : -1, n]; }"""
        )
    )


class GraphRun:
    """``umbra run GRAPH`` in a subprocess; its output is read in a thread, the console's
    address parsed from it."""

    def __init__(self, args: list[str], out_dir: Path) -> None:
        self.proc = subprocess.Popen(
            ["umbra", "run", *args, "--out", str(out_dir)],
            cwd=REPO,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        self.lines: list[str] = []
        self.url = ""
        self._got = threading.Event()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.append(line)
            m = re.search(r"operator console: (http://\S+)", line)
            if m and not self.url:
                self.url = m.group(1)
                self._got.set()

    def wait_url(self, timeout: float = 60.0) -> str:
        if not self._got.wait(timeout):
            raise AssertionError("no console address printed:\n" + "".join(self.lines[-30:]))
        return self.url

    def wait(self, timeout: float) -> int:
        try:
            return self.proc.wait(timeout)
        finally:
            if self.proc.poll() is not None:  # its last lines read (the pipe's end)
                self._reader.join(timeout=10)

    def text(self) -> str:
        return "".join(self.lines)

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
