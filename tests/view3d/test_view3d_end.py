"""The 3-D page at the run's end, in Debian's Chromium: it says the run ended with the verdict,
a page that (re)connects after the end still learns it from the lingering server, and once the
server is gone the page keeps saying it (never viser's "Connecting..." for ever)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.poll import wait_for
from tests.view3d.browser_support import block_outside_loopback, launch, needs_chromium
from umbra.connectors.states import Outcome, Verdict
from umbra.modules.view3d.view3d import View3D
from umbra.runtime.harness import ModuleHarness

pytestmark = [pytest.mark.browser, needs_chromium]

VERDICT = "grasped: the tool is 0.9 mm from the fingers' centre"


def _text(page) -> str:
    return page.inner_text("body")


def _open(browser, url: str, closed: list[bool] | None = None):
    """A page on ``url``; ``closed`` gets an entry when its socket closes."""
    page = browser.new_page(viewport={"width": 1100, "height": 700})
    block_outside_loopback(page)
    if closed is not None:
        page.on("websocket", lambda ws: ws.on("close", lambda _ws: closed.append(True)))
    page.goto(url)
    return page


def test_the_3d_page_ends_with_the_verdict_and_keeps_it_once_the_server_is_gone(
    tmp_path: Path,
) -> None:
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p, ModuleHarness(View3D, {"port": 0}, output_dir=tmp_path) as h:
        browser = launch(p)
        try:
            view = h.module
            closed: list[bool] = []
            early = _open(browser, view.address, closed)
            wait_for(lambda: view.page.clients() == 1, 20.0, "the page to connect", interval_s=0.05)
            h.push("verdict", Verdict(stage="judged", message=VERDICT, outcome=Outcome.SUCCEEDED))
            h.step(dt=0.05)
            early.wait_for_function(f"document.body.innerText.includes({VERDICT!r})", timeout=20000)
            assert "Run ended" not in _text(early)  # the run lives: a verdict, not the end
            h.stop()  # the run ends: the server serves on (it lingers) with the end said
            for page in (early, _open(browser, view.address)):  # a page connecting after it too
                page.wait_for_function(
                    f"document.body.innerText.includes('Run ended: ' + {VERDICT!r})",
                    timeout=20000,
                )
                assert "the run has ended" in _text(page)
            view.page.stop()  # what the process's end does to the lingering server
            wait_for(
                lambda: closed or early.wait_for_timeout(50),
                20.0,
                "the socket to close",
                interval_s=0.05,
            )
            early.wait_for_function(  # viser's client knows: it dims the panel it can't send from
                "[...document.querySelectorAll('div')].some((d) => d.style.opacity === '0.5')",
                timeout=10000,
            )
            text = _text(early)
            assert f"Run ended: {VERDICT}" in text and "Connecting..." not in text, text
            early.screenshot(path=str(tmp_path / "view3d-ended.png"))
        finally:
            browser.close()
