"""Non-perspective n-point pose (Appendix C) and the calibration transform loop (section 5.4)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from umbra.modules.calib.camera_model import Intrinsics, PinholeCamera
from umbra.modules.calib.errors import DegenerateGeometryError
from umbra.modules.calib.npnp import View, initial_pose, linear_generalized_pose, solve_npnp
from umbra.modules.calib.rotations import (
    invert_transform,
    rotation_from_vector,
    transform,
    vector_from_rotation,
)
from umbra.modules.calib.synthetic import TYPICAL_DISTORTION, random_pose, ring_of_cameras
from umbra.modules.calib.transform_loop import (
    Snapshot,
    project_loop,
    solve_device_pose,
    solve_object_pose,
)


def angle_between(R_a: np.ndarray, R_b: np.ndarray) -> float:
    return float(np.linalg.norm(vector_from_rotation(R_a.T @ R_b)))


def make_views(rng, R, d, cameras, points_per_view, noise_px, distortion=None):
    views = []
    for camera in cameras:
        if distortion is not None:
            camera = camera.with_distortion(distortion)
        points = rng.uniform(-0.15, 0.15, (points_per_view, 3))
        pixels = camera.project(points @ R.T + d)
        views.append(View(camera, points, pixels + rng.normal(0, noise_px, pixels.shape)))
    return views


def test_single_camera_matches_solvepnp() -> None:
    rng = np.random.default_rng(31)
    camera = PinholeCamera(Intrinsics(820.0, 815.0, 0.0, 331.0, 244.0), np.eye(3), np.zeros(3))
    R, d = random_pose(rng)
    d = d + np.array([0.0, 0.0, 1.5])
    points = rng.uniform(-0.2, 0.2, (12, 3))
    pixels = camera.project(points @ R.T + d) + rng.normal(0, 0.5, (12, 2))
    ours = solve_npnp([View(camera, points, pixels)])
    ok, rvec, tvec = cv2.solvePnP(points, pixels, camera.K, None, flags=cv2.SOLVEPNP_ITERATIVE)
    assert ok
    # Both minimize the same reprojection error: the same minimum.
    assert angle_between(ours.R, rotation_from_vector(rvec.ravel())) < 1e-6
    np.testing.assert_allclose(ours.d, tvec.ravel(), atol=1e-6)
    assert angle_between(ours.R, R) < np.radians(1.0)


def test_exact_multi_camera_pose_is_exact() -> None:
    rng = np.random.default_rng(32)
    R, d = random_pose(rng)
    views = make_views(rng, R, d, ring_of_cameras(3, 2.0), 3, 0.0, TYPICAL_DISTORTION)
    result = solve_npnp(views)
    assert result.rms_px < 1e-9
    assert angle_between(result.R, R) < 1e-10
    np.testing.assert_allclose(result.d, d, atol=1e-10)


def test_multi_camera_beats_any_single_view_with_noise() -> None:
    rng = np.random.default_rng(33)
    errors_all, errors_single = [], []
    for _ in range(20):
        R, d = random_pose(rng)
        views = make_views(rng, R, d, ring_of_cameras(4, 2.0), 5, 0.5)
        errors_all.append(angle_between(solve_npnp(views).R, R))
        one = views[0]
        flags = cv2.SOLVEPNP_SQPNP
        _, rvec, _ = cv2.solvePnP(one.points, one.pixels, one.camera.K, None, flags=flags)
        R_single = one.camera.R.T @ rotation_from_vector(rvec.ravel())
        errors_single.append(angle_between(R_single, R))
    assert np.median(errors_all) < 0.5 * np.median(errors_single)


def test_one_point_per_view_uses_linear_start() -> None:
    rng = np.random.default_rng(34)
    R, d = random_pose(rng, angle=1.0)
    views = make_views(rng, R, d, ring_of_cameras(8, 2.0, spread=1.2), 1, 0.0)
    R0, _ = initial_pose(views)  # no view has 4 points -> linear generalized pose
    assert angle_between(R0, R) < 1e-9
    result = solve_npnp(views)
    assert angle_between(result.R, R) < 1e-10


def test_linear_generalized_pose_with_noise_is_a_good_start() -> None:
    rng = np.random.default_rng(35)
    R, d = random_pose(rng)
    views = make_views(rng, R, d, ring_of_cameras(4, 2.0), 4, 0.3)
    R0, d0 = linear_generalized_pose(views)
    assert angle_between(R0, R) < np.radians(3.0)
    result = solve_npnp(views, initial=(R0, d0))
    assert angle_between(result.R, R) < np.radians(0.5)
    assert result.iterations < 20


def test_initial_guess_as_matrix_and_far_start() -> None:
    rng = np.random.default_rng(36)
    R, d = random_pose(rng)
    views = make_views(rng, R, d, ring_of_cameras(3, 2.0), 4, 0.0)
    start = transform(rotation_from_vector([0.2, -0.2, 0.1]) @ R, d + np.array([0.05, -0.05, 0.05]))
    result = solve_npnp(views, initial=start)
    assert angle_between(result.R, R) < 1e-10
    np.testing.assert_allclose(result.T, transform(R, d), atol=1e-10)


def test_too_few_points_and_degenerate() -> None:
    rng = np.random.default_rng(37)
    R, d = random_pose(rng)
    views = make_views(rng, R, d, ring_of_cameras(2, 2.0), 1, 0.0)
    with pytest.raises(DegenerateGeometryError, match="at least 3"):
        solve_npnp(views, initial=(R, d))
    # Three collinear points leave the rotation about their line free.
    cameras = ring_of_cameras(3, 2.0)
    line = np.outer([-0.1, 0.0, 0.1], [1.0, 0.5, 0.2])
    collinear = [View(c, line, c.project(line @ R.T + d)) for c in cameras]
    with pytest.raises(DegenerateGeometryError):
        solve_npnp(collinear, initial=(R, d))


def test_view_shape_mismatch() -> None:
    camera = ring_of_cameras(1, 2.0)[0]
    with pytest.raises(DegenerateGeometryError, match="points but"):
        View(camera, np.zeros((3, 3)), np.zeros((2, 2)))


def ptu_snapshots(rng, T_world_dev, T_world_obj, noise_px, count=6, points=3):
    """A camera on a pan-tilt head (mount 0.3 m above the device base), aimed about."""
    camera = PinholeCamera(
        Intrinsics(1000.0, 1002.0, -2.0, 320.0, 240.0),
        rotation_from_vector([0.01, -0.02, 0.03]),
        [-0.002, 0.041, 0.01],
        [-0.1, 0.05, 0.0, 0.0],
    )
    object_points = rng.uniform(-0.1, 0.1, (20, 3))
    snapshots = []
    for pan in np.linspace(-0.25, 0.25, count):
        T_dev_mount = transform(rotation_from_vector([0.0, pan, 0.0]), [0.0, -0.3, 0.0])
        chosen = object_points[rng.choice(len(object_points), points, replace=False)]
        shot = Snapshot(camera, T_dev_mount, chosen, np.zeros((points, 2)))
        pixels = project_loop(shot, T_world_dev, T_world_obj)
        pixels = pixels + rng.normal(0, noise_px, pixels.shape)
        snapshots.append(Snapshot(camera, T_dev_mount, chosen, pixels))
    return snapshots


def test_transform_loop_object_and_device_pose() -> None:
    rng = np.random.default_rng(38)
    T_world_dev = transform(rotation_from_vector([0.0, 0.0, 0.3]), [1.0, 0.5, 0.2])
    T_dev_obj = transform(rotation_from_vector([0.1, 0.2, -0.1]), [0.05, -0.25, 1.5])
    T_world_obj = T_world_dev @ T_dev_obj
    snapshots = ptu_snapshots(rng, T_world_dev, T_world_obj, 0.0)
    # Three points per image: single-view PnP has too few to start; the loop uses all images.
    obj = solve_object_pose(snapshots, T_world_dev)
    np.testing.assert_allclose(obj.T, T_world_obj, atol=1e-9)
    dev = solve_device_pose(snapshots, T_world_obj)
    np.testing.assert_allclose(dev.T, T_world_dev, atol=1e-9)
    assert obj.rms_px < 1e-8 and dev.rms_px < 1e-8


def test_transform_loop_with_noise_and_initial_guess() -> None:
    rng = np.random.default_rng(39)
    T_world_dev = transform(rotation_from_vector([0.0, 0.0, -0.2]), [0.3, 0.0, 0.0])
    T_world_obj = T_world_dev @ transform(rotation_from_vector([0.3, 0, 0]), [0.0, -0.3, 1.2])
    snapshots = ptu_snapshots(rng, T_world_dev, T_world_obj, 0.3, count=8, points=5)
    guess = T_world_obj @ transform(rotation_from_vector([0.05, 0.05, 0.0]), [0.02, 0.0, 0.03])
    obj = solve_object_pose(snapshots, T_world_dev, guess)
    assert angle_between(obj.R, T_world_obj[:3, :3]) < np.radians(0.5)
    assert np.linalg.norm(obj.d - T_world_obj[:3, 3]) < 0.01
    assert 0.2 < obj.rms_px < 0.6
    dev = solve_device_pose(snapshots, T_world_obj, invert_transform(invert_transform(T_world_dev)))
    assert np.linalg.norm(dev.d - T_world_dev[:3, 3]) < 0.01
