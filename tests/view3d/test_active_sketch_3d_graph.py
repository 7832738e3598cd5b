"""graphs/active_sketch_3d.yaml run for real (two processes, zenoh on loopback, real clock) with
Debian's Chromium watching its 3-D view: the PTU cameras' video reaches the page on their
frusta, the world's solids are drawn, and Active Sketch's snapshot and primitive are kept in
the scene file."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from tests.poll import wait_for
from tests.view3d.browser_support import block_outside_loopback, launch, needs_chromium

pytestmark = [pytest.mark.browser, pytest.mark.slow, needs_chromium]

REPO = Path(__file__).resolve().parents[2]
DURATION_S = 20  # snap1 and line1 come at ~6 s; the rest of it the page watches the video


def test_ptu_cameras_solids_and_sketch_items_in_the_3d_view(tmp_path: Path) -> None:
    from playwright.sync_api import sync_playwright

    out = tmp_path / "run"
    run = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "umbra.runtime.cli.main",
            "run",
            "graphs/active_sketch_3d.yaml",
            "--set",
            "view3d.port=0",
            "--duration",
            str(DURATION_S),
            "--out",
            str(out),
        ],
        cwd=REPO,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(run.stdout), daemon=True)
    reader.start()
    try:

        def address() -> str | None:
            for line in list(lines):
                found = re.search(r"3-D view: (http://127\.0\.0\.1:\d+/\?token=\S+)", line)
                if found:
                    return found.group(1)
            return None

        url = wait_for(address, 60, "the 3-D view's address", interval_s=0.05)
        with sync_playwright() as p:
            browser = launch(p)
            page = browser.new_page(viewport={"width": 1200, "height": 800})
            block_outside_loopback(page)
            page.goto(url)
            page.get_by_role("button", name="View from left").wait_for(timeout=30_000)
            while run.poll() is None:  # watch until the run ends
                time.sleep(0.5)
                if "snapshot snap1" in "".join(lines):
                    page.screenshot(path=str(tmp_path / "view3d.png"))
            browser.close()
        assert run.wait(timeout=60) == 0, "".join(lines[-40:])
    finally:
        if run.poll() is None:
            run.terminate()
            run.wait(timeout=30)
    reader.join(timeout=10)
    modules = json.loads((out / "summary-umbra.json").read_text())["modules"]
    view = next(m for m in modules if m["module"] == "view3d")
    # the PTU cameras' video went to the page (nothing is sent while no browser watches)
    assert view["video_frames_sent"]["left"] > 10 and view["video_frames_sent"]["right"] > 10
    assert view["video_frames_sent"]["wrist"] == 0  # this graph has no wrist camera
    assert view["update_parts_failed"] == 0
    scene = json.loads((out / "scene.json").read_text())
    cameras = {s["id"]: s["camera"] for s in scene["snapshots"]}
    assert {"snap1/a": "cam_left", "snap1/b": "cam_right"}.items() <= cameras.items()
    assert [p["kind"] for p in scene["primitives"]][:1] == ["line"]
    assert all((out / "scene.json.images" / s["image"]).exists() for s in scene["snapshots"])
