"""Pin-hole projection with OpenCV's lens distortion, for the simulated camera.

Camera frame: x right, y down, z along the optical axis (OpenCV). A point (x, y, z) in the
camera frame [m] projects to normalized (a, b) = (x/z, y/z), is distorted with OpenCV's model

    r² = a² + b²,  radial = 1 + k1 r² + k2 r⁴ + k3 r⁶
    a_d = a radial + 2 p1 a b + p2 (r² + 2 a²)
    b_d = b radial + p1 (r² + 2 b²) + 2 p2 a b

and mapped to pixels u = fx a_d + skew b_d + u0, v = fy b_d + v0 (tested against
``cv2.projectPoints``). The camera model is calibration's: the intrinsics are
:class:`umbra.modules.calib.camera_model.Intrinsics` (pixels, with the image size), the distortion
OpenCV's coefficients ``[k1, k2, p1, p2(, k3)]`` and its model
:mod:`umbra.modules.calib.distortion`'s; points change frames with
:func:`umbra.modules.geometry.transforms.transform_points`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.modules.calib.camera_model import Intrinsics
from umbra.modules.calib.distortion import distort_normalized, undistort_normalized_fixed_point

FloatArray = NDArray[np.float64]


def project_camera_points(
    points_camera: ArrayLike, intrinsics: Intrinsics, distortion: ArrayLike | None = None
) -> FloatArray:
    """Pixels (N x 2) of points (N x 3) given in the camera frame [m]; z must be positive.
    ``distortion``: OpenCV's ``[k1, k2, p1, p2(, k3)]`` (None or all zero: an ideal lens)."""
    points = np.asarray(points_camera, dtype=np.float64).reshape(-1, 3)
    if np.any(points[:, 2] <= 0.0):
        raise ValueError("cannot project points at or behind the camera plane (z <= 0)")
    ab = points[:, :2] / points[:, 2:3]
    if distortion is not None and np.any(distortion):
        ab = distort_normalized(ab, distortion)
    return intrinsics.pixels_from_normalized(ab)


def ideal_pixels_of_distorted_grid(
    intrinsics: Intrinsics, distortion: ArrayLike
) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """For every pixel of the distorted image (``intrinsics.width`` x ``intrinsics.height``),
    where the same ray lands in the ideal (undistorted) image: two H x W float32 maps (u, v) for
    ``cv2.remap``. Solved once by fixed-point iteration, finite also beyond the lens's fold
    (:func:`~umbra.modules.calib.distortion.undistort_normalized_fixed_point`)."""
    width, height = intrinsics.width, intrinsics.height
    uu, vv = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
    distorted = intrinsics.normalized_from_pixels(np.column_stack([uu.ravel(), vv.ravel()]))
    ideal = intrinsics.pixels_from_normalized(
        undistort_normalized_fixed_point(distorted, distortion)
    )
    shape = (height, width)
    u, v = ideal[:, 0], ideal[:, 1]
    return u.reshape(shape).astype(np.float32), v.reshape(shape).astype(np.float32)
