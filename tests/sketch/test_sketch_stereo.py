"""Stereo pair of a snapshot: epipolar constraint and triangulation with covariance."""

from __future__ import annotations

import numpy as np
import pytest

from umbra.connectors.sketch_messages import StereoSnapshot
from umbra.modules.ptu.aim import look_at
from umbra.modules.sketch.primitives import (
    PrimitiveError,
    line_axis,
    place_primitive,
    plane_rect,
    triad_box,
)
from umbra.modules.sketch.stereo import StereoNoise, StereoPair

K = np.array([[900.0, 0.0, 320.0], [0.0, 900.0, 240.0], [0.0, 0.0, 1.0]])
TARGET = np.array([0.6, 0.1, 0.3])


def _pair(dist=(0, 0, 0, 0, 0), distance=1.5) -> StereoPair:
    eye_a = TARGET + np.array([-distance, -0.2, 0.5])
    eye_b = eye_a + np.array([0.0, 0.4, 0.0])
    return StereoPair(K, look_at(eye_a, TARGET), K, look_at(eye_b, TARGET), dist, dist)


def test_projection_of_target_is_near_centre_and_triangulates_back():
    pair = _pair()
    uv_a, uv_b = pair.project("a", TARGET), pair.project("b", TARGET)
    assert np.allclose(uv_a, [320, 240], atol=1e-6) and np.allclose(uv_b, [320, 240], atol=1e-6)
    point, gap = pair.triangulate(uv_a, uv_b)
    assert np.allclose(point, TARGET, atol=1e-9) and gap < 1e-9


@pytest.mark.parametrize("dist", [(0, 0, 0, 0, 0), (-0.12, 0.05, 0.001, -0.0008, 0.0)])
def test_constrained_vertex_lies_on_epipolar_line_to_1e6_px(dist):
    pair = _pair(dist)
    rng = np.random.default_rng(3)
    uv_a = rng.uniform([50, 50], [590, 430], size=(40, 2))
    uv_b = rng.uniform([50, 50], [590, 430], size=(40, 2))
    constrained = pair.constrain_b(uv_a, uv_b)
    assert np.max(pair.epipolar_error_px(uv_a, constrained)) < 1e-6
    assert np.max(pair.epipolar_error_px(uv_a, uv_b)) > 10.0  # the raw drags were off the line
    # a point's true images satisfy the constraint and are left where they are
    points = TARGET + rng.uniform(-0.2, 0.2, size=(10, 3))
    a, b = pair.project("a", points), pair.project("b", points)
    assert np.max(np.abs(pair.constrain_b(a, b) - b)) < 1e-6


def test_covariance_matches_monte_carlo_of_pixel_noise():
    pair = _pair()
    noise = StereoNoise(pixel_px=0.7, rotation_rad=0, translation_m=0, focal_rel=0, principal_px=0)
    uv_a, uv_b = pair.project("a", TARGET), pair.project("b", TARGET)
    point, cov, _ = pair.triangulate_with_covariance(uv_a, uv_b, noise)
    rng = np.random.default_rng(5)
    samples = np.stack(
        [
            pair.triangulate(uv_a + rng.normal(0, 0.7, 2), uv_b + rng.normal(0, 0.7, 2))[0]
            for _ in range(1500)
        ]
    )
    empirical = np.cov(samples.T)
    assert np.allclose(point, TARGET, atol=1e-9)
    w_pred, w_emp = np.linalg.eigvalsh(cov), np.linalg.eigvalsh(empirical)
    assert np.allclose(np.sqrt(w_emp[1:]), np.sqrt(w_pred[1:]), rtol=0.12)
    # depth dominates, as the textbook figure Z^2 sqrt(2) sigma / (f B) says (B = 0.4 m)
    depth = np.linalg.norm(TARGET - pair._a.T_base_camera[:3, 3])
    textbook = depth**2 * np.sqrt(2) * 0.7 / (900.0 * 0.4)
    assert np.sqrt(w_pred[-1]) == pytest.approx(textbook, rel=0.05)
    assert np.sqrt(w_pred[-1]) > 5 * np.sqrt(w_pred[0])


