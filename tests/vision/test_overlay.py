"""Overlay drawing and the video writer (read back with cv2.VideoCapture)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from umbra.modules.vision.overlay import (
    AXIS_BGR,
    CONTOUR_BGR,
    ELLIPSE_BGR,
    OFFENDING_BGR,
    RECTANGLE_BGR,
    VERTEX_BGR,
    draw_overlay,
)
from umbra.modules.vision.polygon import rectangle, resample_uniform
from umbra.modules.vision.sanity import SanityLimits, check_contour
from umbra.modules.vision.video import VideoFileError, VideoWriter


def color_near(image: np.ndarray, uv, bgr, radius: int = 2) -> bool:
    u, v = round(uv[0]), round(uv[1])
    patch = image[v - radius : v + radius + 1, u - radius : u + radius + 1].reshape(-1, 3)
    return bool(np.any(np.all(np.abs(patch.astype(int) - bgr) <= 40, axis=1)))


def test_overlay_draws_contour_vertices_shapes_and_axes() -> None:
    image = np.zeros((480, 640, 3), dtype=np.uint8)
    contour = resample_uniform(rectangle((320.0, 240.0), (200.0, 120.0), 0.3), 48)
    contour[5] += (40.0, -40.0)  # one vertex pulled out of the rectangle
    sanity = check_contour(contour, SanityLimits())
    assert 5 in sanity.offending
    drawn = draw_overlay(image, contour, sanity, ["stage: approach", "status: failed"])
    assert not np.any(image)  # the input is left alone
    assert color_near(drawn, contour[5], OFFENDING_BGR)
    good = next(i for i in range(len(contour)) if i not in set(sanity.offending))
    assert color_near(drawn, contour[good], VERTEX_BGR)
    midpoint = 0.5 * (contour[20] + contour[21])
    assert color_near(drawn, midpoint, CONTOUR_BGR)
    corner = sanity.outer_rectangle.corners()[0]
    assert color_near(drawn, corner, RECTANGLE_BGR)
    ellipse = sanity.inner_ellipse
    c, s = np.cos(ellipse.angle_rad), np.sin(ellipse.angle_rad)
    tip = np.asarray(ellipse.center_uv) + ellipse.half_sizes[1] * np.array([-s, c])
    assert color_near(drawn, tip, ELLIPSE_BGR)
    features = sanity.features
    axis_end = np.asarray(features.centroid_uv) + 0.4 * features.major_axis_px * np.array([c, s])
    assert color_near(drawn, axis_end, AXIS_BGR)
    # Text is written at the top left, on a darkened band.
    assert drawn[5:45, 5:150].max() > 200


def test_overlay_without_a_contour_only_writes_text() -> None:
    image = np.full((100, 200, 3), 90, dtype=np.uint8)
    drawn = draw_overlay(image, lines=["no target"])
    assert np.array_equal(drawn[60:], image[60:])
    assert not np.array_equal(drawn[:30], image[:30])


@pytest.mark.parametrize("suffix", [".avi", ".mp4"])
def test_video_writer_round_trip(tmp_path, suffix: str) -> None:
    path = tmp_path / f"overlay{suffix}"
    frames = []
    with VideoWriter(path, 15.0, (320, 240)) as writer:
        for k in range(12):
            frame = np.zeros((240, 320, 3), dtype=np.uint8)
            frame[:, :] = (20 * k, 100, 255 - 20 * k)
            cv2.rectangle(frame, (10 + 10 * k, 50), (60 + 10 * k, 120), (255, 255, 255), -1)
            frames.append(frame)
            writer.write(frame)
    assert writer.frames == 12
    capture = cv2.VideoCapture(str(path))
    read = []
    while True:
        ok, frame = capture.read()
        if not ok:
            break
        read.append(frame)
    capture.release()
    assert len(read) == 12
    assert read[0].shape == (240, 320, 3)
    errors = [np.abs(a.astype(int) - b).mean() for a, b in zip(read, frames, strict=True)]
    assert max(errors) < 8.0


def test_video_writer_refuses_bad_names_and_frames(tmp_path) -> None:
    with pytest.raises(VideoFileError, match="must end in"):
        VideoWriter(tmp_path / "out.gif", 10.0, (64, 48))
    writer = VideoWriter(tmp_path / "out.avi", 10.0, (64, 48))
    with pytest.raises(VideoFileError, match="64x48x3"):
        writer.write(np.zeros((48, 65, 3), dtype=np.uint8))
    writer.close()
