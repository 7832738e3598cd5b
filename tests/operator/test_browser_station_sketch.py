"""Active Sketch in the station's 3-D panel, in real Chromium: the snapshots' frusta, a placed
primitive and the path being played with the arm's place on it, drawn beside the arm, with
names that do not cover each other."""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.operator.browser import chromium, needs_chromium
from tests.operator.helpers import stepping
from tests.operator.test_browser_station import Plant
from tests.operator.test_sketch_scene import T_BASE_TABLE, path, snapshot
from umbra.connectors.messages import Poses
from umbra.connectors.path_messages import VcrState
from umbra.connectors.sketch_messages import SketchPrimitive
from umbra.modules.operator.console import OperatorConsole
from umbra.runtime.harness import ModuleHarness

pytestmark = [pytest.mark.browser, pytest.mark.slow, needs_chromium]

ROOT = Path(__file__).resolve().parents[2]


def _pixels(page: Any, rgb: int) -> int:
    """Pixels of colour ``rgb`` (within a small tolerance) on the 3-D panel's canvas."""
    from PIL import Image as PILImage

    shot = page.locator("#view3d canvas").screenshot()
    px = np.asarray(PILImage.open(io.BytesIO(shot)).convert("RGB")).astype(int)
    want = [(rgb >> 16) & 255, (rgb >> 8) & 255, rgb & 255]
    return int(np.sum(np.all(np.abs(px - want) < 40, axis=-1)))


def _labels_apart(page: Any) -> list[str]:
    """The names on the panel that cover another (none expected)."""
    boxes = page.eval_on_selector_all(
        "#view3d-labels .frame-name",
        "els => els.map(e => { const r = e.getBoundingClientRect();"
        " return [e.textContent, r.left, r.top, r.right, r.bottom]; })",
    )
    covered = []
    for i, (name, x0, y0, x1, y1) in enumerate(boxes):
        for other, a0, b0, a1, b1 in boxes[i + 1 :]:
            if x0 < a1 - 1 and a0 < x1 - 1 and y0 < b1 - 1 and b0 < y1 - 1:
                covered.append(f"{name} / {other}")
    return covered


def test_the_3d_panel_draws_snapshots_primitives_and_the_path_being_played() -> None:
    h = ModuleHarness(OperatorConsole, {}, frames={"base->table": T_BASE_TABLE})
    plant = Plant(h)
    links = np.stack([np.eye(4), np.eye(4)])
    links[0][:3, 3] = [0.0, 0.0, 0.6]
    links[1][:3, 3] = [0.4, 0.0, 0.5]
    plant.steady = {
        "link_poses": Poses(matrices=links, children=["shoulder", "flange"], frame="base")
    }
    with stepping(plant), chromium() as browser:
        page = browser.new_page(viewport={"width": 1920, "height": 1080})
        page.goto(h.module.url)
        page.wait_for_function("window.umbra.view3d && window.umbra.view3d.links === 2")
        page.wait_for_timeout(400)
        orange_before = _pixels(page, 0xFF8C00)
        with plant.lock:
            plant.extra += [
                ("snapshot", snapshot()),
                (
                    "primitive",
                    SketchPrimitive(
                        primitive_id="pipe",
                        kind="line",
                        points=np.array([[0.35, 0.0, 0.1], [0.65, 0.0, 0.1]]),
                        edges=np.array([[0, 1]]),
                        frame="table",
                    ),
                ),
                ("path", path()),
            ]
            plant.steady["vcr_state"] = VcrState(path_id="p1", mode="playing", s=0.5, progress=0.5)
        page.wait_for_function(
            "(() => { const k = window.umbra.view3d.sketch; return k && k.snapshots === 1"
            " && k.primitives === 1 && k.path === 11 && k.at !== null; })()",
            timeout=15000,
        )
        sketch = page.evaluate("window.umbra.view3d.sketch")
        assert sketch["at"] == [0.6, -0.2, 0.35] and sketch["progress"] == 0.5
        page.wait_for_timeout(400)
        names = page.eval_on_selector_all(
            "#view3d-labels .frame-name", "els => els.map(e => e.textContent)"
        )
        for name in ("snapshot s1", "line pipe", "path grab pipe", "playing 50 %", "flange"):
            assert name in names, (name, names)
        assert _labels_apart(page) == []
        assert _pixels(page, 0xFF8C00) > orange_before + 20  # the snapshots' frusta
        assert _pixels(page, 0xFF44FF) > 5  # the primitive
        assert _pixels(page, 0x33DD55) > 20  # the played part of the path and the marker
        # the player moves on: the marker follows
        with plant.lock:
            plant.steady["vcr_state"] = VcrState(path_id="p1", mode="done", s=1.0, progress=1.0)
        page.wait_for_function("window.umbra.view3d.sketch.progress === 1", timeout=15000)
        assert page.evaluate("window.umbra.view3d.sketch.at") == [0.7, -0.2, 0.35]
        page.locator("#view3d").screenshot(path=str(ROOT / "docs/images/station-3d-sketch.png"))
