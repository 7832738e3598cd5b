"""Moment features against OpenCV, and the interaction matrix against finite differences."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from tests.servo.servo_scene import (
    INTRINSICS,
    PATCH_AREA,
    camera_above,
    features_seen,
    move,
    patch_corners,
)
from umbra.modules.servo.features import (
    FeatureError,
    Intrinsics,
    features_from_contour,
    polygon_moments,
    wrap_roll_error,
)
from umbra.modules.servo.law import interaction_matrix


def test_polygon_moments_match_opencv():
    rng = np.random.default_rng(0)
    for _ in range(20):
        # A random star-shaped (simple) polygon in pixels, elongated and turned.
        angles = np.sort(rng.uniform(0, 2 * np.pi, 12))
        radii = rng.uniform(40, 80, 12)[:, None]
        shape = np.c_[np.cos(angles), rng.uniform(0.4, 1.0) * np.sin(angles)] * radii
        turn = rng.uniform(-np.pi, np.pi)
        R = np.array([[np.cos(turn), -np.sin(turn)], [np.sin(turn), np.cos(turn)]])
        vertices = shape @ R.T + rng.uniform(100, 500, 2)
        ours = polygon_moments(vertices)
        reference = cv2.moments(vertices.astype(np.float32))
        assert ours.area == pytest.approx(abs(reference["m00"]), rel=1e-5)
        centroid = [reference["m10"] / reference["m00"], reference["m01"] / reference["m00"]]
        np.testing.assert_allclose(ours.centroid, centroid, rtol=1e-5)
        for name in ("mu20", "mu11", "mu02"):
            expected = reference[name] / reference["m00"]
            assert getattr(ours, name) == pytest.approx(expected, rel=1e-3, abs=1e-3)
        # Winding does not matter.
        reverse = polygon_moments(vertices[::-1])
        assert reverse.area == pytest.approx(ours.area)
        assert reverse.orientation == pytest.approx(ours.orientation)


def test_features_of_a_parallel_patch_are_its_camera_coordinates_and_depth():
    # Camera 0.3 m above, shifted: the patch centre is at camera (x, y) = (-0.02, +0.01)
    # (camera x = world x, camera y = -world y when looking down with zero yaw).
    T = camera_above(0.02, 0.01, 0.3, yaw_deg=0.0)
    s = features_seen(T)
    assert s.a_n == pytest.approx(0.3, rel=1e-9)
    assert s.x_n == pytest.approx(-0.02, abs=1e-9)
    assert s.y_n == pytest.approx(0.01, abs=1e-9)
    assert s.alpha == pytest.approx(0.0, abs=1e-9)  # long side along image x
    # Yawing the camera by +20 deg about its optical axis turns the image by -20 deg.
    assert features_seen(camera_above(0, 0, 0.3, yaw_deg=20.0)).alpha == pytest.approx(
        np.radians(-20), abs=1e-9
    )


@pytest.mark.parametrize("pose", [(0.0, 0.0, 0.4, 0.0), (0.03, -0.02, 0.25, 35.0)])
def test_interaction_matrix_matches_finite_differences(pose):
    T = camera_above(*pose)
    s = features_seen(T)
    L = interaction_matrix(s)
    h = 1e-6
    numeric = np.zeros((4, 4))
    for column, axis in enumerate((0, 1, 2, 5)):  # vx, vy, vz, wz
        twist = np.zeros(6)
        twist[axis] = 1.0
        plus = features_seen(move(T, twist, h)).as_array()
        minus = features_seen(move(T, twist, -h)).as_array()
        numeric[:, column] = (plus - minus) / (2 * h)
    np.testing.assert_allclose(L, numeric, atol=1e-6)
    # Near -I for translations and -1 for roll when the patch is near the optical axis.
    np.testing.assert_allclose(np.diag(L), -1.0)


def test_roll_error_wraps_into_half_open_interval():
    assert wrap_roll_error(np.radians(100)) == pytest.approx(np.radians(-80))
    assert wrap_roll_error(np.radians(-100)) == pytest.approx(np.radians(80))
    assert wrap_roll_error(np.pi / 2) == pytest.approx(np.pi / 2)
    assert wrap_roll_error(-np.pi / 2) == pytest.approx(np.pi / 2)
    assert wrap_roll_error(np.radians(10)) == pytest.approx(np.radians(10))


def test_skewed_intrinsics_round_trip():
    K = Intrinsics(fx=500, fy=520, u0=300, v0=200, skew=3.0)
    uv = np.array([[10.0, 20.0], [400.0, 300.0]])
    np.testing.assert_allclose(K.pixel(K.normalize(uv)), uv)


def test_degenerate_contours_are_rejected():
    with pytest.raises(FeatureError, match="at least 3"):
        features_from_contour(np.zeros((2, 2)), INTRINSICS, PATCH_AREA)
    with pytest.raises(FeatureError, match="no area"):
        features_from_contour(np.array([[0, 0], [1, 1], [2, 2]]), INTRINSICS, PATCH_AREA)
    assert len(patch_corners()) == 32
