"""Appendix A of the Sandia report: the camera matrix from 3-D/2-D pairs (direct linear transform).

Each pair ``(x, y, z) -> (u, v)`` gives two equations linear in the twelve entries of the 3x4
camera matrix ``C`` (equation 10 of the report). The report fixes ``c34 = 1`` and takes the
pseudo-inverse; here the homogeneous system is solved by SVD after Hartley's normalization
(points moved to their centroid and scaled to mean distance sqrt(3), pixels to sqrt(2)), which
is better conditioned and does not fail when ``c34`` is near zero (world origin on the camera's
principal plane).

The configuration is checked before solving: at least six pairs, finite values, points that are
not coplanar (Appendix A requires "at least 6 non-planar points"), and a design matrix whose null
space is one-dimensional.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.modules.calib.decompose import normalize_camera_matrix
from umbra.modules.calib.errors import DegenerateGeometryError

FloatArray = NDArray[np.float64]

#: Thickness over extent below which the 3-D points are called coplanar.
COPLANAR_TOLERANCE = 1e-6
#: Second-smallest over largest singular value of the design matrix below which it is rank < 11.
RANK_TOLERANCE = 1e-9


def check_correspondences(
    points: ArrayLike, pixels: ArrayLike, minimum: int = 6
) -> tuple[FloatArray, FloatArray]:
    """Validate ``(n, 3)`` points and ``(n, 2)`` pixels; return them as float arrays."""
    X = np.asarray(points, dtype=float)
    uv = np.asarray(pixels, dtype=float)
    if X.ndim != 2 or X.shape[1] != 3:
        raise DegenerateGeometryError(f"points must have shape (n, 3), got {X.shape}")
    if uv.ndim != 2 or uv.shape[1] != 2:
        raise DegenerateGeometryError(f"pixels must have shape (n, 2), got {uv.shape}")
    if len(X) != len(uv):
        raise DegenerateGeometryError(f"{len(X)} points but {len(uv)} pixels")
    if len(X) < minimum:
        raise DegenerateGeometryError(f"need at least {minimum} point/pixel pairs, got {len(X)}")
    if not (np.all(np.isfinite(X)) and np.all(np.isfinite(uv))):
        raise DegenerateGeometryError("points and pixels must be finite numbers")
    return X, uv


def check_not_coplanar(points: FloatArray) -> None:
    """Raise if the points lie on one plane (or line) within :data:`COPLANAR_TOLERANCE`."""
    centred = points - points.mean(axis=0)
    singular = np.linalg.svd(centred, compute_uv=False)
    if singular[0] == 0 or singular[2] <= COPLANAR_TOLERANCE * singular[0]:
        shape = "collinear" if singular[1] <= COPLANAR_TOLERANCE * singular[0] else "coplanar"
        raise DegenerateGeometryError(
            f"the 3-D points are {shape} (spread across the thinnest direction "
            f"{singular[2] / np.sqrt(len(points)):.3g} vs {singular[0] / np.sqrt(len(points)):.3g} "
            "along the widest); the DLT needs points in at least two planes"
        )


def normalizing_transform(points: FloatArray) -> FloatArray:
    """Hartley similarity (``(k+1) x (k+1)``) moving k-D points to mean distance sqrt(k) about 0."""
    k = points.shape[1]
    centroid = points.mean(axis=0)
    mean_distance = np.mean(np.linalg.norm(points - centroid, axis=1))
    if mean_distance == 0:
        raise DegenerateGeometryError("all points coincide")
    scale = np.sqrt(k) / mean_distance
    T = np.eye(k + 1)
    T[:k, :k] *= scale
    T[:k, k] = -scale * centroid
    return T


def design_matrix(points: FloatArray, pixels: FloatArray) -> FloatArray:
    """The ``2n x 12`` matrix ``A`` of ``A vec(C) = 0`` (equation 10 of the report, homogeneous)."""
    n = len(points)
    Xh = np.hstack([points, np.ones((n, 1))])
    A = np.zeros((2 * n, 12))
    A[0::2, 0:4] = Xh
    A[0::2, 8:12] = -pixels[:, 0:1] * Xh
    A[1::2, 4:8] = Xh
    A[1::2, 8:12] = -pixels[:, 1:2] * Xh
    return A


def dlt_camera_matrix(points: ArrayLike, pixels: ArrayLike) -> FloatArray:
    """Camera matrix from ``n >= 6`` non-coplanar points (metres) and their ideal pixels.

    Returns:
        ``P`` (3x4) scaled as :func:`umbra.modules.calib.decompose.normalize_camera_matrix` does
        (``|m3| = 1``, ``det M > 0``), so ``P @ (X, 1)`` has the point's depth as third entry.

    Raises:
        DegenerateGeometryError: too few pairs, coplanar points, a rank-deficient design matrix,
            or points that would lie behind the fitted camera.
    """
    X, uv = check_correspondences(points, pixels)
    check_not_coplanar(X)
    T3 = normalizing_transform(X)
    T2 = normalizing_transform(uv)
    Xn = (np.hstack([X, np.ones((len(X), 1))]) @ T3.T)[:, :3]
    uvn = (np.hstack([uv, np.ones((len(uv), 1))]) @ T2.T)[:, :2]
    A = design_matrix(Xn, uvn)
    _, singular, Vt = np.linalg.svd(A, full_matrices=False)
    if singular[10] <= RANK_TOLERANCE * singular[0]:
        raise DegenerateGeometryError(
            "the DLT system has rank < 11: the points do not determine a unique camera "
            "(add points off the current planes/lines)"
        )
    Pn = Vt[-1].reshape(3, 4)
    P = normalize_camera_matrix(np.linalg.solve(T2, Pn @ T3))
    depths = np.hstack([X, np.ones((len(X), 1))]) @ P[2]
    if np.count_nonzero(depths > 0) < len(X) / 2:
        raise DegenerateGeometryError(
            "the fitted camera sees the points behind it (mirror-image fit): the pixel and point "
            "coordinate systems have opposite handedness (check the sign of an axis)"
        )
    return P


def project(P: ArrayLike, points: ArrayLike) -> FloatArray:
    """Pixels ``(n, 2)`` of points ``(n, 3)`` through camera matrix ``P``."""
    X = np.asarray(points, dtype=float)
    h = np.hstack([X, np.ones((len(X), 1))]) @ np.asarray(P, dtype=float).T
    return h[:, :2] / h[:, 2:3]


def reprojection_errors(P: ArrayLike, points: ArrayLike, pixels: ArrayLike) -> FloatArray:
    """Pixel distance between each measured pixel and the projection of its point."""
    return np.linalg.norm(project(P, points) - np.asarray(pixels, dtype=float), axis=1)


def rms(errors: ArrayLike) -> float:
    """Root mean square of pixel distances."""
    e = np.asarray(errors, dtype=float)
    return float(np.sqrt(np.mean(e**2)))
