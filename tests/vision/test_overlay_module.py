"""The Overlay module: drawing on the camera image and writing a video file."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from umbra.connectors import UserError
from umbra.connectors.messages import Contour, Image, Status
from umbra.modules.vision.digicam import DigiCam
from umbra.modules.vision.overlay import CONTOUR_BGR, RECTANGLE_BGR
from umbra.modules.vision.overlay_module import Overlay
from umbra.modules.vision.vs_snake import VsSnake
from umbra.runtime.harness import ModuleHarness


def snake_frames(count: int) -> list[tuple[Image, Contour]]:
    cam = ModuleHarness(DigiCam, {"noise_sigma": 4.0, "patch_yaw_deg": 10.0}).start()
    out = cam.step(0.1)
    snake = ModuleHarness(VsSnake, {"seed_uv": out["truth"][0].centroid.tolist()}).start()
    pairs = []
    for _ in range(count):
        image = cam.step(0.1)["image"][0]
        snake.push("image", image)
        pairs.append((image, snake.step(0.1)["contour"][0]))
    return pairs


def near(image: np.ndarray, uv, bgr) -> bool:
    u, v = round(uv[0]), round(uv[1])
    block = image[v - 2 : v + 3, u - 2 : u + 3].reshape(-1, 3).astype(int)
    return bool(np.any(np.all(np.abs(block - bgr) <= 40, axis=1)))


def test_draws_the_contour_its_shapes_and_the_stage(tmp_path) -> None:
    ((image, contour),) = snake_frames(1)
    with ModuleHarness(Overlay, {}, output_dir=tmp_path) as h:
        h.push("contour", contour)
        h.push("status", Status(stage="approach", message="closing in"))
        h.push("image", image)
        drawn = h.step(0.01)["overlay"][0]
    assert drawn.stamp == image.stamp
    # The contour's segments are drawn (the outer rectangle may cross a few of them).
    midpoints = 0.5 * (contour.vertices + np.roll(contour.vertices, -1, axis=0))
    drawn_share = np.mean([near(drawn.pixels, m, CONTOUR_BGR) for m in midpoints])
    assert drawn_share >= 0.8
    assert not any(near(image.pixels, m, CONTOUR_BGR) for m in midpoints)
    # The outer rectangle lies 12 % outside the contour along the major axis.
    c, s = np.cos(contour.orientation), np.sin(contour.orientation)
    reach = 0.5 * contour.axes[0] * np.sqrt(12) / 4 * 1.12
    assert near(drawn.pixels, contour.centroid + reach * np.array([c, s]), RECTANGLE_BGR)
    assert drawn.pixels[5:60, 5:200].max() == 255  # text lines at the top left


def test_writes_a_video_that_reads_back(tmp_path) -> None:
    pairs = snake_frames(8)
    with ModuleHarness(
        Overlay, {"video": "run/overlay.avi", "video_fps": 15.0}, output_dir=tmp_path
    ) as h:
        for image, contour in pairs:
            h.push("contour", contour)
            h.push("image", image)
            h.step(0.1)
    summary = h.module.summary()  # after stop: the encoder's thread has written every frame
    assert summary["video_frames"] == 8 and summary["video_dropped"] == 0
    capture = cv2.VideoCapture(str(tmp_path / "run" / "overlay.avi"))
    count = 0
    while capture.read()[0]:
        count += 1
    assert count == 8
    assert capture.get(cv2.CAP_PROP_FRAME_WIDTH) == 640


def test_old_contours_are_not_drawn(tmp_path) -> None:
    ((image, contour),) = snake_frames(1)
    with ModuleHarness(Overlay, {"max_contour_age": 0.2}, output_dir=tmp_path) as h:
        h.push("contour", contour)
        h.step(1.0)
        h.push("image", image)
        drawn = h.step(0.01)["overlay"][0]
    midpoint = 0.5 * (contour.vertices[3] + contour.vertices[4])
    assert not near(drawn.pixels, midpoint, CONTOUR_BGR)


def test_bad_video_name_is_a_user_error(tmp_path) -> None:
    with pytest.raises(UserError, match=r"\.avi or \.mp4"):
        ModuleHarness(Overlay, {"video": "x.gif"}, output_dir=tmp_path).start()
