"""Image-moment features of a planar patch for 4-DOF visual servoing (Tahri and Chaumette).

From a closed contour (pixels) and the camera intrinsics:

* the contour is mapped to *normalized* image coordinates ``x = (u - u0 - skew y)/fx``,
  ``y = (v - v0)/fy`` (camera frame: x right, y down, z along the optical axis);
* its moments are integrated exactly over the polygon (Green's theorem,
  :func:`umbra.modules.geometry.polygon_moments.polygon_moments`): area ``a``, centroid
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
:func:`umbra.modules.geometry.polygon_moments.wrap_axis_angle`). A square patch has no principal
axis at all; use a rectangle.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.modules.calib.camera_model import Intrinsics
from umbra.modules.geometry.polygon_moments import DegeneratePolygonError, polygon_moments

FloatArray = NDArray[np.float64]


class FeatureError(ValueError):
    """The contour cannot give features (too few vertices, zero area, bad intrinsics)."""


def checked_intrinsics(intrinsics: Intrinsics) -> Intrinsics:
    """``intrinsics`` [px] when its focal lengths are positive (the features divide by them);
    :class:`FeatureError` otherwise."""
    if not (intrinsics.fx > 0 and intrinsics.fy > 0):
        raise FeatureError(
            f"focal lengths must be positive, got fx={intrinsics.fx}, fy={intrinsics.fy}"
        )
    return intrinsics


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
    try:
        moments = polygon_moments(vertices_normalized)
    except DegeneratePolygonError as exc:
        raise FeatureError(str(exc)) from None
    return features_from_normalized(
        moments.area, moments.centroid, moments.orientation, patch_area_m2
    )


def features_from_contour(
    vertices_px: ArrayLike, intrinsics: Intrinsics, patch_area_m2: float
) -> MomentFeatures:
    """Servo features of a contour given in (ideal, undistorted) pixels; see module docstring."""
    normalized = checked_intrinsics(intrinsics).normalized_from_pixels(vertices_px)
    return features_from_normalized_contour(normalized, patch_area_m2)
