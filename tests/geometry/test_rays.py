"""Rays, triangulation and epipolar lines against known geometry and OpenCV."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from umbra.modules.geometry.rays import (
    RayGeometryError,
    camera_centre,
    closest_ranges,
    epipolar_line,
    epipole,
    fundamental_matrix,
    line_distance,
    pixel_rays,
    triangulate_linear,
    triangulate_midpoint,
    triangulate_pixels,
    triangulate_rays,
)

K = np.array([[820.0, 0.0, 331.0], [0.0, 815.0, 244.0], [0.0, 0.0, 1.0]])


def camera(rvec: list[float], centre: list[float]) -> np.ndarray:
    R, _ = cv2.Rodrigues(np.array(rvec, dtype=float))
    t = -R @ np.array(centre, dtype=float)
    return K @ np.hstack([R, t[:, None]])


def project(P: np.ndarray, X: np.ndarray) -> np.ndarray:
    h = np.hstack([X, np.ones((len(X), 1))]) @ P.T
    return h[:, :2] / h[:, 2:]


@pytest.fixture
def stereo() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(7)
    P_a = camera([0.0, 0.15, 0.0], [-0.3, 0.0, 0.0])
    P_b = camera([0.02, -0.15, 0.01], [0.3, 0.05, 0.02])
    X = rng.uniform([-0.4, -0.3, 1.5], [0.4, 0.3, 3.0], (40, 3))
    return P_a, P_b, X


def skew_lines(rng: np.random.Generator, gap: float):
    """Two rays whose common perpendicular has its midpoint at a known point and known length."""
    midpoint = rng.normal(size=3)
    normal = rng.normal(size=3)
    normal /= np.linalg.norm(normal)
    a = np.cross(normal, rng.normal(size=3))
    b = np.cross(normal, rng.normal(size=3))
    origin_a = midpoint - gap / 2 * normal - rng.uniform(1, 3) * a
    origin_b = midpoint + gap / 2 * normal - rng.uniform(1, 3) * b
    return midpoint, origin_a, a, origin_b, b


def test_midpoint_of_skew_rays_is_known_point_and_gap() -> None:
    rng = np.random.default_rng(1)
    for gap in (0.0, 1e-3, 0.25):
        midpoint, oa, a, ob, b = skew_lines(rng, gap)
        result = triangulate_midpoint(oa, a * 3.7, ob, b * 0.2)
        np.testing.assert_allclose(result.point, midpoint, atol=1e-12)
        assert result.gap == pytest.approx(gap, abs=1e-12)


def test_midpoint_ranges_match_closest_points() -> None:
    rng = np.random.default_rng(2)
    midpoint, oa, a, ob, b = skew_lines(rng, 0.1)
    range_a, range_b = closest_ranges(oa, a, ob, b)
    end_a = oa + range_a * a / np.linalg.norm(a)
    end_b = ob + range_b * b / np.linalg.norm(b)
    # The common perpendicular is perpendicular to both rays.
    assert abs(np.dot(end_b - end_a, a)) < 1e-12
    assert abs(np.dot(end_b - end_a, b)) < 1e-12
    np.testing.assert_allclose((end_a + end_b) / 2, midpoint, atol=1e-12)


def test_least_squares_equals_midpoint_for_two_rays() -> None:
    rng = np.random.default_rng(3)
    _, oa, a, ob, b = skew_lines(rng, 0.3)
    ls = triangulate_rays(np.stack([oa, ob]), np.stack([a, b]))
    mid = triangulate_midpoint(oa, a, ob, b)
    np.testing.assert_allclose(ls.point, mid.point, atol=1e-12)
    assert ls.gap == pytest.approx(mid.gap, rel=1e-10)


def test_least_squares_many_rays_through_a_point() -> None:
    rng = np.random.default_rng(4)
    target = np.array([0.3, -0.2, 2.0])
    origins = rng.normal(size=(6, 3))
    result = triangulate_rays(origins, target - origins)
    np.testing.assert_allclose(result.point, target, atol=1e-12)
    assert result.gap < 1e-12


def test_parallel_rays_are_refused() -> None:
    with pytest.raises(RayGeometryError, match="parallel"):
        triangulate_midpoint([0, 0, 0], [0, 0, 1], [1, 0, 0], [0, 0, 2])
    with pytest.raises(RayGeometryError, match="parallel"):
        triangulate_rays([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 0, 1]] * 3)


def test_pixel_rays_pass_through_the_projected_points(stereo) -> None:
    P_a, _, X = stereo
    origin, directions = pixel_rays(P_a, project(P_a, X))
    np.testing.assert_allclose(origin, [-0.3, 0.0, 0.0], atol=1e-12)
    to_points = X - origin
    ranges = np.sum(to_points * directions, axis=1)
    assert np.all(ranges > 0)  # rays point into the scene
    np.testing.assert_allclose(origin + ranges[:, None] * directions, X, atol=1e-9)


def test_rays_do_not_depend_on_camera_matrix_scale_or_sign(stereo) -> None:
    P_a, _, X = stereo
    uv = project(P_a, X[:5])
    o1, d1 = pixel_rays(P_a, uv)
    o2, d2 = pixel_rays(-0.01 * P_a, uv)
    np.testing.assert_allclose(o1, o2, atol=1e-12)
    np.testing.assert_allclose(d1, d2, atol=1e-12)
    np.testing.assert_allclose(camera_centre(-3 * P_a), o1, atol=1e-12)


@pytest.mark.parametrize("method", ["midpoint", "least_squares", "linear"])
def test_exact_pixels_triangulate_exactly(stereo, method: str) -> None:
    P_a, P_b, X = stereo
    result = triangulate_pixels([P_a, P_b], [project(P_a, X), project(P_b, X)], method)
    np.testing.assert_allclose(result.point, X, atol=1e-10)
    assert np.max(result.gap) < 1e-10


@pytest.mark.parametrize("method", ["midpoint", "least_squares", "linear"])
def test_noisy_pixels_match_opencv_triangulation(stereo, method: str) -> None:
    P_a, P_b, X = stereo
    rng = np.random.default_rng(11)
    uv_a = project(P_a, X) + rng.normal(0, 0.5, (len(X), 2))
    uv_b = project(P_b, X) + rng.normal(0, 0.5, (len(X), 2))
    ours = triangulate_pixels([P_a, P_b], [uv_a, uv_b], method).point
    h = cv2.triangulatePoints(P_a, P_b, uv_a.T, uv_b.T)
    theirs = (h[:3] / h[3]).T
    error_ours = np.linalg.norm(ours - X, axis=1)
    error_cv = np.linalg.norm(theirs - X, axis=1)
    # Same noise, same information: the estimates agree to a fraction of their error.
    assert np.median(np.linalg.norm(ours - theirs, axis=1)) < 0.2 * np.median(error_cv)
    assert np.sqrt(np.mean(error_ours**2)) < 1.2 * np.sqrt(np.mean(error_cv**2))


def test_gap_grows_with_mismatch(stereo) -> None:
    P_a, P_b, X = stereo
    uv_a, uv_b = project(P_a, X[:1]), project(P_b, X[:1])
    gaps = [triangulate_pixels([P_a, P_b], [uv_a[0], uv_b[0] + [0.0, dv]]).gap for dv in (0, 2, 20)]
    assert gaps[0] < 1e-12 < gaps[1] < gaps[2]
    # One pixel of vertical mismatch at ~2 m and f ~ 815 px is about 2.5 mm of gap.
    assert 2 * 2.0 / 815 * 0.5 < gaps[1] < 2 * 3.0 / 815 * 1.5


def test_three_cameras_least_squares(stereo) -> None:
    P_a, P_b, X = stereo
    P_c = camera([0.3, 0.0, 0.0], [0.0, -0.5, 0.2])
    pixels = [project(P, X) for P in (P_a, P_b, P_c)]
    for method in ("least_squares", "linear"):
        result = triangulate_pixels([P_a, P_b, P_c], pixels, method)
        np.testing.assert_allclose(result.point, X, atol=1e-10)
    with pytest.raises(RayGeometryError, match="two cameras"):
        triangulate_pixels([P_a, P_b, P_c], pixels, "midpoint")


def test_linear_single_point_shape(stereo) -> None:
    P_a, P_b, X = stereo
    result = triangulate_linear([P_a, P_b], [project(P_a, X)[0], project(P_b, X)[0]])
    assert result.point.shape == (3,)
    assert isinstance(result.gap, float)


def test_bad_arguments_are_refused(stereo) -> None:
    P_a, P_b, _ = stereo
    with pytest.raises(RayGeometryError, match="unknown triangulation method"):
        triangulate_pixels([P_a, P_b], [[1, 2], [3, 4]], "magic")
    with pytest.raises(RayGeometryError, match="3x4"):
        pixel_rays(np.eye(3), [1, 2])
    with pytest.raises(RayGeometryError, match="at least two cameras"):
        triangulate_pixels([P_a], [[1, 2]])


def test_epipolar_lines_contain_the_matches(stereo) -> None:
    P_a, P_b, X = stereo
    uv_a, uv_b = project(P_a, X), project(P_b, X)
    lines = epipolar_line(P_a, P_b, uv_a)
    np.testing.assert_allclose(np.linalg.norm(lines[:, :2], axis=1), 1.0)
    assert np.max(np.abs(line_distance(lines, uv_b))) < 1e-9
    # Every epipolar line passes through the epipole.
    e = epipole(P_a, P_b)
    assert np.max(np.abs(lines @ e)) < 1e-9
    # A pixel shifted off its match by 3 px across the line is 3 px away.
    shifted = uv_b[0] + 3.0 * lines[0, :2]
    assert line_distance(lines[0], shifted) == pytest.approx(3.0, abs=1e-9)


def test_fundamental_matrix_matches_opencv(stereo) -> None:
    P_a, P_b, X = stereo
    uv_a, uv_b = project(P_a, X), project(P_b, X)
    F_cv, _ = cv2.findFundamentalMat(uv_a, uv_b, cv2.FM_8POINT)
    F = fundamental_matrix(P_a, P_b)
    F_cv = F_cv / np.linalg.norm(F_cv)
    sign = np.sign(np.sum(F * F_cv))
    np.testing.assert_allclose(F, sign * F_cv, atol=1e-6)
    assert np.linalg.matrix_rank(F, tol=1e-10) == 2


def test_same_centre_has_no_epipolar_geometry() -> None:
    P_a = camera([0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
    P_b = camera([0.0, 0.3, 0.0], [0.0, 0.0, 0.0])
    with pytest.raises(RayGeometryError, match="centre"):
        fundamental_matrix(P_a, P_b)
