"""Rochester camera model and the guide's two stereo methods (sections 4, 11, 12, 13.2).

Imaging model (section 4): a point ``(X, Y, Z)`` in a camera's CamPos frame (Z along the optic
axis, Y down, X right) appears at centred pixel coordinates ``x = f X / Z``, ``y = f s Y / Z``,
where ``f`` is the effective focal length in pixels and ``s`` the aspect ratio (row spacing
per column spacing, "y/x"). PhysPixel shifts the origin to the upper-left corner of the
512x512 image: ``x_pix = x + 255``, ``y_pix = y + 255`` (section 11).

Stereo:

* :func:`stereo_pseudo_inverse` — section 11: each camera gives two equations linear in the
  point, ``x (T2 . X) = f (T0 . X)`` and ``y (T2 . X) = f s (T1 . X)`` with ``T`` the inverse of
  the camera's pose; the four equations in three unknowns are solved by ``(X^T X)^-1 X^T Y``.
* :func:`stereo_duda_hart` — section 12: unit rays ``u = (x, y/s, f)/|.|`` from each lens
  centre, baseline ``b = CamPosL^-1 CamPosR (0,0,0,1)``, the right ray rotated into the left
  camera frame, and the midpoint of the closest points of the two rays. The closed form is
  :func:`umbra.modules.geometry.rays.triangulate_midpoint` (the generic implementation); this file
  only builds the Rochester rays.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.modules.geometry.rays import Triangulation, triangulate_midpoint
from umbra.modules.geometry.transforms import invert_transform

FloatArray = NDArray[np.float64]

#: Measured pixels per degree near the image centre at the 134 cm focus distance (section 13.2).
CAM_X_PIXELS_PER_DEGREE = 17.75
CAM_Y_PIXELS_PER_DEGREE = 22.79


@dataclass(frozen=True)
class RochesterCamera:
    """Intrinsics of the section 4 model; defaults are the section 13.2 constants.

    ``focal_px`` is the effective focal length (pixels), ``aspect`` the y/x pixel aspect ratio
    ``s``, ``centre_px`` the PhysPixel offset (pixel coordinates of the optic axis).
    """

    focal_px: float = 980.5
    aspect: float = 1.289
    centre_px: tuple[float, float] = (255.0, 255.0)

    def pixel_from_point(self, point_camera: ArrayLike) -> FloatArray:
        """Pixel ``(x_pix, y_pix)`` of points ``(3,)`` or ``(n, 3)`` in CamPos (metres)."""
        p = np.asarray(point_camera, dtype=float)
        z = p[..., 2]
        if np.any(z <= 0):
            raise ValueError("a point at or behind the camera plane has no image")
        x = self.focal_px * p[..., 0] / z + self.centre_px[0]
        y = self.focal_px * self.aspect * p[..., 1] / z + self.centre_px[1]
        return np.stack([x, y], axis=-1)

    def ray_from_pixel(self, pixel: ArrayLike) -> FloatArray:
        """Unit direction ``(x, y/s, f)/|.|`` in CamPos of pixel ``(x_pix, y_pix)`` (sec. 12)."""
        uv = np.asarray(pixel, dtype=float)
        x = uv[..., 0] - self.centre_px[0]
        y = uv[..., 1] - self.centre_px[1]
        d = np.stack([x, y / self.aspect, np.full_like(x, self.focal_px)], axis=-1)
        return d / np.linalg.norm(d, axis=-1, keepdims=True)

    def pixels_per_degree(self) -> tuple[float, float]:
        """Pixels per degree at the image centre implied by the model: ``f pi/180``, ``f s pi/180``.

        The slope of ``x = f tan(angle)`` at zero; farther out a degree spans more pixels.
        """
        per_radian_to_per_degree = np.pi / 180.0
        return (
            self.focal_px * per_radian_to_per_degree,
            self.focal_px * self.aspect * per_radian_to_per_degree,
        )


ROCHESTER_CAMERA = RochesterCamera()


def stereo_pseudo_inverse(
    pixels: tuple[ArrayLike, ArrayLike],
    T_world_cameras: tuple[ArrayLike, ArrayLike],
    cameras: tuple[RochesterCamera, RochesterCamera] = (ROCHESTER_CAMERA, ROCHESTER_CAMERA),
) -> FloatArray:
    """Point (metres, world frame) from two pixels by the section 11 pseudo-inverse.

    Args:
        pixels: ``(x_pix, y_pix)`` of the point in each image.
        T_world_cameras: pose of each camera's CamPos in the world frame (LAB or FLANGE); the
            guide's ``T`` is its inverse.
        cameras: intrinsics of each camera.

    Returns:
        ``(3,)`` point in the world frame: ``B = (X^T X)^-1 X^T Y`` over the 4x3 system.
    """
    rows, rhs = [], []
    for pixel, T_world_camera, camera in zip(pixels, T_world_cameras, cameras, strict=True):
        T = invert_transform(T_world_camera)
        px = np.asarray(pixel, dtype=np.float64)
        x = float(px[0]) - camera.centre_px[0]
        y = float(px[1]) - camera.centre_px[1]
        f, fs = camera.focal_px, camera.focal_px * camera.aspect
        rows.append(x * T[2, :3] - f * T[0, :3])
        rhs.append(f * T[0, 3] - x * T[2, 3])
        rows.append(y * T[2, :3] - fs * T[1, :3])
        rhs.append(fs * T[1, 3] - y * T[2, 3])
    X = np.array(rows)
    Y = np.array(rhs)
    # (X^T X)^-1 X^T Y, solved without forming the inverse.
    return np.linalg.solve(X.T @ X, X.T @ Y)


def stereo_duda_hart(
    pixels: tuple[ArrayLike, ArrayLike],
    T_flange_campos: tuple[ArrayLike, ArrayLike],
    cameras: tuple[RochesterCamera, RochesterCamera] = (ROCHESTER_CAMERA, ROCHESTER_CAMERA),
) -> Triangulation:
    """Point (metres, FLANGE) from two pixels by Duda and Hart's two-ray method (section 12).

    The rays are built in the left camera's frame as the guide does (left lens centre at the
    origin, baseline ``b = CamPosL^-1 CamPosR (0,0,0,1)``, right ray rotated by
    ``CamPosL^-1 CamPosR``), triangulated, and the point is returned in FLANGE.

    Args:
        pixels: ``(x_pix, y_pix)`` in the left and the right image.
        T_flange_campos: CamPosL and CamPosR (4x4, metres) in FLANGE; any common frame works.
        cameras: intrinsics of the left and the right camera.

    Returns:
        ``Triangulation(point, gap)``: point in FLANGE, gap = distance between the rays (m).
    """
    T_flange_left = np.asarray(T_flange_campos[0], dtype=float)
    T_left_right = invert_transform(T_flange_left) @ np.asarray(T_flange_campos[1], dtype=float)
    u_left = cameras[0].ray_from_pixel(pixels[0])
    u_right = T_left_right[:3, :3] @ cameras[1].ray_from_pixel(pixels[1])
    baseline = T_left_right[:3, 3]
    in_left = triangulate_midpoint(np.zeros(3), u_left, baseline, u_right)
    point = T_flange_left[:3, :3] @ in_left.point + T_flange_left[:3, 3]
    return Triangulation(point, in_left.gap)
