"""A real viewer: Lichtblick (the open-source Foxglove) in Debian's Chromium opens a zoom_targeting
recording with its images placed in 3-D, and a live pick-up with its video and the arm's frames.
Screenshots are kept in the test's folder (``lichtblick-*.png``) for a person to look at."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path
from urllib.parse import quote

import pytest

from tests.browser import CHROMIUM, needs_chromium
from tests.live.helpers import REPO, LiveRun
from tests.live.lichtblick import (
    WEBGL_ARGS,
    Served,
    colours,
    free_port,
    needs_lichtblick,
    unpack,
    with_layout,
)

pytestmark = [pytest.mark.slow, pytest.mark.browser, needs_chromium, needs_lichtblick]

_GRID = {
    "visible": True, "layerId": "foxglove.Grid", "size": 2, "divisions": 20, "instanceId": "grid",
    "frameLocked": True, "order": 1, "position": [0, 0, 0], "rotation": [0, 0, 0],
    "color": "#248eff", "lineWidth": 1,
}  # fmt: skip


def _camera(distance: float, target_z: float) -> dict:
    return {
        "distance": distance, "perspective": True, "phi": 55, "thetaOffset": 30,
        "targetOffset": [0, 0, target_z], "target": [0, 0, 0], "targetOrientation": [0, 0, 0, 1],
        "fovy": 45, "near": 0.01, "far": 100,
    }  # fmt: skip


def _layout(three_d: dict, image: dict) -> dict:
    return {
        "configById": {"3D!a": three_d, "Image!b": image},
        "globalVariables": {},
        "userNodes": {},
        "playbackConfig": {"speed": 1},
        "layout": {"direction": "row", "first": "3D!a", "second": "Image!b", "splitPercentage": 60},
    }


def _problems(page: object) -> str:
    """The text of Lichtblick's Problems tab (a missing transform is listed there)."""
    page.get_by_text("Problems").first.click()  # type: ignore[attr-defined]
    time.sleep(1.0)
    text = page.inner_text("body")  # type: ignore[attr-defined]
    return text


def _open(
    url: str, shot: Path, wait_s: float, play: bool, args: list[str] = WEBGL_ARGS
) -> tuple[bytes, str]:
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=str(CHROMIUM), args=args)
        try:
            page = browser.new_page(viewport={"width": 1400, "height": 800})
            page.set_default_timeout(120_000)  # two loaded cores
            page.goto(url)
            time.sleep(wait_s)  # two loaded cores: the app takes 10-20 s
            if play:
                page.keyboard.press("Space")
                time.sleep(8.0)
            png = page.screenshot(path=str(shot))
            return png, _problems(page)
        finally:
            browser.close()


#: The 3-D and image panels in a 1400 x 800 screenshot with the side bar open.
PANEL_3D = (330, 80, 960, 710)
PANEL_IMAGE = (975, 80, 1395, 710)


def test_a_zoom_targeting_recording_shows_its_images_placed_in_3d(tmp_path: Path) -> None:
    out = tmp_path / "zoom"
    cmd = [sys.executable, "-m", "umbra.runtime.cli.main", "run", "graphs/zoom_targeting.yaml"]
    cmd += ["--record", "--out", str(out), "--quiet"]
    subprocess.run(cmd, cwd=REPO, check=True, timeout=180, capture_output=True)
    root = unpack(tmp_path / "app")
    three_d = {
        "followTf": "base", "followMode": "follow-pose", "cameraState": _camera(3.2, 0.8),
        "scene": {"transforms": {"showLabel": True, "axisScale": 0.15, "labelSize": 0.04}},
        "topics": {
            "/tf_static": {"visible": True},
            "/calib_left/camera/mount": {"visible": True},
            "/calib_right/camera/mount": {"visible": True},
            "/calib_left/camera/calibration": {"visible": True},
            "/calib_right/camera/calibration": {"visible": True},
            "/view_left/image": {
                "visible": True, "cameraInfoTopic": "/calib_left/camera/calibration",
                "distance": 1.2,
            },
        },
        "layers": {"grid": _GRID},
    }  # fmt: skip
    image = {"imageMode": {"imageTopic": "/view_left/image"}}
    page = with_layout(root, "zoom.html", _layout(three_d, image))
    served = Served(root, free_port(), {"rec.mcap": out / "recording.mcap"})
    try:
        url = f"{served.base}/{page}?ds=remote-file&ds.url={served.base}/data/rec.mcap"
        png, problems = _open(url, tmp_path / "lichtblick-zoom.png", 15.0, play=True)
    finally:
        served.close()
    # before: "Missing transform from frame <left_camera> to frame <base>"
    assert "Missing transform" not in problems, problems[-1500:]
    assert "left_camera" in problems or "3D" in problems  # the page was read
    # the image drawn in the 3-D scene and in its panel: many colours, not a grid on grey
    assert colours(png, PANEL_3D) > 60
    assert colours(png, PANEL_IMAGE) > 40


