"""Synthetic calibration data with known truth, for tests, benchmarks and trying the tools.

The rig imitates Figure 18 of the Sandia report: a grid of known points on a panel that slides
to several depths, in front of a camera with a typical 640x480 lens (mild barrel distortion).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from umbra.modules.calib.camera_model import Intrinsics, PinholeCamera
from umbra.modules.calib.rotations import rotation_from_vector

FloatArray = NDArray[np.float64]

#: A 640x480 camera: fx, fy, skew, u0, v0 in pixels.
TYPICAL_INTRINSICS = Intrinsics(fx=820.0, fy=815.0, skew=0.0, u0=331.0, v0=244.0)
#: k1, k2, p1, p2 of a mild barrel distortion.
TYPICAL_DISTORTION = np.array([-0.21, 0.12, 0.0012, -0.0008])


def panel_rig(
    columns: int = 7,
    rows: int = 5,
    depths: tuple[float, ...] = (0.0, 0.15, 0.3),
    pitch: float = 0.09,
) -> FloatArray:
    """Grid points (metres, rig frame) of a panel at several depths (rig z); ``(n, 3)``."""
    u, v = np.meshgrid(np.arange(columns) - (columns - 1) / 2, np.arange(rows) - (rows - 1) / 2)
    grid = np.stack([u.ravel() * pitch, v.ravel() * pitch], axis=1)
    return np.vstack([np.hstack([grid, np.full((len(grid), 1), z)]) for z in depths])


def rig_camera(
    distance: float = 1.0,
    intrinsics: Intrinsics = TYPICAL_INTRINSICS,
    distortion: FloatArray = TYPICAL_DISTORTION,
    rotation_vector: tuple[float, float, float] = (0.08, -0.12, 0.03),
) -> PinholeCamera:
    """A camera ``distance`` metres in front of the rig (rig z toward the camera's -z)."""
    R = rotation_from_vector(rotation_vector)
    d = np.array([0.01, -0.02, distance + 0.1])
    return PinholeCamera(intrinsics, R, d, distortion)


def random_pose(
    rng: np.random.Generator, angle: float = 0.5, offset: float = 0.2
) -> tuple[FloatArray, FloatArray]:
    """A random rigid transform: rotation up to ``angle`` radians, translation up to ``offset``."""
    axis = rng.normal(size=3)
    R = rotation_from_vector(axis / np.linalg.norm(axis) * rng.uniform(0, angle))
    return R, rng.uniform(-offset, offset, 3)


def ring_of_cameras(
    count: int, radius: float, intrinsics: Intrinsics = TYPICAL_INTRINSICS, spread: float = 0.7
) -> list[PinholeCamera]:
    """``count`` cameras on an arc of ``radius`` metres about the origin, all looking at it."""
    cameras = []
    for angle in np.linspace(-spread, spread, count):
        R = rotation_from_vector([0.0, float(angle), 0.0]).T
        centre = rotation_from_vector([0.0, float(angle), 0.0]) @ np.array([0, 0, -radius])
        cameras.append(PinholeCamera(intrinsics, R, -R @ centre))
    return cameras


def observe(
    camera: PinholeCamera, points: FloatArray, noise_px: float, rng: np.random.Generator
) -> FloatArray:
    """Pixels of ``points`` with Gaussian noise of ``noise_px`` pixels per axis."""
    pixels = camera.project(points)
    return pixels + rng.normal(0.0, noise_px, pixels.shape)
