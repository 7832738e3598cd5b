"""The simulated camera's projection against cv2.projectPoints and cv2.undistortPoints."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from umbra.modules.calib.camera_model import Intrinsics
from umbra.modules.vision.projection import ideal_pixels_of_distorted_grid, project_camera_points

from .conftest import DISTORTION, INTRINSICS


@pytest.mark.parametrize(
    "distortion",
    [np.zeros(5), DISTORTION, np.array([0.08, -0.05, -0.002, 0.001, 0.01])],
)
def test_projection_matches_opencv(distortion: np.ndarray) -> None:
    rng = np.random.default_rng(5)
    points = np.column_stack(
        [rng.uniform(-0.1, 0.1, 200), rng.uniform(-0.08, 0.08, 200), rng.uniform(0.15, 0.5, 200)]
    )
    ours = project_camera_points(points, INTRINSICS, distortion)
    theirs, _ = cv2.projectPoints(points, np.zeros(3), np.zeros(3), INTRINSICS.matrix(), distortion)
    np.testing.assert_allclose(ours, theirs.reshape(-1, 2), atol=1e-6)


def test_skew_shifts_u_by_skew_times_b() -> None:
    skewed = Intrinsics(600.0, 600.0, 5.0, 320.0, 240.0)
    point = np.array([[0.02, 0.05, 0.25]])
    plain = project_camera_points(point, Intrinsics(600.0, 600.0, 0.0, 320.0, 240.0))
    assert project_camera_points(point, skewed)[0, 0] - plain[0, 0] == pytest.approx(5.0 * 0.2)


def test_points_behind_the_camera_are_refused() -> None:
    with pytest.raises(ValueError, match="behind"):
        project_camera_points(np.array([[0.0, 0.0, -1.0]]), INTRINSICS)


def test_undistortion_maps_agree_with_opencv_and_invert_the_model() -> None:
    map_u, map_v = ideal_pixels_of_distorted_grid(INTRINSICS, DISTORTION)
    rng = np.random.default_rng(6)
    cols = rng.integers(0, INTRINSICS.width, 300)
    rows = rng.integers(0, INTRINSICS.height, 300)
    pixels = np.column_stack([cols, rows]).astype(np.float64)
    reference = cv2.undistortPoints(
        pixels.reshape(-1, 1, 2),
        INTRINSICS.matrix(),
        DISTORTION,
        P=INTRINSICS.matrix(),
        criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12),
    ).reshape(-1, 2)
    ours = np.column_stack([map_u[rows, cols], map_v[rows, cols]])
    np.testing.assert_allclose(ours, reference, atol=1e-3)
    # Distorting the ideal pixel brings it back to where it came from.
    K_inv = np.linalg.inv(INTRINSICS.matrix())
    rays = np.column_stack([ours, np.ones(len(ours))]) @ K_inv.T
    again = project_camera_points(rays, INTRINSICS, DISTORTION)
    np.testing.assert_allclose(again, pixels, atol=1e-3)
