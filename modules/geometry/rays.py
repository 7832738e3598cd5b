"""Rays through pixels, triangulation of two or more rays, and epipolar lines.

Conventions (shared with :mod:`umbra.modules.calib`):

* A camera is given by its 3x4 camera matrix ``P = K [R | d]`` mapping a homogeneous world point
  ``(x, y, z, 1)`` in metres (world frame) to a homogeneous pixel ``(U, V, t)``, pixel
  ``(u, v) = (U/t, V/t)``. ``R``, ``d`` take world coordinates into the camera frame
  (``X_cam = R X_world + d``); the camera looks along its +z axis, x right, y down. Any nonzero
  scale of ``P`` (including a negative one) describes the same camera.
* Pixels must be ideal pin-hole pixels: undistort them first
  (:func:`umbra.modules.calib.distortion.undistort_points`).
* A ray is an origin (metres, world frame) and a unit direction pointing away from the camera into
  the scene.

Triangulation returns a :class:`Triangulation`: the point (metres, world frame) and the *gap*
(metres): for two rays the length of their common perpendicular (the distance between the rays
at their closest approach), for ``n`` rays twice the RMS perpendicular distance from the point to
the rays (the same number when ``n == 2``). A large gap means the pixels do not match.

Methods:

* :func:`triangulate_midpoint` — Duda and Hart (1973), as in the Rochester guide section 12:
  midpoint of the common perpendicular of two rays.
* :func:`triangulate_rays` — linear least squares over ``n >= 2`` rays: the point minimizing the
  sum of squared perpendicular distances (equals the midpoint for two rays).
* :func:`triangulate_linear` — the Rochester guide section 11 pseudo-inverse: two linear equations
  per camera in ``(x, y, z)`` from the rows of the camera matrices, solved by least squares.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.modules.geometry.transforms import skew

FloatArray = NDArray[np.float64]

#: Rays whose directions have ``1 - cos^2(angle) < PARALLEL_TOLERANCE`` are treated as parallel.
PARALLEL_TOLERANCE = 1e-12


class RayGeometryError(ValueError):
    """The rays or cameras given cannot define the quantity asked for (parallel rays, ...)."""


class Triangulation(NamedTuple):
    """A triangulated point (metres, world frame) and the ray gap (metres); see module docstring."""

    point: FloatArray
    gap: FloatArray | float


def _as_camera_matrix(P: ArrayLike) -> FloatArray:
    P = np.asarray(P, dtype=float)
    if P.shape != (3, 4):
        raise RayGeometryError(f"a camera matrix must be 3x4, got shape {P.shape}")
    if abs(np.linalg.det(P[:, :3])) < 1e-300 or np.linalg.cond(P[:, :3]) > 1e15:
        raise RayGeometryError("camera matrix has a singular left 3x3 block (not a finite camera)")
    return P


def _unit(v: FloatArray) -> FloatArray:
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    if np.any(norm == 0):
        raise RayGeometryError("a ray direction has zero length")
    return v / norm


def camera_centre(P: ArrayLike) -> FloatArray:
    """Centre of projection (metres, world frame) of camera matrix ``P``: the null vector of P."""
    P = _as_camera_matrix(P)
    return np.asarray(-np.linalg.solve(P[:, :3], P[:, 3]), dtype=np.float64)


def pixel_rays(P: ArrayLike, pixels: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Rays through ideal pixels of camera ``P``.

    Args:
        P: 3x4 camera matrix (any scale or sign).
        pixels: ``(2,)`` or ``(n, 2)`` pixel coordinates ``(u, v)``.

    Returns:
        ``(origin, directions)``: the camera centre ``(3,)`` and unit directions ``(3,)`` or
        ``(n, 3)`` in the world frame, pointing in front of the camera.
    """
    P = _as_camera_matrix(P)
    uv = np.asarray(pixels, dtype=float)
    if uv.shape[-1] != 2:
        raise RayGeometryError(f"pixels must have shape (2,) or (n, 2), got {uv.shape}")
    M = P[:, :3]
    homogeneous = np.concatenate([uv, np.ones((*uv.shape[:-1], 1))], axis=-1)
    directions = np.linalg.solve(M, homogeneous.reshape(-1, 3).T).T.reshape(homogeneous.shape)
    # M^-1 x points into the scene for P = s K[R|d] with s > 0; the sign of det M is that of s.
    directions *= np.sign(np.linalg.det(M))
    return camera_centre(P), _unit(directions)


