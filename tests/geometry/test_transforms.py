"""Homogeneous transforms and the camera-to-tool twist transform."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from umbra.modules.geometry import transforms as tf


def random_transform(rng: np.random.Generator, reach: float = 0.5) -> np.ndarray:
    R = Rotation.random(random_state=rng).as_matrix()
    return tf.transform_from_rotation_translation(R, rng.uniform(-reach, reach, 3))


def test_invert_and_compose():
    rng = np.random.default_rng(0)
    for _ in range(50):
        A, B = random_transform(rng), random_transform(rng)
        np.testing.assert_allclose(tf.invert_transform(A), np.linalg.inv(A), atol=1e-12)
        np.testing.assert_allclose(tf.compose(A, tf.invert_transform(A)), np.eye(4), atol=1e-12)
        np.testing.assert_allclose(tf.compose(A, B), A @ B)
        assert tf.is_rigid(A @ B)


def test_rotations_agree_with_opencv_rodrigues():
    for axis, vector in (("x", [1, 0, 0]), ("y", [0, 1, 0]), ("z", [0, 0, 1])):
        R_cv, _ = cv2.Rodrigues(np.array(vector, dtype=float) * 0.7)
        np.testing.assert_allclose(tf.rotation_about_axis(axis, 0.7)[:3, :3], R_cv, atol=1e-12)


def test_transform_points_matches_homogeneous_product():
    rng = np.random.default_rng(1)
    T = random_transform(rng)
    points = rng.normal(size=(10, 3))
    homogeneous = np.c_[points, np.ones(10)] @ T.T
    np.testing.assert_allclose(tf.transform_points(T, points), homogeneous[:, :3])


def test_xyz_rpy_deg_round_trip_and_convention():
    T = tf.transform_from_xyz_rpy_deg([0.1, 0.2, 0.3], [10, 20, 30])
    R_expected = (tf.rot_z(np.radians(30)) @ tf.rot_y(np.radians(20)) @ tf.rot_x(np.radians(10)))[
        :3, :3
    ]
    np.testing.assert_allclose(T[:3, :3], R_expected, atol=1e-12)
    xyz, rpy = tf.xyz_rpy_deg_from_transform(T)
    np.testing.assert_allclose(xyz, [0.1, 0.2, 0.3])
    np.testing.assert_allclose(rpy, [10, 20, 30])


def test_pure_rotation_mount_only_rotates_the_twist():
    T_tool_camera = tf.transform_from_xyz_rpy_deg([0, 0, 0], [0, 0, 90])
    tool = tf.twist_tool_from_camera(T_tool_camera, [1, 0, 0, 0, 0, 0])
    np.testing.assert_allclose(tool, [0, 1, 0, 0, 0, 0], atol=1e-12)


def test_offset_camera_adds_the_lever_arm_term():
    # Camera 0.1 m along tool z; spinning the camera about its own axis x must move the tool
    # origin: v_tool = w x (p_tool - p_cam) = (1,0,0) x (0,0,-0.1) = (0, 0.1, 0).
    T_tool_camera = tf.translation(0.0, 0.0, 0.1)
    tool = tf.twist_tool_from_camera(T_tool_camera, [0, 0, 0, 1, 0, 0])
    np.testing.assert_allclose(tool, [0, 0.1, 0, 1, 0, 0], atol=1e-12)


def test_twist_transform_moves_the_camera_as_asked():
    """Move the tool by the converted twist for a small dt; the camera moves by its twist."""
    rng = np.random.default_rng(2)
    dt = 1e-4
    for _ in range(50):
        T_base_tool = random_transform(rng, reach=1.0)
        T_tool_camera = random_transform(rng, reach=0.2)
        camera_twist = rng.normal(size=6)
        tool_twist = tf.twist_tool_from_camera(T_tool_camera, camera_twist)
        moved_camera = tf.integrate_body_twist(T_base_tool, tool_twist, dt) @ T_tool_camera
        expected = tf.integrate_body_twist(T_base_tool @ T_tool_camera, camera_twist, dt)
        # Exact for a constant twist of a rigid body (not only to first order).
        np.testing.assert_allclose(moved_camera, expected, atol=1e-12)
        # And the camera's finite-difference velocity equals the asked twist.
        T0 = T_base_tool @ T_tool_camera
        delta = tf.invert_transform(T0) @ moved_camera
        v = delta[:3, 3] / dt
        w = Rotation.from_matrix(delta[:3, :3]).as_rotvec() / dt
        np.testing.assert_allclose(np.r_[v, w], camera_twist, atol=1e-3)


def test_closed_form_exponential_matches_expm():
    rng = np.random.default_rng(4)
    for scale in (1.0, 1e-3, 1e-8, 0.0):
        for _ in range(20):
            xi = rng.normal(size=6) * scale
            np.testing.assert_allclose(
                tf.twist_exponential(xi, 0.7), tf.twist_exponential_expm(xi, 0.7), atol=1e-13
            )


def test_adjoint_matches_the_function_and_inverts():
    rng = np.random.default_rng(3)
    T = random_transform(rng)
    xi = rng.normal(size=6)
    np.testing.assert_allclose(tf.twist_adjoint(T) @ xi, tf.twist_tool_from_camera(T, xi))
    back = tf.twist_camera_from_tool(T, tf.twist_tool_from_camera(T, xi))
    np.testing.assert_allclose(back, xi, atol=1e-12)


def test_bad_shapes_are_rejected():
    with pytest.raises(tf.TransformError, match="6 entries"):
        tf.twist_tool_from_camera(np.eye(4), [1, 2, 3])
    with pytest.raises(tf.TransformError, match="shape"):
        tf.transform_from_rotation_translation(np.eye(2), [0, 0, 0])
    with pytest.raises(tf.TransformError, match="axis"):
        tf.rotation_about_axis("w", 1.0)


def test_rigid_and_orthonormal_transforms_share_one_rule():
    A = random_transform(np.random.default_rng(7))
    mirror = A.copy()
    mirror[:3, 2] *= -1.0  # a reflection: orthonormal axes, det -1
    scaled = A.copy()
    scaled[:3, :3] *= 1.01
    not_affine = A.copy()
    not_affine[3, 0] = 0.1
    assert tf.is_rigid(A) and tf.is_orthonormal_transform(A)
    assert not tf.is_rigid(mirror) and tf.is_orthonormal_transform(mirror)
    for bad in (scaled, not_affine, np.full((4, 4), np.nan), np.eye(3)):
        assert not tf.is_rigid(bad) and not tf.is_orthonormal_transform(bad)
    nudged = A.copy()
    nudged[0, 3] += 1.0  # translation is free
    nudged[:3, :3] += 5e-7  # within 1e-6, not within 1e-9
    assert tf.is_orthonormal_transform(nudged, 1e-6) and not tf.is_orthonormal_transform(nudged)
