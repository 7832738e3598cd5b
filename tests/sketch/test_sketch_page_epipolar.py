"""Issue #31 item 7 in real Chromium: the /sketch page draws the epipolar CURVE of a distorted
camera pair, in the snapshot's own image size (1280 x 720 here), and keeps image b's vertex on it.

The reference curve is OpenCV's (``cv2.undistortPoints`` of the vertex in image a, points along
its ray through ``cv2.projectPoints`` into camera b); the page's polyline must follow it.
"""

from __future__ import annotations

import httpx
import numpy as np
import pytest

from tests.operator.browser import chromium, needs_chromium
from tests.sketch.test_sketch_epipolar_curve import (
    DIST,
    T_A,
    T_B,
    camera_matrix,
    distance_to,
    reference_curve,
)
from tests.sketch.test_sketch_page import Browser, Stepper
from umbra.connectors.messages import CameraModel
from umbra.connectors.sketch_messages import StereoSnapshot
from umbra.modules.sketch_page.sketch_page import SketchPage
from umbra.runtime.harness import ModuleHarness

WIDTH, HEIGHT = 1280, 720


def snapshot() -> StereoSnapshot:
    K = camera_matrix(WIDTH, HEIGHT)
    model = CameraModel(
        fx=K[0, 0], fy=K[1, 1], u0=K[0, 2], v0=K[1, 2], dist=DIST, width=WIDTH, height=HEIGHT
    )
    image = np.full((HEIGHT, WIDTH, 3), 60, np.uint8)
    return StereoSnapshot.of_pair(0.0, "snap1", (model, image, T_A), (model, image, T_B))


@pytest.mark.browser
@needs_chromium
def test_page_draws_the_distorted_epipolar_curve_at_1280x720() -> None:
    K = camera_matrix(WIDTH, HEIGHT)
    with ModuleHarness(SketchPage, {}) as h, Stepper(h) as stepper, chromium() as browser:
        stepper.push(h, "snapshot", snapshot())
        page = browser.new_context(viewport={"width": 1500, "height": 900}).new_page()
        page.goto(h.module.url)
        page.wait_for_function("window.sketch.state && window.sketch.state.snapshot", timeout=20000)
        assert page.get_attribute("#svg-b", "viewBox") == f"0 0 {WIDTH} {HEIGHT}"
        page.click("[data-testid=drop-line]")
        page.wait_for_function(
            "document.querySelectorAll('#svg-b polyline.epi').length === 2", timeout=20000
        )
        a = np.array(page.evaluate("window.sketch.a"))
        b = np.array(page.evaluate("window.sketch.b"))
        # the page's defaults scaled to the image
        np.testing.assert_allclose(a, [[220 * 2, 240 * 1.5], [420 * 2, 240 * 1.5]])
        drawn = page.evaluate(
            "[...document.querySelectorAll('#svg-b polyline.epi')].map((p) => "
            "p.getAttribute('points').split(' ').map((xy) => xy.split(',').map(Number)))"
        )
        worst_line = 0.0
        for i, points in enumerate(drawn):
            reference = reference_curve(K, a[i])
            points = np.array(points)
            assert len(points) > 20
            assert max(distance_to(reference, p) for p in points) < 0.05
            # image b's vertex rides on the curve
            assert distance_to(reference, b[i]) < 0.05
            F = np.array(page.evaluate("window.sketch.state.snapshot.F"))
            line = F @ np.append(a[i], 1.0)
            off = np.abs(points @ line[:2] + line[2]) / np.hypot(line[0], line[1])
            worst_line = max(worst_line, float(off.max()))
        assert worst_line > 1.0  # the straight line the page drew before was a pixel and more off
        page.screenshot(path="/tmp/g_sketch_epipolar.png")
        # the route answers with its token only, and refuses what is not a pixel, saying so
        viewer = Browser(h.module.url)
        good = viewer.client.get(viewer.root + "/sketch/epipolar?u=600&v=300")
        assert good.status_code == 200 and good.json()["snapshot"] == "snap1"
        bad = viewer.client.get(viewer.root + "/sketch/epipolar?u=nan&v=3")
        assert bad.status_code == 400
        assert bad.json()["error"] == "/sketch/epipolar: expected finite pixels, got [nan, 3.0]"
        assert httpx.get(viewer.root + "/sketch/epipolar?u=1&v=2").status_code == 403
        viewer.close()
