"""Pin-hole projection with OpenCV's lens distortion, for the simulated camera.

Camera frame: x right, y down, z along the optical axis (OpenCV). A point (x, y, z) in the
camera frame [m] projects to normalized (a, b) = (x/z, y/z), is distorted with OpenCV's model

    r² = a² + b²,  radial = 1 + k1 r² + k2 r⁴ + k3 r⁶
    a_d = a radial + 2 p1 a b + p2 (r² + 2 a²)
    b_d = b radial + p1 (r² + 2 b²) + 2 p2 a b

and mapped to pixels u = fx a_d + skew b_d + u0, v = fy b_d + v0 (tested against
``cv2.projectPoints``). The distortion model itself is :mod:`umbra.modules.calib.distortion`'s;
points change frames with :func:`umbra.modules.geometry.transforms.transform_points`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.modules.calib.distortion import distort_normalized

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class CameraIntrinsics:
    """Pixels: focal lengths ``fx``, ``fy``, ``skew``, principal point ``u0``, ``v0``; size."""

    fx: float = 600.0
    fy: float = 600.0
    skew: float = 0.0
    u0: float = 320.0
    v0: float = 240.0
    width: int = 640
    height: int = 480

    def matrix(self) -> FloatArray:
        """The 3x3 camera matrix K."""
        return np.array(
            [[self.fx, self.skew, self.u0], [0.0, self.fy, self.v0], [0.0, 0.0, 1.0]],
            dtype=np.float64,
        )


@dataclass(frozen=True)
class Distortion:
    """OpenCV distortion coefficients (unitless): radial k1, k2, k3 and tangential p1, p2."""

    k1: float = 0.0
    k2: float = 0.0
    p1: float = 0.0
    p2: float = 0.0
    k3: float = 0.0

    def as_array(self) -> FloatArray:
        """[k1, k2, p1, p2, k3], OpenCV's order."""
        return np.array([self.k1, self.k2, self.p1, self.p2, self.k3], dtype=np.float64)

    @property
    def is_zero(self) -> bool:
        return not np.any(self.as_array())


def project_camera_points(
    points_camera: ArrayLike, intrinsics: CameraIntrinsics, distortion: Distortion | None = None
) -> FloatArray:
    """Pixels (N x 2) of points (N x 3) given in the camera frame [m]; z must be positive."""
    points = np.asarray(points_camera, dtype=np.float64).reshape(-1, 3)
    if np.any(points[:, 2] <= 0.0):
        raise ValueError("cannot project points at or behind the camera plane (z <= 0)")
    ab = points[:, :2] / points[:, 2:3]
    if distortion is not None and not distortion.is_zero:
        ab = distort_normalized(ab, distortion.as_array())
    u = intrinsics.fx * ab[:, 0] + intrinsics.skew * ab[:, 1] + intrinsics.u0
    v = intrinsics.fy * ab[:, 1] + intrinsics.v0
    return np.column_stack([u, v])


def undistort_normalized(
    ab_distorted: FloatArray, distortion: Distortion, iterations: int = 30
) -> FloatArray:
    """Invert :func:`~umbra.modules.calib.distortion.distort_normalized` by fixed-point iteration,
    as OpenCV's undistortPoints. Unlike :func:`umbra.modules.calib.distortion.undistort_normalized`
    (Newton, NaN where the lens folds over) it gives finite, if meaningless, values beyond the
    fold, which the renderer's margin and remap tables can take."""
    a_d, b_d = ab_distorted[:, 0], ab_distorted[:, 1]
    a, b = a_d.copy(), b_d.copy()
    for _ in range(iterations):
        r2 = a * a + b * b
        radial = 1.0 + r2 * (distortion.k1 + r2 * (distortion.k2 + r2 * distortion.k3))
        delta_a = 2.0 * distortion.p1 * a * b + distortion.p2 * (r2 + 2.0 * a * a)
        delta_b = distortion.p1 * (r2 + 2.0 * b * b) + 2.0 * distortion.p2 * a * b
        a = (a_d - delta_a) / radial
        b = (b_d - delta_b) / radial
    return np.column_stack([a, b])


def ideal_pixels_of_distorted_grid(
    intrinsics: CameraIntrinsics, distortion: Distortion
) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """For every pixel of the distorted image, where the same ray lands in the ideal (undistorted)
    image: two H x W float32 maps (u, v) for ``cv2.remap``. Solved once by iteration."""
    width, height = intrinsics.width, intrinsics.height
    uu, vv = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
    b_d = (vv.ravel() - intrinsics.v0) / intrinsics.fy
    a_d = (uu.ravel() - intrinsics.u0 - intrinsics.skew * b_d) / intrinsics.fx
    ab = undistort_normalized(np.column_stack([a_d, b_d]), distortion)
    u = intrinsics.fx * ab[:, 0] + intrinsics.skew * ab[:, 1] + intrinsics.u0
    v = intrinsics.fy * ab[:, 1] + intrinsics.v0
    shape = (height, width)
    return u.reshape(shape).astype(np.float32), v.reshape(shape).astype(np.float32)
