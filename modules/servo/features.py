"""Image-moment features of a planar patch for 4-DOF visual servoing (Tahri and Chaumette).

From a closed contour (pixels) and the camera intrinsics:

* the contour is mapped to *normalized* image coordinates ``x = (u - u0 - skew y)/fx``,
  ``y = (v - v0)/fy`` (camera frame: x right, y down, z along the optical axis);
* its moments are integrated exactly over the polygon (Green's theorem): area ``a``, centroid
  ``(x_g, y_g)`` and central moments ``mu20, mu11, mu02``;
* the features are::

      a_n   = sqrt(A / a)        normalized area; A = patch area (m^2). Chaumette's
                                 a_n = Z* sqrt(a*/a) with a* = A / Z*^2. For a patch parallel
                                 to the image plane a_n is its depth Z (m): the known patch size
                                 turns area into absolute distance.
      x_n   = a_n x_g            normalized centroid (m): the patch centre's X in the camera
      y_n   = a_n y_g            frame when the patch is parallel to the image plane
      alpha = 1/2 atan2(2 mu11, mu20 - mu02)   principal-axis angle (rad), from +x towards +y

A rectangle's principal axis has no direction: ``alpha`` is defined modulo pi (see
:func:`wrap_roll_error`). A square patch has no principal axis at all; use a rectangle.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


class FeatureError(ValueError):
    """The contour cannot give features (too few vertices, zero area, bad intrinsics)."""


@dataclass(frozen=True)
class Intrinsics:
    """Pin-hole intrinsics in pixels: focal lengths ``fx``, ``fy``, principal point, skew."""

    fx: float
    fy: float
    u0: float
    v0: float
    skew: float = 0.0

    def __post_init__(self) -> None:
        if not (self.fx > 0 and self.fy > 0):
            raise FeatureError(f"focal lengths must be positive, got fx={self.fx}, fy={self.fy}")

    def normalize(self, pixels: ArrayLike) -> FloatArray:
        """Normalized image coordinates ``(x, y)`` of pixels ``(u, v)`` (shape ``(..., 2)``)."""
        uv = np.asarray(pixels, dtype=float)
        y = (uv[..., 1] - self.v0) / self.fy
        x = (uv[..., 0] - self.u0 - self.skew * y) / self.fx
        return np.stack([x, y], axis=-1)

    def pixel(self, normalized: ArrayLike) -> FloatArray:
        """Pixels ``(u, v)`` of normalized coordinates ``(x, y)``."""
        xy = np.asarray(normalized, dtype=float)
        u = self.fx * xy[..., 0] + self.skew * xy[..., 1] + self.u0
        v = self.fy * xy[..., 1] + self.v0
        return np.stack([u, v], axis=-1)


@dataclass(frozen=True)
class PolygonMoments:
    """Area, centroid and central second moments (per unit area) of a polygon."""

    area: float
    centroid: FloatArray
    mu20: float
    mu11: float
    mu02: float

    @property
    def orientation(self) -> float:
        """Principal-axis angle (rad) in (-pi/2, pi/2], from +x towards +y."""
        return float(0.5 * np.arctan2(2.0 * self.mu11, self.mu20 - self.mu02))


def polygon_moments(vertices: ArrayLike) -> PolygonMoments:
    """Exact moments of the region inside a simple closed polygon (either winding).

    Args:
        vertices: ``(n, 2)`` polygon vertices, n >= 3, the last joined to the first.

    Returns:
        :class:`PolygonMoments`; ``mu`` are central moments divided by the area.
    """
    p = np.asarray(vertices, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2 or p.shape[0] < 3:
        raise FeatureError(f"a contour needs at least 3 vertices as (n, 2), got {p.shape}")
    # Shift to the mean vertex first for numerical accuracy on pixel coordinates.
    origin = p.mean(axis=0)
    x, y = (p - origin).T
    x1, y1 = np.roll(x, -1), np.roll(y, -1)
    cross = x * y1 - x1 * y
    m00 = cross.sum() / 2.0
    extent = float(np.ptp(x) * np.ptp(y))
    if not np.isfinite(m00) or abs(m00) <= 1e-12 * extent:
        raise FeatureError("the contour encloses no area")
    m10 = ((x + x1) * cross).sum() / 6.0
    m01 = ((y + y1) * cross).sum() / 6.0
    m20 = ((x * x + x * x1 + x1 * x1) * cross).sum() / 12.0
    m02 = ((y * y + y * y1 + y1 * y1) * cross).sum() / 12.0
    m11 = ((x * y1 + 2 * x * y + 2 * x1 * y1 + x1 * y) * cross).sum() / 24.0
    xg, yg = m10 / m00, m01 / m00
    return PolygonMoments(
        area=float(abs(m00)),
        centroid=np.array([xg, yg]) + origin,
        mu20=float(m20 / m00 - xg * xg),
        mu11=float(m11 / m00 - xg * yg),
        mu02=float(m02 / m00 - yg * yg),
    )


@dataclass(frozen=True)
class MomentFeatures:
    """The 4 servo features ``s = (x_n, y_n, a_n, alpha)`` (m, m, m, rad)."""

    x_n: float
    y_n: float
    a_n: float
    alpha: float

    def as_array(self) -> FloatArray:
        """``[x_n, y_n, a_n, alpha]``."""
        return np.array([self.x_n, self.y_n, self.a_n, self.alpha])


def features_from_normalized(
    area: float, centroid: ArrayLike, alpha: float, patch_area_m2: float
) -> MomentFeatures:
    """Features from normalized-image area, centroid and principal-axis angle."""
    if not area > 0:
        raise FeatureError(f"contour area must be positive, got {area}")
    if not patch_area_m2 > 0:
        raise FeatureError(f"patch area must be positive, got {patch_area_m2} m^2")
    a_n = float(np.sqrt(patch_area_m2 / area))
    xg, yg = np.asarray(centroid, dtype=float)
    return MomentFeatures(x_n=a_n * float(xg), y_n=a_n * float(yg), a_n=a_n, alpha=float(alpha))


def features_from_normalized_contour(
    vertices_normalized: ArrayLike, patch_area_m2: float
) -> MomentFeatures:
    """Servo features of a contour already in normalized image coordinates (undistorted)."""
    moments = polygon_moments(vertices_normalized)
    return features_from_normalized(
        moments.area, moments.centroid, moments.orientation, patch_area_m2
    )


def features_from_contour(
    vertices_px: ArrayLike, intrinsics: Intrinsics, patch_area_m2: float
) -> MomentFeatures:
    """Servo features of a contour given in (ideal, undistorted) pixels; see module docstring."""
    return features_from_normalized_contour(intrinsics.normalize(vertices_px), patch_area_m2)


def wrap_roll_error(angle: float) -> float:
    """Wrap a principal-axis angle difference into (-pi/2, pi/2] (the axis has no direction)."""
    wrapped = float(np.mod(angle + np.pi / 2, np.pi) - np.pi / 2)
    return np.pi / 2 if wrapped == -np.pi / 2 else wrapped
