"""Rotation helpers against OpenCV's Rodrigues and scipy."""

from __future__ import annotations

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from umbra.modules.calib.rotations import (
    invert_transform,
    nearest_rotation,
    rotation_from_vector,
    rotation_from_xyz,
    transform,
    vector_from_rotation,
    xyz_from_rotation,
)


def test_rodrigues_matches_cv2_including_tiny_angles() -> None:
    rng = np.random.default_rng(51)
    for scale in (3.0, 1.0, 1e-3, 1e-7, 1e-9, 0.0):
        w = rng.normal(size=3) * scale
        expected, _ = cv2.Rodrigues(w)
        np.testing.assert_allclose(rotation_from_vector(w), expected, atol=1e-15)
        if scale:
            np.testing.assert_allclose(
                vector_from_rotation(rotation_from_vector(w)), w, rtol=1e-9, atol=1e-15
            )


def test_xyz_angles_are_fixed_axis_rz_ry_rx() -> None:
    angles = np.array([0.3, -0.2, 1.1])
    Rx = Rotation.from_rotvec([angles[0], 0, 0]).as_matrix()
    Ry = Rotation.from_rotvec([0, angles[1], 0]).as_matrix()
    Rz = Rotation.from_rotvec([0, 0, angles[2]]).as_matrix()
    np.testing.assert_allclose(rotation_from_xyz(angles), Rz @ Ry @ Rx, atol=1e-15)
    np.testing.assert_allclose(xyz_from_rotation(rotation_from_xyz(angles)), angles, atol=1e-12)


def test_nearest_rotation_and_inverse_transform() -> None:
    rng = np.random.default_rng(52)
    R = rotation_from_vector(rng.normal(size=3))
    noisy = R + rng.normal(0, 1e-3, (3, 3))
    fixed = nearest_rotation(noisy)
    np.testing.assert_allclose(fixed @ fixed.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(fixed) > 0 and np.abs(fixed - R).max() < 5e-3
    T = transform(R, [1.0, -2.0, 0.5])
    np.testing.assert_allclose(invert_transform(T) @ T, np.eye(4), atol=1e-12)