def test_a_live_pickup_shows_its_video_and_the_arm_frames(tmp_path: Path) -> None:
    """The viewer is opened first (on two loaded cores the app takes up to a minute to load) on
    the address the run will print (a fixed port; the token from the operator page's token file,
    which the live server shares), then the pick-up starts (its operator clicks late, so it
    outlasts all this: the run ends at its grasp) and the app's reconnection finds it."""
    from playwright.sync_api import sync_playwright

    root = unpack(tmp_path / "app")
    port, live_port = free_port(), free_port()
    token = "live-test-token-0123456789abcdef"
    (tmp_path / "token").write_text(token + "\n")
    url = f"ws://127.0.0.1:{live_port}/?token={token}"
    three_d = {
        "followTf": "base", "followMode": "follow-pose", "cameraState": _camera(2.4, 0.45),
        "scene": {"transforms": {"showLabel": True, "axisScale": 0.25, "labelSize": 0.035}},
        "topics": {"/kinematics/link_poses": {"visible": True}, "/tf_static": {"visible": True}},
        "layers": {"grid": _GRID},
    }  # fmt: skip
    image = {
        "imageMode": {
            "imageTopic": "/camera/image",
            "annotations": {"/snake/contour/annotations": {"visible": True}},
        }
    }
    page_name = with_layout(root, "live.html", _layout(three_d, image))
    served = Served(root, port)
    args = ("--single-process", "--clock", "real", "--duration", "150")
    args += ("--foxglove-origin", f"http://127.0.0.1:{port}", "--foxglove-port", str(live_port))
    args += ("--set", f"console.token_file={tmp_path / 'token'}")
    args += ("--set", "operator.click_delay_s=120")
    run = None
    png = b""
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=str(CHROMIUM), args=WEBGL_ARGS)
            try:
                context = browser.new_context(
                    permissions=["local-network-access"],  # what a person grants at the prompt
                    viewport={"width": 1400, "height": 800},
                )
                page = context.new_page()
                page.set_default_timeout(120_000)
                page.goto(f"{served.base}/{page_name}?ds=foxglove-websocket&ds.url={quote(url)}")
                page.get_by_text("Problems").first.wait_for()  # the app is up (and cannot connect)
                run = LiveRun(str(REPO / "graphs" / "tool_pickup.yaml"), tmp_path / "run", *args)
                assert run.url == url
                deadline = time.monotonic() + 90
                while time.monotonic() < deadline:  # until the video shows (or give up)
                    time.sleep(5.0)
                    png = page.screenshot(path=str(tmp_path / "lichtblick-live.png"))
                    if colours(png, PANEL_IMAGE) > 60 and colours(png, PANEL_3D) > 25:
                        break
                problems = _problems(page)
            finally:
                browser.close()
    finally:
        if run is not None:
            run.stop()
        served.close()
    (tmp_path / "problems.txt").write_text(problems)
    assert run is not None and "viewer connected" in run.text()
    assert "Missing transform" not in problems, problems[-1500:]
    assert colours(png, PANEL_IMAGE) > 60  # the wrist camera's video, not an empty panel
    assert colours(png, PANEL_3D) > 25  # the arm's frames (axes, labels) over the grid
