"""Polygon moments (the tracker's and the servo's) against OpenCV's and against closed forms."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from umbra.modules.geometry.polygon_moments import DegeneratePolygonError, polygon_moments


def random_star(rng: np.random.Generator, count: int = 12) -> np.ndarray:
    """A simple (star-shaped) polygon in pixels, elongated, turned and far from the origin."""
    angles = np.sort(rng.uniform(0, 2 * np.pi, count))
    radii = rng.uniform(40, 80, count)[:, None]
    shape = np.c_[np.cos(angles), rng.uniform(0.4, 1.0) * np.sin(angles)] * radii
    turn = rng.uniform(-np.pi, np.pi)
    R = np.array([[np.cos(turn), -np.sin(turn)], [np.sin(turn), np.cos(turn)]])
    return shape @ R.T + rng.uniform(100, 500, 2)


@pytest.mark.parametrize("seed", range(20))
def test_moments_match_opencv_on_random_polygons(seed: int) -> None:
    vertices = random_star(np.random.default_rng(seed))
    ours = polygon_moments(vertices)
    cv = cv2.moments(vertices.astype(np.float32))
    assert ours.area == pytest.approx(abs(cv["m00"]), rel=1e-5)
    assert ours.signed_area == pytest.approx(cv["m00"], rel=1e-5)
    centroid = [cv["m10"] / cv["m00"], cv["m01"] / cv["m00"]]
    np.testing.assert_allclose(ours.centroid, centroid, rtol=1e-5)
    for name in ("mu20", "mu11", "mu02"):
        assert getattr(ours, name) == pytest.approx(cv[name] / cv["m00"], rel=1e-3, abs=1e-3)
    reverse = polygon_moments(vertices[::-1])  # winding changes the sign of the area only
    assert reverse.area == pytest.approx(ours.area)
    assert reverse.signed_area == pytest.approx(-ours.signed_area)
    assert reverse.orientation == pytest.approx(ours.orientation)
    np.testing.assert_allclose(reverse.centroid, ours.centroid)


@pytest.mark.parametrize("angle_deg", [0.0, 30.0, 90.0, -60.0])
def test_a_turned_rectangle_has_its_closed_form_moments(angle_deg: float) -> None:
    length, width, angle = 0.08, 0.05, np.radians(angle_deg)  # normalized-coordinate sized
    corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * [length / 2, width / 2]
    R = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    moments = polygon_moments(corners @ R.T + [0.01, -0.02])
    assert moments.area == pytest.approx(length * width, rel=1e-12)
    np.testing.assert_allclose(moments.centroid, [0.01, -0.02], atol=1e-15)
    along, across = length**2 / 12, width**2 / 12  # a solid rectangle's variances
    c, s = np.cos(angle), np.sin(angle)
    assert moments.mu20 == pytest.approx(along * c * c + across * s * s, rel=1e-9)
    assert moments.mu02 == pytest.approx(along * s * s + across * c * c, rel=1e-9)
    assert moments.mu11 == pytest.approx((along - across) * c * s, abs=1e-15)
    expected = np.pi / 2 if angle_deg == 90.0 else angle  # (-pi/2, pi/2]
    assert moments.orientation == pytest.approx(expected)


def test_polygons_without_moments_are_refused_with_what_was_found() -> None:
    with pytest.raises(DegeneratePolygonError, match=r"at least 3 vertices .* got shape \(2, 2\)"):
        polygon_moments(np.zeros((2, 2)))
    with pytest.raises(DegeneratePolygonError, match="zero area"):
        polygon_moments([[0.0, 0.0], [10.0, 0.0], [20.0, 0.0]])
    with pytest.raises(DegeneratePolygonError, match="zero area"):
        polygon_moments([[300.0, 200.0], [301.0, 201.0], [302.0, 202.0]])
    assert issubclass(DegeneratePolygonError, ValueError)
