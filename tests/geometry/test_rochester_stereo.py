"""The guide's two stereo methods and its camera constants."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from umbra.modules.geometry import rays
from umbra.modules.geometry import rochester_head as head
from umbra.modules.geometry import rochester_stereo as stereo
from umbra.modules.geometry.transforms import invert_transform, transform_points

CAMERA = stereo.ROCHESTER_CAMERA


def stereo_pair(point_flange, rng=None):
    """Aim both cameras at the point (as the head would), then offset the aim a little."""
    phi, theta_left = head.aim_camera_at_point(point_flange, "left")
    _, theta_right = head.aim_camera_at_point(point_flange, "right")
    if rng is not None:  # a target that is not exactly centred
        phi += rng.uniform(-0.05, 0.05)
        theta_left += rng.uniform(-0.05, 0.05)
        theta_right += rng.uniform(-0.05, 0.05)
    left = head.T_flange_campos(phi, theta_left, "left")
    right = head.T_flange_campos(phi, theta_right, "right")
    return left, right


def image_of(point_flange, T_flange_camera):
    return CAMERA.pixel_from_point(
        transform_points(invert_transform(T_flange_camera), point_flange)
    )


def camera_matrix(T_flange_camera, camera=CAMERA):
    K = np.array(
        [
            [camera.focal_px, 0, camera.centre_px[0]],
            [0, camera.focal_px * camera.aspect, camera.centre_px[1]],
            [0, 0, 1],
        ]
    )
    return K @ invert_transform(T_flange_camera)[:3]


def test_projection_matches_opencv():
    rng = np.random.default_rng(0)
    points = rng.uniform([-0.3, -0.3, 0.8], [0.3, 0.3, 2.0], (20, 3))
    K = camera_matrix(np.eye(4))[:, :3]
    expected, _ = cv2.projectPoints(points, np.zeros(3), np.zeros(3), K, None)
    np.testing.assert_allclose(CAMERA.pixel_from_point(points), expected[:, 0], atol=1e-9)


@pytest.mark.parametrize("method", ["pseudo_inverse", "duda_hart"])
def test_both_methods_recover_exact_points(method):
    rng = np.random.default_rng(1)
    for _ in range(50):
        point = rng.uniform([-0.4, -0.4, 0.8], [0.4, 0.4, 2.0])
        left, right = stereo_pair(point, rng)
        pixels = (image_of(point, left), image_of(point, right))
        if method == "pseudo_inverse":
            found = stereo.stereo_pseudo_inverse(pixels, (left, right))
        else:
            result = stereo.stereo_duda_hart(pixels, (left, right))
            found = result.point
            assert result.gap < 1e-9
        np.testing.assert_allclose(found, point, atol=1e-9)


def test_with_pixel_noise_both_methods_agree_with_opencv_triangulation():
    rng = np.random.default_rng(2)
    point = np.array([0.05, -0.1, 1.34])  # the guide's standard focus distance
    left, right = stereo_pair(point)
    for _ in range(20):
        pixels = tuple(image_of(point, T) + rng.normal(0, 0.5, 2) for T in (left, right))
        pinv = stereo.stereo_pseudo_inverse(pixels, (left, right))
        midpoint = stereo.stereo_duda_hart(pixels, (left, right)).point
        homogeneous = cv2.triangulatePoints(
            camera_matrix(left), camera_matrix(right), pixels[0], pixels[1]
        )
        opencv = homogeneous[:3, 0] / homogeneous[3, 0]
        # Half-pixel noise at 1.34 m with a 0.165 m baseline: errors of a few mm, and the
        # three methods agree to well under a millimetre.
        assert np.linalg.norm(pinv - point) < 0.02
        assert np.linalg.norm(midpoint - pinv) < 1e-3
        assert np.linalg.norm(opencv - pinv) < 1e-3


def test_duda_hart_matches_the_generic_ray_triangulation():
    point = np.array([-0.2, 0.1, 1.0])
    left, right = stereo_pair(point)
    pixels = (
        image_of(point, left) + np.array([1.5, -2.0]),
        image_of(point, right) + np.array([-1.0, 0.5]),
    )
    ours = stereo.stereo_duda_hart(pixels, (left, right))
    generic = rays.triangulate_pixels([camera_matrix(left), camera_matrix(right)], pixels)
    np.testing.assert_allclose(ours.point, generic.point, atol=1e-12)
    assert ours.gap == pytest.approx(generic.gap, rel=1e-9)
    assert ours.gap > 0


def test_pixels_per_degree_measured_agree_with_focal_length_near_centre():
    x_per_degree, y_per_degree = CAMERA.pixels_per_degree()
    # 980.5 px and aspect 1.289 imply 17.11 and 22.06 px/deg; measured 17.75 and 22.79.
    assert x_per_degree == pytest.approx(stereo.CAM_X_PIXELS_PER_DEGREE, rel=0.05)
    assert y_per_degree == pytest.approx(stereo.CAM_Y_PIXELS_PER_DEGREE, rel=0.05)


def test_small_angle_slope_is_the_pixels_per_degree_and_grows_off_centre():
    # Turn a point by one degree about the camera's y axis and see how far its image moves.
    def x_pixel(angle_deg):
        a = np.radians(angle_deg)
        return CAMERA.pixel_from_point([np.sin(a), 0.0, np.cos(a)])[0]

    x_per_degree, _ = CAMERA.pixels_per_degree()
    assert x_pixel(0.5) - x_pixel(-0.5) == pytest.approx(x_per_degree, rel=1e-4)
    # Near the edge of the 512-pixel image (~14 degrees) a degree spans more pixels.
    assert x_pixel(14.5) - x_pixel(13.5) > 1.05 * x_per_degree
