"""The operator's station in real Chromium, as an operator uses it, for the console benchmark.

The page (Debian's Chromium, via Playwright) opens the station, shows its 3-D panel (three.js
drawing with WebGL: software WebGL through ANGLE's SwiftShader, as on a machine without a GPU),
takes control and clicks the live image every 0.4 s. Over a measured window that starts once the
3-D panel draws, it reads from the page what it showed: the glass-to-glass latency of each video
frame painted (frame stamp to paint, the figure the page reports to the console), video frames
painted per second, and frames the 3-D panel drew per second (``window.umbra.view3d.drawn``).
A 3-D panel that did not draw, or drew a picture of its background only, is an error: the
figures would be a page without it.
"""

from __future__ import annotations

import time
from typing import Any

import cv2
import numpy as np

from benchmarks.common import percentiles
from tests.browser import CHROMIUM, CHROMIUM_ARGS

#: WebGL in software (ANGLE on SwiftShader): headless Chromium on a machine without a GPU
WEBGL_FLAGS = ("--use-angle=swiftshader", "--enable-unsafe-swiftshader")
#: the 3-D panel's background (view3d.js: scene.background), BGR as OpenCV decodes a PNG
PANEL_BACKGROUND_BGR = (0x24, 0x20, 0x1D)
#: least share of the 3-D panel's pixels that must differ from its background (grid, chain,
#: frustum and the live image on it cover far more)
MIN_DRAWN_SHARE = 0.02
#: shortest measured window worth reporting [s]
MIN_WINDOW_S = 4.0
#: what the page holds at a moment: frames painted, their latencies so far, 3-D draws, page time
_COUNTERS = """() => ({painted: umbra.painted, latencies: umbra.latencies.length,
  drawn: umbra.view3d ? umbra.view3d.drawn : 0, t_ms: performance.now()})"""
_RENDERER = """() => { const g = document.createElement("canvas").getContext("webgl");
  if (!g) return "no WebGL"; const d = g.getExtension("WEBGL_debug_renderer_info");
  return d ? g.getParameter(d.UNMASKED_RENDERER_WEBGL) : g.getParameter(g.RENDERER); }"""


def launch_with_webgl(playwright: Any) -> Any:
    """Headless Chromium with the repository's flags (tests/browser.py) and software WebGL."""
    return playwright.chromium.launch(
        executable_path=str(CHROMIUM), args=[*CHROMIUM_ARGS, *WEBGL_FLAGS]
    )


def _open_3d_panel(page: Any) -> None:
    """Show the 3-D panel (as its Panels menu entry does) and wait until it draws."""
    page.wait_for_function("window.umbra.state && window.umbra.state.panels", timeout=20000)
    if not page.evaluate("window.umbra.state.panels.view3d"):
        raise RuntimeError("the graph does not feed the station's 3-D panel (no link poses)")
    page.evaluate("umbra.setPanel('view3d', true)")
    page.wait_for_function("window.umbra.view3d && window.umbra.view3d.drawn > 2", timeout=30000)


def drawn_share(png: bytes) -> float:
    """Share of a screenshot's pixels that differ from the 3-D panel's background."""
    img = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)
    off = np.abs(img.astype(int) - np.array(PANEL_BACKGROUND_BGR)).max(axis=2) > 8
    return float(off.mean())


def _window(page: Any, until: float, box: dict[str, float]) -> dict[str, Any]:
    """Click the image's centre every 0.4 s until ``until`` (``time.monotonic()`` [s]); what the
    page showed meanwhile: glass-to-glass p50/p95 [ms], video frames painted and 3-D draws per
    second."""
    if until - time.monotonic() < MIN_WINDOW_S:
        raise RuntimeError(
            f"the station took too long to open: {until - time.monotonic():.1f} s left of "
            f"the run to measure (expected >= {MIN_WINDOW_S:g} s)"
        )
    start = page.evaluate(_COUNTERS)
    clicks = 0
    while time.monotonic() < until:
        page.mouse.click(box["x"] + box["width"] * 0.5, box["y"] + box["height"] * 0.5)
        clicks += 1
        page.wait_for_timeout(400)
    stop = page.evaluate(_COUNTERS)
    latencies = page.evaluate(f"umbra.latencies.slice({start['latencies']}, {stop['latencies']})")
    window_s = (stop["t_ms"] - start["t_ms"]) / 1e3
    lat = percentiles(latencies, (50, 95)) if latencies else {}
    return {
        "window_s": round(window_s, 2),
        "clicks": clicks,
        "painted": stop["painted"] - start["painted"],
        "latency_p50_ms": round(lat["p50"], 2) if lat else None,
        "latency_p95_ms": round(lat["p95"], 2) if lat else None,
        "fps_shown": round((stop["painted"] - start["painted"]) / window_s, 2),
        "view3d_frames": stop["drawn"] - start["drawn"],
        "view3d_fps": round((stop["drawn"] - start["drawn"]) / window_s, 2),
    }


def watch_station(
    url: str, until: float, viewport: tuple[int, int], hidden_s: float
) -> dict[str, Any]:
    """Open the station at ``url`` in a ``viewport`` (CSS px) page and take control; then, each
    window clicking the image every 0.4 s: ``hidden_s`` seconds with the 3-D panel hidden (the
    same page without it, for comparison), and with the 3-D panel shown from its first draws
    until ``until`` (``time.monotonic()`` [s]). Returns ``{"hidden": ..., "shown": ...}`` (see
    ``_window``) and the 3-D panel's checks: links drawn, share of its pixels drawn, WebGL."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        browser = launch_with_webgl(p)
        page = browser.new_page(viewport={"width": viewport[0], "height": viewport[1]})
        page.goto(url)
        page.wait_for_function("window.umbra.painted > 2", timeout=20000)
        page.click("#take")
        page.wait_for_function(
            "window.umbra.state && window.umbra.state.control_session === window.umbra.session",
            timeout=10000,
        )
        page.evaluate("umbra.setPanel('view3d', false)")
        box = page.locator("#video").bounding_box()
        hidden = _window(page, time.monotonic() + hidden_s, box)
        _open_3d_panel(page)
        shown = _window(page, until, page.locator("#video").bounding_box())
        links = page.evaluate("umbra.view3d.links")
        renderer = page.evaluate(_RENDERER)
        share = drawn_share(page.locator("#view3d canvas").screenshot())
        browser.close()
    if shown["view3d_frames"] < 1 or share < MIN_DRAWN_SHARE:
        raise RuntimeError(
            f"the 3-D panel did not draw: {shown['view3d_frames']} frames in "
            f"{shown['window_s']:.1f} s, {share:.1%} of its pixels off its background "
            f"(expected >= {MIN_DRAWN_SHARE:.0%})"
        )
    return {
        "hidden": hidden,
        "shown": shown,
        "view3d_links": links,
        "view3d_drawn_share": round(share, 3),
        "webgl_renderer": renderer,
    }