def test_calibration_noise_adds_to_the_covariance_and_zoom_shrinks_it():
    pixel_only = StereoNoise(rotation_rad=0, translation_m=0, focal_rel=0, principal_px=0)
    full = StereoNoise()
    pair = _pair()
    uv = pair.project("a", TARGET), pair.project("b", TARGET)
    _, cov_pixel, _ = pair.triangulate_with_covariance(*uv, pixel_only)
    _, cov_full, _ = pair.triangulate_with_covariance(*uv, full)
    assert np.trace(cov_full) > 1.2 * np.trace(cov_pixel)
    zoomed = StereoPair(
        np.diag([3.0, 3.0, 1.0]) @ K,
        pair._a.T_base_camera,
        np.diag([3.0, 3.0, 1.0]) @ K,
        pair._b.T_base_camera,
    )
    uvz = zoomed.project("a", TARGET), zoomed.project("b", TARGET)
    _, cov_zoom, _ = zoomed.triangulate_with_covariance(*uvz, pixel_only)
    assert np.trace(cov_zoom) == pytest.approx(np.trace(cov_pixel) / 9.0, rel=0.05)


def test_line_plane_triad_primitives_from_pixels():
    pair = _pair()
    noise = StereoNoise()
    ends = np.array([[0.6, -0.1, 0.3], [0.6, 0.3, 0.3]])
    # the operator's right-hand clicks are 8 px off the epipolar line; the constraint fixes them
    b_clicks = pair.project("b", ends) + np.array([[0.0, 8.0], [0.0, -8.0]])
    line = place_primitive(
        pair, "line", pair.project("a", ends), b_clicks, noise, primitive_id="L1"
    )
    axis = line_axis(line)
    assert np.allclose(axis.middle, ends.mean(axis=0), atol=2e-3)
    assert axis.direction @ np.array([0, 1, 0]) > 0.999
    assert line.covariances.shape == (2, 3, 3) and np.all(line.gaps < 1e-9)
    corners = np.array([[0.5, 0.0, 0.2], [0.5, 0.2, 0.2], [0.7, 0.2, 0.2]])
    plane = place_primitive(
        pair,
        "plane",
        pair.project("a", corners),
        pair.project("b", corners),
        noise,
        primitive_id="P1",
    )
    rect = plane_rect(plane)
    assert abs(rect.normal @ [0, 0, 1]) > 1 - 1e-9
    assert np.allclose(rect.perimeter()[2], [0.7, 0.0, 0.2], atol=1e-9)
    box_pts = np.array([[0.5, 0.0, 0.1], [0.8, 0.0, 0.1], [0.5, 0.2, 0.1], [0.5, 0.0, 0.25]])
    triad = place_primitive(
        pair,
        "triad",
        pair.project("a", box_pts),
        pair.project("b", box_pts),
        noise,
        primitive_id="T1",
    )
    box = triad_box(triad)
    assert np.allclose(box.size, [0.3, 0.2, 0.15], atol=1e-9)
    assert np.allclose(box.T_base_box[:3, 3], [0.65, 0.1, 0.175], atol=1e-9)
    with pytest.raises(PrimitiveError, match="a line has 2 vertices"):
        place_primitive(pair, "line", [[1, 2]], [[1, 2]], noise, primitive_id="bad")


def test_snapshot_rebuilds_the_same_pair():
    pair = _pair()
    snap = StereoSnapshot(
        snapshot_id="s1",
        image_a=np.zeros((480, 640, 3), np.uint8),
        image_b=np.zeros((480, 640, 3), np.uint8),
        K_a=K,
        K_b=K,
        T_base_camera_a=pair._a.T_base_camera,
        T_base_camera_b=pair._b.T_base_camera,
    )
    again = StereoPair.from_snapshot(snap)
    assert np.allclose(again.P_a, pair.P_a) and np.allclose(snap.camera_matrix("b"), pair.P_b)
