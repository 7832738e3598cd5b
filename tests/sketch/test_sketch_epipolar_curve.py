"""Issue #31 item 7: the epipolar CURVE of a distorted camera pair, at any image size.

Reference: OpenCV alone. Pixel a is undistorted with ``cv2.undistortPoints`` (iterated to
convergence), points along its ray are projected into camera b with ``cv2.projectPoints``
(distortion included) densely; every point of the project's curve must lie on that polyline.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from umbra.modules.ptu.aim import look_at
from umbra.modules.sketch.stereo import StereoPair

TARGET = np.array([1.5, 0.0, 0.3])
T_A = look_at(np.array([0.0, 0.35, 1.0]), TARGET)
T_B = look_at(np.array([0.0, -0.35, 1.0]), TARGET)
DIST = np.array([-0.3, 0.12, 0.0008, -0.0006, 0.0])


def camera_matrix(width: int, height: int) -> np.ndarray:
    f = 0.9 * width  # about 58 deg across, whatever the resolution
    return np.array([[f, 0.0, width / 2 + 7.0], [0.0, f * 1.003, height / 2 - 5.0], [0, 0, 1]])


def reference_curve(K: np.ndarray, pixel_a) -> np.ndarray:
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-14)
    xy = cv2.undistortPoints(np.array([[pixel_a]], float), K, DIST, criteria=criteria).reshape(2)
    depths = 1.0 / np.linspace(1.0 / 0.05, 1e-4, 20000)
    points = (T_A[:3, :3] @ (np.append(xy, 1.0)[:, None] * depths)).T + T_A[:3, 3]
    T_b = np.linalg.inv(T_B)
    points = points[(points @ T_b[:3, :3].T + T_b[:3, 3])[:, 2] > 0.05]
    rvec = cv2.Rodrigues(T_b[:3, :3])[0]
    return cv2.projectPoints(points, rvec, T_b[:3, 3], K, DIST)[0].reshape(-1, 2)


def distance_to(polyline: np.ndarray, p: np.ndarray) -> float:
    a, b = polyline[:-1], polyline[1:]
    ab = b - a
    t = np.clip(
        np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-18), 0, 1
    )
    return float(np.min(np.linalg.norm(a + t[:, None] * ab - p, axis=1)))


@pytest.mark.parametrize("size", [(640, 480), (1920, 1080), (1280, 720)])
def test_curve_follows_opencv_at_any_image_size(size) -> None:
    width, height = size
    K = camera_matrix(width, height)
    pair = StereoPair(K, T_A, K, T_B, DIST, DIST)
    worst_line_px = 0.0
    for fx, fy in ((0.1, 0.8), (0.5, 0.5), (0.9, 0.15), (0.3, 0.2)):
        pixel_a = (fx * width, fy * height)
        curve = pair.epipolar_curve_b(pixel_a, size)
        assert len(curve) > 20
        assert np.all((curve >= 0) & (curve <= [width, height]))
        reference = reference_curve(K, pixel_a)
        assert max(distance_to(reference, p) for p in curve) < 0.05
        # it spans the image: from one border to another (or to the epipole)
        span = np.linalg.norm(curve[-1] - curve[0])
        assert span > 0.5 * min(width, height)
        # the straight ideal-pixel line is off the true curve by pixels
        line = pair.epipolar_line_b(pixel_a)
        ideal = pair.ideal("b", curve)
        assert np.max(np.abs(ideal @ line[:2] + line[2])) < 1e-6  # same epipolar plane
        worst_line_px = max(worst_line_px, float(np.max(np.abs(curve @ line[:2] + line[2]))))
    assert worst_line_px > 2.0
