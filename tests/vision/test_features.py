"""Polygon moment features against OpenCV's moments and fitEllipse and against closed forms."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from umbra.modules.vision.features import (
    angle_difference,
    equivalent_rectangle_sides,
    polygon_features,
)
from umbra.modules.vision.polygon import (
    circle,
    rectangle,
    resample_uniform,
    segment_lengths,
    signed_area,
    with_positive_area,
)


def random_star(rng: np.random.Generator, count: int = 40) -> np.ndarray:
    """A simple (star-shaped, so non-self-intersecting) polygon with random radii."""
    angles = np.sort(rng.uniform(0, 2 * np.pi, count))
    radii = rng.uniform(20, 120, count)
    centre = rng.uniform(150, 350, 2)
    return centre + radii[:, None] * np.column_stack([np.cos(angles), np.sin(angles)])


@pytest.mark.parametrize("seed", range(5))
def test_moments_match_opencv_on_random_polygons(seed: int) -> None:
    polygon = random_star(np.random.default_rng(seed))
    cv = cv2.moments(polygon.astype(np.float32))
    features = polygon_features(polygon)
    assert features.area_px2 == pytest.approx(abs(cv["m00"]), rel=1e-4)
    assert features.centroid_uv == pytest.approx((cv["m10"] / cv["m00"], cv["m01"] / cv["m00"]))
    mu = (cv["mu20"] / cv["m00"], cv["mu11"] / cv["m00"], cv["mu02"] / cv["m00"])
    assert features.second_moments == pytest.approx(mu, rel=1e-4, abs=1e-3)


def test_vertex_order_does_not_change_features() -> None:
    polygon = random_star(np.random.default_rng(7))
    forward = polygon_features(polygon)
    backward = polygon_features(polygon[::-1])
    assert backward.area_px2 == pytest.approx(forward.area_px2)
    assert backward.orientation_rad == pytest.approx(forward.orientation_rad)
    assert signed_area(polygon) == pytest.approx(-signed_area(polygon[::-1]))
    assert signed_area(with_positive_area(polygon[::-1])) > 0


@pytest.mark.parametrize("angle_deg", [0.0, 17.0, 60.0, 90.0, -35.0, 135.0])
def test_rectangle_features_are_analytic(angle_deg: float) -> None:
    length, width = 160.0, 100.0
    angle = np.deg2rad(angle_deg)
    features = polygon_features(rectangle((300.0, 200.0), (length, width), angle))
    assert features.area_px2 == pytest.approx(length * width)
    assert features.centroid_uv == pytest.approx((300.0, 200.0))
    assert angle_difference(features.orientation_rad, angle) < 1e-9
    assert -np.pi / 2 < features.orientation_rad <= np.pi / 2
    # A solid rectangle has variance L²/12 along a side.
    assert features.major_axis_px == pytest.approx(4 * np.sqrt(length**2 / 12))
    assert features.minor_axis_px == pytest.approx(4 * np.sqrt(width**2 / 12))
    assert equivalent_rectangle_sides(features) == pytest.approx((length, width))
    assert features.aspect_ratio == pytest.approx(length / width)


@pytest.mark.parametrize("angle_deg", [10.0, 45.0, 80.0, 120.0])
def test_ellipse_axes_and_angle_match_fit_ellipse(angle_deg: float) -> None:
    a, b = 90.0, 40.0  # semi-axes [px]
    t = np.linspace(0, 2 * np.pi, 720, endpoint=False)
    angle = np.deg2rad(angle_deg)
    c, s = np.cos(angle), np.sin(angle)
    local = np.column_stack([a * np.cos(t), b * np.sin(t)])
    polygon = np.array([320.0, 240.0]) + local @ np.array([[c, s], [-s, c]])
    features = polygon_features(polygon)
    (cu, cv), (width, height), fit_angle = cv2.fitEllipse(polygon.astype(np.float32))
    fit_major, fit_minor = max(width, height), min(width, height)
    # OpenCV's angle is that of the ``width`` axis; turn it into the major axis' angle.
    fit_major_angle = np.deg2rad(fit_angle if width >= height else fit_angle + 90.0)
    assert features.major_axis_px == pytest.approx(fit_major, rel=1e-3)
    assert features.minor_axis_px == pytest.approx(fit_minor, rel=1e-3)
    assert features.major_axis_px == pytest.approx(2 * a, rel=1e-3)
    assert features.minor_axis_px == pytest.approx(2 * b, rel=1e-3)
    assert angle_difference(features.orientation_rad, fit_major_angle) < np.deg2rad(0.1)
    assert angle_difference(features.orientation_rad, angle) < np.deg2rad(0.01)
    assert features.centroid_uv == pytest.approx((cu, cv), abs=1e-2)


def test_orientation_points_down_the_image_for_positive_angles() -> None:
    # A bar from the top left to the bottom right of the screen: u and v grow together.
    bar = np.array([[0.0, 0.0], [100.0, 100.0], [95.0, 105.0], [-5.0, 5.0]])
    assert polygon_features(bar).orientation_rad == pytest.approx(np.pi / 4)


def test_zero_area_polygon_is_rejected() -> None:
    with pytest.raises(ValueError, match="zero area"):
        polygon_features(np.array([[0.0, 0.0], [10.0, 0.0], [20.0, 0.0]]))


def test_uniform_resampling_keeps_the_outline() -> None:
    square = rectangle((100.0, 100.0), (80.0, 80.0))
    resampled = resample_uniform(square, 32)
    lengths = segment_lengths(resampled)
    assert lengths == pytest.approx(np.full(32, 10.0))
    assert polygon_features(resampled).area_px2 == pytest.approx(6400.0)
    round_ = circle((0.0, 0.0), 50.0, 400)
    assert signed_area(round_) == pytest.approx(np.pi * 2500, rel=1e-3)
