"""A point-mass camera above a planar rectangular patch, for servo tests (no runtime)."""

from __future__ import annotations

import numpy as np

from umbra.modules.calib.camera_model import Intrinsics
from umbra.modules.geometry.transforms import integrate_body_twist, transform_from_xyz_rpy_deg
from umbra.modules.servo.features import MomentFeatures, features_from_contour

INTRINSICS = Intrinsics(fx=600.0, fy=610.0, skew=0.0, u0=320.0, v0=240.0)
PATCH_SIZE = (0.08, 0.05)  # metres: a rectangle, long side along world x
PATCH_AREA = PATCH_SIZE[0] * PATCH_SIZE[1]
#: vsServo parameters that describe this scene's patch and camera.
SCENE_PARAMS = {
    "patch_width": PATCH_SIZE[0],
    "patch_height": PATCH_SIZE[1],
    "fx": INTRINSICS.fx,
    "fy": INTRINSICS.fy,
    "u0": INTRINSICS.u0,
    "v0": INTRINSICS.v0,
}


def patch_corners(samples_per_side: int = 8) -> np.ndarray:
    """Points on the patch outline (world frame, z = 0), like a snake's vertices."""
    w, h = PATCH_SIZE[0] / 2, PATCH_SIZE[1] / 2
    corners = np.array([[-w, -h], [w, -h], [w, h], [-w, h]])
    points = []
    for i in range(4):
        a, b = corners[i], corners[(i + 1) % 4]
        for t in np.linspace(0, 1, samples_per_side, endpoint=False):
            points.append(a + t * (b - a))
    return np.c_[np.array(points), np.zeros(len(points))]


def camera_above(x: float, y: float, height: float, yaw_deg: float, tilt_deg=(0.0, 0.0)):
    """T_world_camera: camera at (x, y, height) looking down (camera z = world -z)."""
    looking_down = transform_from_xyz_rpy_deg([x, y, height], [180.0, 0.0, 0.0])
    turn = transform_from_xyz_rpy_deg([0, 0, 0], [tilt_deg[0], tilt_deg[1], yaw_deg])
    return looking_down @ turn


def project(T_world_camera: np.ndarray, points_world: np.ndarray) -> np.ndarray:
    T_camera_world = np.linalg.inv(T_world_camera)
    p = points_world @ T_camera_world[:3, :3].T + T_camera_world[:3, 3]
    if np.any(p[:, 2] <= 0):
        raise ValueError("patch behind the camera")
    return INTRINSICS.pixels_from_normalized(p[:, :2] / p[:, 2:3])


def features_seen(T_world_camera: np.ndarray) -> MomentFeatures:
    return features_from_contour(project(T_world_camera, patch_corners()), INTRINSICS, PATCH_AREA)


def move(T_world_camera: np.ndarray, camera_twist: np.ndarray, dt: float) -> np.ndarray:
    return integrate_body_twist(T_world_camera, camera_twist, dt)
