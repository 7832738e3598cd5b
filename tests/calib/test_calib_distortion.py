"""OpenCV's distortion model: ours against cv2.projectPoints, undistortPoints and undistort."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from umbra.modules.calib.camera_model import Intrinsics, PinholeCamera
from umbra.modules.calib.distortion import (
    distort_normalized,
    distort_points,
    undistort_image,
    undistort_normalized_fixed_point,
    undistort_normalized_newton,
    undistort_points,
    undistortion_maps,
)
from umbra.modules.calib.rotations import rotation_from_vector

K = np.array([[820.0, 0.0, 331.0], [0.0, 815.0, 244.0], [0.0, 0.0, 1.0]])
DISTORTIONS = [
    np.array([-0.21, 0.12, 0.0012, -0.0008]),
    np.array([0.15, -0.3, -0.002, 0.003, 0.05]),
    np.array([-0.35, 0.15, 0.0, 0.0, -0.03]),
]


def cv_undistort_iter(pixels: np.ndarray, dist: np.ndarray, P: np.ndarray | None) -> np.ndarray:
    """cv2 point undistortion run to convergence (OpenCV 4: undistortPointsIter; 5: criteria)."""
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-15)
    src = pixels[:, None, :]
    if hasattr(cv2, "undistortPointsIter"):
        out = cv2.undistortPointsIter(src, K, dist, None, P, criteria)
    else:
        out = cv2.undistortPoints(src, K, dist, None, None, P, criteria)
    return out.reshape(-1, 2)


@pytest.fixture
def scene() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(5)
    points = rng.uniform([-0.5, -0.35, 1.0], [0.5, 0.35, 1.5], (200, 3))
    rvec = np.array([0.05, -0.1, 0.02])
    tvec = np.array([0.02, -0.01, 0.1])
    return points, rvec, tvec


@pytest.mark.parametrize("dist", DISTORTIONS)
def test_projection_matches_cv2_project_points(scene, dist: np.ndarray) -> None:
    points, rvec, tvec = scene
    camera = PinholeCamera(Intrinsics.from_matrix(K), rotation_from_vector(rvec), tvec, dist)
    expected, _ = cv2.projectPoints(points, rvec, tvec, K, dist)
    np.testing.assert_allclose(camera.project(points), expected.reshape(-1, 2), atol=1e-9)


@pytest.mark.parametrize("dist", DISTORTIONS)
def test_undistort_inverts_distort(dist: np.ndarray) -> None:
    rng = np.random.default_rng(6)
    ideal = rng.uniform(-0.45, 0.45, (500, 2))
    recovered = undistort_normalized_newton(distort_normalized(ideal, dist), dist)
    np.testing.assert_allclose(recovered, ideal, atol=1e-12)
    pixels = rng.uniform([0, 0], [640, 480], (100, 2))
    np.testing.assert_allclose(
        distort_points(undistort_points(pixels, K, dist), K, dist), pixels, atol=1e-8
    )


@pytest.mark.parametrize("dist", DISTORTIONS)
def test_undistort_points_matches_cv2(dist: np.ndarray) -> None:
    rng = np.random.default_rng(8)
    pixels = rng.uniform([20, 20], [620, 460], (300, 2))
    ours = undistort_points(pixels, K, dist)
    np.testing.assert_allclose(ours, cv_undistort_iter(pixels, dist, K), atol=1e-6)
    # Default cv2.undistortPoints stops after 5 fixed-point iterations: ours is closer to exact.
    quick = cv2.undistortPoints(pixels[:, None, :], K, dist, None, K).reshape(-1, 2)
    error_cv = np.abs(distort_points(quick, K, dist) - pixels).max()
    error_ours = np.abs(distort_points(ours, K, dist) - pixels).max()
    assert error_ours <= error_cv
    normalized = undistort_points(pixels, K, dist, normalized=True)
    np.testing.assert_allclose(normalized, cv_undistort_iter(pixels, dist, None), atol=1e-8)


def test_zero_distortion_is_identity() -> None:
    pixels = np.array([[10.0, 20.0], [600.0, 400.0]])
    np.testing.assert_allclose(undistort_points(pixels, K, [0, 0, 0, 0]), pixels, atol=1e-12)


def test_no_inverse_is_nan() -> None:
    dist = np.array([-0.4, 0.0, 0.0, 0.0])
    # r (1 - 0.4 r^2) peaks at 0.609 for r = 0.913; beyond it there is only a mirrored root.
    distorted = np.array([[0.1, 0.0], [2.0, 0.0], [0.55, 0.3], [0.0, 0.6]])
    out = undistort_normalized_newton(distorted, dist)
    assert np.all(np.isfinite(out[[0, 3]]))
    assert np.all(np.isnan(out[[1, 2]]))
    np.testing.assert_allclose(distort_normalized(out[3], dist), [0.0, 0.6], atol=1e-12)
    # the fixed-point inversion stays finite there (the renderer's tables need a value)
    assert np.all(np.isfinite(undistort_normalized_fixed_point(distorted, dist)))


@pytest.mark.parametrize("dist", DISTORTIONS)
def test_both_inversions_agree_where_the_lens_has_an_inverse(dist: np.ndarray) -> None:
    u, v = np.meshgrid(np.arange(0.0, 640.0, 8.0), np.arange(0.0, 480.0, 8.0))
    distorted = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1]], axis=-1)
    exact = undistort_normalized_newton(distorted, dist)
    fixed = undistort_normalized_fixed_point(distorted, dist)
    assert fixed.shape == exact.shape == distorted.shape
    np.testing.assert_allclose(fixed, exact, atol=1e-12)
    residual = np.abs(distort_normalized(fixed, dist) - distorted).max()
    assert residual < 1e-13


def test_bad_coefficient_count() -> None:
    with pytest.raises(ValueError, match="4"):
        distort_normalized(np.zeros((1, 2)), [0.1, 0.2, 0.3])


@pytest.mark.parametrize("dist", DISTORTIONS[:2])
def test_maps_match_cv2(dist: np.ndarray) -> None:
    new_K = K.copy()
    new_K[0, 0] *= 0.9
    map_x, map_y = undistortion_maps(K, dist, (640, 480), new_K)
    cv_x, cv_y = cv2.initUndistortRectifyMap(K, dist, None, new_K, (640, 480), cv2.CV_32FC1)
    assert np.max(np.abs(map_x - cv_x)) < 2e-3
    assert np.max(np.abs(map_y - cv_y)) < 2e-3


def test_image_matches_cv2_undistort() -> None:
    rng = np.random.default_rng(9)
    dist = DISTORTIONS[0]
    # A smooth image with detail, so interpolation differences stay small and meaningful.
    v, u = np.mgrid[0:480, 0:640].astype(float)
    image = np.stack(
        [
            127 + 100 * np.sin(u / 17.0) * np.cos(v / 23.0),
            127 + 100 * np.cos((u + v) / 29.0),
            rng.uniform(0, 255) + 0 * u,
        ],
        axis=-1,
    ).astype(np.uint8)
    ours = undistort_image(image, K, dist)
    expected = cv2.undistort(image, K, dist)
    difference = np.abs(ours.astype(int) - expected.astype(int))
    assert ours.shape == expected.shape and ours.dtype == expected.dtype
    assert np.mean(difference) < 0.6
    assert np.percentile(difference, 99.5) <= 2
