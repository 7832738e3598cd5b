"""Features of a closed polygon from its exact area moments (shoelace / Green's theorem).

Image frame: u right, v down, pixels. The orientation is the angle of the principal (major)
axis measured from the +u axis towards +v (so clockwise as seen on screen), in radians within
(-pi/2, pi/2]. The axis lengths are those of the ellipse with the same second moments (full
lengths, 4 sqrt(eigenvalue) of the normalized central second-moment matrix), the same
convention as scikit-image's ``major_axis_length``; for a filled ellipse they are its axes.
The rectangle with the same second moments has sides ``sqrt(12 eigenvalue)``
(:func:`equivalent_rectangle_sides`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.modules.vision.polygon import as_polygon, following

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class PolygonFeatures:
    """Moment features of a polygon region.

    ``centroid_uv`` [px]; ``area_px2`` [px²] (unsigned); ``orientation_rad`` principal-axis angle
    [rad]; ``major_axis_px`` ≥ ``minor_axis_px`` [px]; ``second_moments`` the normalized central
    moments (mu20, mu11, mu02) [px²].
    """

    centroid_uv: tuple[float, float]
    area_px2: float
    orientation_rad: float
    major_axis_px: float
    minor_axis_px: float
    second_moments: tuple[float, float, float]

    @property
    def aspect_ratio(self) -> float:
        """Major over minor axis length (inf for a degenerate polygon)."""
        return self.major_axis_px / self.minor_axis_px if self.minor_axis_px > 0 else np.inf


def raw_moments(points: ArrayLike) -> tuple[float, float, float, float, float, float]:
    """Signed area moments (m00, m10, m01, m20, m11, m02) of a closed polygon [px^k]."""
    polygon = as_polygon(points)
    x0, y0 = polygon[:, 0], polygon[:, 1]
    x1, y1 = following(x0), following(y0)
    cross = x0 * y1 - x1 * y0
    m00 = cross.sum() / 2.0
    m10 = (cross * (x0 + x1)).sum() / 6.0
    m01 = (cross * (y0 + y1)).sum() / 6.0
    m20 = (cross * (x0 * x0 + x0 * x1 + x1 * x1)).sum() / 12.0
    m02 = (cross * (y0 * y0 + y0 * y1 + y1 * y1)).sum() / 12.0
    m11 = (cross * (2.0 * x0 * y0 + x0 * y1 + x1 * y0 + 2.0 * x1 * y1)).sum() / 24.0
    return float(m00), float(m10), float(m01), float(m20), float(m11), float(m02)


def polygon_features(points: ArrayLike) -> PolygonFeatures:
    """Centroid, area, orientation and axis lengths of the region inside a closed polygon.

    Raises ValueError for a polygon with (nearly) zero area.
    """
    m00, m10, m01, m20, m11, m02 = raw_moments(points)
    if abs(m00) < 1e-9:
        raise ValueError("polygon has zero area; its features are undefined")
    cu, cv = m10 / m00, m01 / m00
    mu20 = m20 / m00 - cu * cu
    mu11 = m11 / m00 - cu * cv
    mu02 = m02 / m00 - cv * cv
    half_trace = 0.5 * (mu20 + mu02)
    spread = float(np.hypot(0.5 * (mu20 - mu02), mu11))
    lam_major = max(half_trace + spread, 0.0)
    lam_minor = max(half_trace - spread, 0.0)
    orientation = 0.5 * float(np.arctan2(2.0 * mu11, mu20 - mu02))
    if orientation <= -np.pi / 2:
        orientation += np.pi
    return PolygonFeatures(
        centroid_uv=(cu, cv),
        area_px2=abs(m00),
        orientation_rad=orientation,
        major_axis_px=4.0 * float(np.sqrt(lam_major)),
        minor_axis_px=4.0 * float(np.sqrt(lam_minor)),
        second_moments=(mu20, mu11, mu02),
    )


def equivalent_rectangle_sides(features: PolygonFeatures) -> tuple[float, float]:
    """Sides [px] (along the major axis, along the minor axis) of the rectangle with the same
    second moments: a solid rectangle of side L has variance L²/12 along it, and the axis
    length is 4 sqrt(variance), so L = axis * sqrt(12) / 4."""
    scale = np.sqrt(12.0) / 4.0
    return features.major_axis_px * scale, features.minor_axis_px * scale


def angle_difference(a_rad: float, b_rad: float) -> float:
    """Smallest difference [rad] between two axis orientations (defined modulo pi), in [0, pi/2]."""
    d = (a_rad - b_rad) % np.pi
    return float(min(d, np.pi - d))
