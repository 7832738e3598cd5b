"""Moment features of a seen patch, and the interaction matrix against finite differences."""

from __future__ import annotations

import numpy as np
import pytest

from tests.servo.servo_scene import (
    INTRINSICS,
    PATCH_AREA,
    camera_above,
    features_seen,
    move,
    patch_corners,
    project,
)
from umbra.modules.calib.camera_model import Intrinsics
from umbra.modules.geometry.polygon_moments import wrap_axis_angle
from umbra.modules.servo.features import (
    FeatureError,
    features_from_contour,
)
from umbra.modules.servo.law import interaction_matrix


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
    assert wrap_axis_angle(np.radians(100)) == pytest.approx(np.radians(-80))
    assert wrap_axis_angle(np.radians(-100)) == pytest.approx(np.radians(80))
    assert wrap_axis_angle(np.pi / 2) == pytest.approx(np.pi / 2)
    assert wrap_axis_angle(-np.pi / 2) == pytest.approx(np.pi / 2)
    assert wrap_axis_angle(np.radians(10)) == pytest.approx(np.radians(10))


def test_degenerate_contours_are_rejected():
    with pytest.raises(FeatureError, match="at least 3"):
        features_from_contour(np.zeros((2, 2)), INTRINSICS, PATCH_AREA)
    with pytest.raises(FeatureError, match="zero area"):
        features_from_contour(np.array([[0, 0], [1, 1], [2, 2]]), INTRINSICS, PATCH_AREA)


def test_intrinsics_without_a_focal_length_give_no_features():
    flat = Intrinsics(fx=0.0, fy=610.0, skew=0.0, u0=320.0, v0=240.0)
    pixels = project(camera_above(0.0, 0.0, 0.3, yaw_deg=0.0), patch_corners())
    with pytest.raises(FeatureError, match=r"focal lengths must be positive, got fx=0\.0,"):
        features_from_contour(pixels, flat, PATCH_AREA)
    assert len(patch_corners()) == 32