def closest_ranges(
    origin_a: ArrayLike, direction_a: ArrayLike, origin_b: ArrayLike, direction_b: ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """Distances along two rays (metres) to the ends of their common perpendicular.

    Duda and Hart's closed form with unit directions ``a``, ``b`` and baseline
    ``t = origin_b - origin_a``: ``s_a = (a.t - (a.b)(b.t)) / (1 - (a.b)^2)``,
    ``s_b = ((a.b)(a.t) - b.t) / (1 - (a.b)^2)``. A negative range means the closest point is
    behind that ray's origin. Inputs broadcast over leading axes.

    Raises:
        RayGeometryError: if a pair of rays is parallel.
    """
    a = _unit(np.asarray(direction_a, dtype=float))
    b = _unit(np.asarray(direction_b, dtype=float))
    t = np.asarray(origin_b, dtype=float) - np.asarray(origin_a, dtype=float)
    ab = np.sum(a * b, axis=-1)
    at = np.sum(a * t, axis=-1)
    bt = np.sum(b * t, axis=-1)
    denominator = 1.0 - ab**2
    if np.any(denominator < PARALLEL_TOLERANCE):
        raise RayGeometryError("rays are parallel: no unique closest points")
    return (at - ab * bt) / denominator, (ab * at - bt) / denominator


def triangulate_midpoint(
    origin_a: ArrayLike, direction_a: ArrayLike, origin_b: ArrayLike, direction_b: ArrayLike
) -> Triangulation:
    """Midpoint of the common perpendicular of two rays (Duda and Hart).

    Args:
        origin_a, origin_b: ray origins (metres, world frame), ``(3,)`` or ``(n, 3)``.
        direction_a, direction_b: ray directions (any length), same shapes.

    Returns:
        ``Triangulation(point, gap)``; ``gap`` is the length of the common perpendicular.
    """
    oa = np.asarray(origin_a, dtype=float)
    ob = np.asarray(origin_b, dtype=float)
    a = _unit(np.asarray(direction_a, dtype=float))
    b = _unit(np.asarray(direction_b, dtype=float))
    range_a, range_b = closest_ranges(oa, a, ob, b)
    end_a = oa + range_a[..., None] * a
    end_b = ob + range_b[..., None] * b
    gap = np.linalg.norm(end_a - end_b, axis=-1)
    return Triangulation(0.5 * (end_a + end_b), gap if gap.ndim else float(gap))


def triangulate_rays(origins: ArrayLike, directions: ArrayLike) -> Triangulation:
    """Least-squares point of ``n >= 2`` rays: minimizes the sum of squared distances to the rays.

    Solves ``sum_i (I - u_i u_i^T) (p - o_i) = 0``.

    Args:
        origins: ``(n, 3)`` ray origins (metres, world frame); or ``(n, m, 3)`` for ``m`` points.
        directions: same shape, ray directions (any length).

    Returns:
        ``Triangulation(point, gap)``, ``gap`` = twice the RMS distance from the point to the rays.

    Raises:
        RayGeometryError: fewer than two rays, or all rays parallel.
    """
    o = np.asarray(origins, dtype=float)
    u = _unit(np.asarray(directions, dtype=float))
    o, u = np.broadcast_arrays(o, u)
    if o.ndim not in (2, 3) or o.shape[-1] != 3 or o.shape[0] < 2:
        raise RayGeometryError(f"need (n>=2, 3) or (n>=2, m, 3) rays, got shape {o.shape}")
    projectors = np.eye(3) - u[..., :, None] * u[..., None, :]  # (n, [m,] 3, 3)
    normal = projectors.sum(axis=0)
    rhs = np.einsum("...ij,...j->...i", projectors, o).sum(axis=0)
    eigenvalues = np.linalg.eigvalsh(normal)
    if np.any(eigenvalues[..., 0] < PARALLEL_TOLERANCE * eigenvalues[..., -1] * 1e3):
        raise RayGeometryError("rays are all parallel: the point along them is undetermined")
    point = np.linalg.solve(normal, rhs[..., None])[..., 0]
    return Triangulation(point, _gap(point, o, u))


def _gap(point: FloatArray, origins: FloatArray, units: FloatArray) -> FloatArray | float:
    offset = point[None] - origins
    perpendicular = offset - np.sum(offset * units, axis=-1, keepdims=True) * units
    gap = 2.0 * np.sqrt(np.mean(np.sum(perpendicular**2, axis=-1), axis=0))
    return gap if gap.ndim else float(gap)


def triangulate_linear(camera_matrices: Sequence[ArrayLike], pixels: Sequence[ArrayLike]):
    """Rochester guide section 11: pseudo-inverse solution of the camera-matrix equations.

    Each camera gives ``u (p3 . X) = p1 . X`` and ``v (p3 . X) = p2 . X`` for ``X = (x, y, z, 1)``,
    two equations linear in ``(x, y, z)``; the stacked system is solved by least squares. This
    minimizes an algebraic error, not a geometric one.

    Args:
        camera_matrices: ``n >= 2`` camera matrices (3x4).
        pixels: for each camera, the ideal pixel ``(2,)`` or ``(m, 2)`` pixels of ``m`` points.

    Returns:
        ``Triangulation(point, gap)`` with the gap of the rays through the pixels.
    """
    cameras = [_as_camera_matrix(P) for P in camera_matrices]
    uvs = [np.asarray(uv, dtype=float) for uv in pixels]
    _check_views(cameras, uvs)
    single = uvs[0].ndim == 1
    uvs = [uv.reshape(-1, 2) for uv in uvs]
    rows = []
    for P, uv in zip(cameras, uvs, strict=True):
        # P scaled to unit norm so each camera weighs alike regardless of its scale.
        Pn = P / np.linalg.norm(P)
        rows.append(uv[:, 0:1] * Pn[2] - Pn[0])
        rows.append(uv[:, 1:2] * Pn[2] - Pn[1])
    A = np.stack(rows, axis=1)  # (m, 2n, 4)
    coefficients, rhs = A[..., :3], -A[..., 3]
    point = np.stack(
        [np.linalg.lstsq(c, r, rcond=None)[0] for c, r in zip(coefficients, rhs, strict=True)]
    )
    gap = _gap_of_pixels(point, cameras, uvs)
    if single:
        return Triangulation(point[0], float(gap[0]))
    return Triangulation(point, gap)


def _check_views(cameras: list[FloatArray], uvs: list[FloatArray]) -> None:
    if len(cameras) < 2 or len(cameras) != len(uvs):
        raise RayGeometryError(
            f"need at least two cameras and one pixel set per camera, "
            f"got {len(cameras)} cameras and {len(uvs)} pixel sets"
        )
    shapes = {uv.shape for uv in uvs}
    if len(shapes) != 1 or next(iter(shapes))[-1] != 2:
        raise RayGeometryError(f"pixel sets must all be (2,) or (m, 2) alike, got {sorted(shapes)}")


def _gap_of_pixels(
    point: FloatArray, cameras: list[FloatArray], uvs: list[FloatArray]
) -> FloatArray:
    origins, units = [], []
    for P, uv in zip(cameras, uvs, strict=True):
        origin, direction = pixel_rays(P, uv)
        origins.append(np.broadcast_to(origin, direction.shape))
        units.append(direction)
    return np.atleast_1d(_gap(point, np.stack(origins), np.stack(units)))


def triangulate_pixels(
    camera_matrices: Sequence[ArrayLike], pixels: Sequence[ArrayLike], method: str = "midpoint"
) -> Triangulation:
    """Triangulate ideal pixels seen by two or more cameras.

    Args:
        camera_matrices: ``n >= 2`` camera matrices (3x4).
        pixels: per camera, the pixel ``(2,)`` or pixels ``(m, 2)`` of ``m`` points.
        method: ``"midpoint"`` (Duda-Hart, two cameras only), ``"least_squares"`` (perpendicular
            distances, any number of cameras) or ``"linear"`` (Rochester section 11).

    Returns:
        ``Triangulation(point, gap)``: ``(3,)`` and float, or ``(m, 3)`` and ``(m,)``.
    """
    if method == "linear":
        return triangulate_linear(camera_matrices, pixels)
    cameras = [_as_camera_matrix(P) for P in camera_matrices]
    uvs = [np.asarray(uv, dtype=float) for uv in pixels]
    _check_views(cameras, uvs)
    rays = [pixel_rays(P, uv) for P, uv in zip(cameras, uvs, strict=True)]
    if method == "midpoint":
        if len(rays) != 2:
            raise RayGeometryError(f"the midpoint method takes two cameras, got {len(rays)}")
        (oa, da), (ob, db) = rays
        return triangulate_midpoint(oa, da, ob, db)
    if method == "least_squares":
        origins = np.stack([np.broadcast_to(o, d.shape) for o, d in rays])
        return triangulate_rays(origins, np.stack([d for _, d in rays]))
    raise RayGeometryError(
        f"unknown triangulation method {method!r}; expected midpoint, least_squares or linear"
    )


def fundamental_matrix(P_a: ArrayLike, P_b: ArrayLike) -> FloatArray:
    """Fundamental matrix ``F`` with ``x_b^T F x_a = 0`` for matching ideal pixels (unit norm).

    ``F = [e_b]_x P_b P_a^+`` where ``e_b = P_b C_a`` is the epipole of camera a in image b.
    """
    Pa = _as_camera_matrix(P_a)
    Pb = _as_camera_matrix(P_b)
    centre_a = np.append(camera_centre(Pa), 1.0)
    epipole = Pb @ centre_a
    if np.linalg.norm(epipole) < 1e-12 * np.linalg.norm(Pb) * np.linalg.norm(centre_a):
        raise RayGeometryError("the two cameras share their centre: no epipolar geometry")
    F = skew(epipole) @ Pb @ np.linalg.pinv(Pa)
    return F / np.linalg.norm(F)


def epipole(P_a: ArrayLike, P_b: ArrayLike) -> FloatArray:
    """Homogeneous image of camera a's centre in image b (``(3,)``, unit norm; last entry 0 if
    the epipole is at infinity)."""
    e = _as_camera_matrix(P_b) @ np.append(camera_centre(P_a), 1.0)
    return e / np.linalg.norm(e)


def epipolar_line(P_a: ArrayLike, P_b: ArrayLike, pixels_a: ArrayLike) -> FloatArray:
    """Epipolar line in image b of ideal pixel(s) of image a.

    Args:
        P_a, P_b: camera matrices of images a and b.
        pixels_a: ``(2,)`` or ``(m, 2)`` pixels in image a.

    Returns:
        Lines ``(3,)`` or ``(m, 3)`` ``(l1, l2, l3)`` with ``l1^2 + l2^2 = 1``, so that
        ``l1 u + l2 v + l3`` is the signed distance in pixels of pixel ``(u, v)`` of image b
        from the line (see :func:`line_distance`).
    """
    F = fundamental_matrix(P_a, P_b)
    uv = np.asarray(pixels_a, dtype=float)
    homogeneous = np.concatenate([uv, np.ones((*uv.shape[:-1], 1))], axis=-1)
    lines = homogeneous @ F.T
    return lines / np.linalg.norm(lines[..., :2], axis=-1, keepdims=True)


def line_distance(lines: ArrayLike, pixels: ArrayLike) -> FloatArray:
    """Signed distance (pixels) of pixels from normalized lines ``(l1, l2, l3)``."""
    lines = np.asarray(lines, dtype=float)
    uv = np.asarray(pixels, dtype=float)
    return lines[..., 0] * uv[..., 0] + lines[..., 1] * uv[..., 1] + lines[..., 2]
