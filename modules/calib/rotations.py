"""Rotation helpers: skew matrices, rotation vectors and the x-y-z angles of the zoom file.

All angles are radians. ``R`` is a proper rotation matrix (orthonormal, ``det R = +1``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

# The project's transform helpers; re-exported here for the calibration code.
from umbra.modules.geometry.transforms import invert_transform, skew
from umbra.modules.geometry.transforms import transform_from_rotation_translation as transform

__all__ = [
    "invert_transform",
    "nearest_rotation",
    "rotation_from_vector",
    "rotation_from_xyz",
    "skew",
    "transform",
    "vector_from_rotation",
    "xyz_from_rotation",
]

FloatArray = NDArray[np.float64]


def rotation_from_vector(rotation_vector: ArrayLike) -> FloatArray:
    """Rotation matrix of an axis-angle vector (axis times angle in radians; Rodrigues)."""
    w = np.asarray(rotation_vector, dtype=float).reshape(3)
    theta2 = float(w @ w)
    W = skew(w)
    if theta2 < 1e-12:  # series of sin(t)/t and (1 - cos t)/t^2, exact to double precision here
        a, b = 1.0 - theta2 / 6.0, 0.5 - theta2 / 24.0
    else:
        theta = np.sqrt(theta2)
        a, b = np.sin(theta) / theta, (1.0 - np.cos(theta)) / theta2
    return np.eye(3) + a * W + b * (W @ W)


def vector_from_rotation(R: ArrayLike) -> FloatArray:
    """Axis-angle vector (radians) of a rotation matrix."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(np.asarray(R, dtype=float)).as_rotvec()


def rotation_from_xyz(angles_rad: ArrayLike) -> FloatArray:
    """``R = Rz(tz) Ry(ty) Rx(tx)``: rotations about the fixed x, then y, then z axes.

    This is the reading used for the zoom file's ``thetax thetay thetaz``.
    """
    from scipy.spatial.transform import Rotation

    return Rotation.from_euler("xyz", np.asarray(angles_rad, dtype=float)).as_matrix()


def xyz_from_rotation(R: ArrayLike) -> FloatArray:
    """Inverse of :func:`rotation_from_xyz` (radians, ``ty`` in ``[-pi/2, pi/2]``)."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(np.asarray(R, dtype=float)).as_euler("xyz")


def nearest_rotation(M: ArrayLike) -> FloatArray:
    """Closest proper rotation to a 3x3 matrix in the Frobenius norm (SVD projection)."""
    U, _, Vt = np.linalg.svd(np.asarray(M, dtype=float))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    return U @ D @ Vt
