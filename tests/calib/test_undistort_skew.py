"""Issue #31 item 3: every undistortion honours the whole camera model, skew included.

Reference: the forward model written out here (OpenCV's distortion, then ``K`` with skew),
inverted by ``scipy.optimize.root`` point by point; and ``cv2.undistortPoints`` (iterated to
convergence) on pixels whose skew was removed first (OpenCV has no skew term of its own).
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy.optimize import root

from umbra.modules.calib.camera_model import Intrinsics, PinholeCamera
from umbra.modules.calib.distortion import undistort_points
from umbra.modules.sketch.stereo import StereoPair

K = np.array([[740.09, -4.58, 344.25], [0.0, 741.60, 212.84], [0.0, 0.0, 1.0]])
DIST = np.array([-0.28, 0.11, 0.0012, -0.0009, -0.02])


def forward(xy: np.ndarray) -> np.ndarray:
    k1, k2, p1, p2, k3 = DIST
    x, y = xy[..., 0], xy[..., 1]
    r2 = x * x + y * y
    radial = 1 + k1 * r2 + k2 * r2**2 + k3 * r2**3
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return np.stack([K[0, 0] * xd + K[0, 1] * yd + K[0, 2], K[1, 1] * yd + K[1, 2]], axis=-1)


def scipy_ideal_pixels(pixels: np.ndarray) -> np.ndarray:
    out = []
    for uv in pixels:
        guess = np.array([(uv[0] - K[0, 2]) / K[0, 0], (uv[1] - K[1, 2]) / K[1, 1]])
        xy = root(lambda xy, uv=uv: forward(xy) - uv, guess, tol=1e-13).x
        assert np.max(np.abs(forward(xy) - uv)) < 1e-8
        out.append(K[:2, :2] @ xy + K[:2, 2])
    return np.array(out)


def grid() -> np.ndarray:
    u, v = np.meshgrid(np.linspace(0, 639, 9), np.linspace(0, 479, 7))
    return np.column_stack([u.ravel(), v.ravel()])


def test_undistort_points_and_camera_model_match_scipy_with_skew() -> None:
    pixels = grid()
    expected = scipy_ideal_pixels(pixels)
    np.testing.assert_allclose(undistort_points(pixels, K, DIST), expected, atol=1e-6)
    camera = PinholeCamera(Intrinsics.from_matrix(K), distortion=DIST)
    np.testing.assert_allclose(camera.ideal_pixels(pixels), expected, atol=1e-6)
    pair = StereoPair(K, np.eye(4), K, np.eye(4), DIST, DIST)
    np.testing.assert_allclose(pair.ideal("b", pixels), expected, atol=1e-6)


def test_opencv_after_removing_the_skew_agrees() -> None:
    pixels = grid()
    # un-skew through K's inverse: y_d = (v - v0) / fy, x_d = (u - u0 - skew y_d) / fx
    y_d = (pixels[:, 1] - K[1, 2]) / K[1, 1]
    x_d = (pixels[:, 0] - K[0, 2] - K[0, 1] * y_d) / K[0, 0]
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-14)
    xy = cv2.undistortPoints(
        np.column_stack([x_d, y_d]).reshape(-1, 1, 2),
        np.eye(3),
        DIST,
        R=None,
        P=None,
        criteria=criteria,
    ).reshape(-1, 2)
    expected = xy @ K[:2, :2].T + K[:2, 2]
    np.testing.assert_allclose(undistort_points(pixels, K, DIST), expected, atol=1e-6)
    # and OpenCV with the skewed K itself is off by pixels: what the fix is about
    plain = cv2.undistortPoints(
        pixels.reshape(-1, 1, 2), K, DIST, R=None, P=K, criteria=criteria
    ).reshape(-1, 2)
    assert np.max(np.abs(plain - expected)) > 0.5
