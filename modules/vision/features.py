"""Features of a closed polygon from its exact area moments
(:mod:`umbra.modules.geometry.polygon_moments`).

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

from umbra.modules.geometry.polygon_moments import polygon_moments

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


def polygon_features(points: ArrayLike) -> PolygonFeatures:
    """Centroid, area, orientation and axis lengths of the region inside a closed polygon
    (its moments: :func:`umbra.modules.geometry.polygon_moments.polygon_moments`).

    Raises ValueError (:class:`~umbra.modules.geometry.polygon_moments.DegeneratePolygonError`)
    for a polygon of fewer than 3 vertices or (nearly) zero area.
    """
    moments = polygon_moments(points)
    mu20, mu11, mu02 = moments.mu20, moments.mu11, moments.mu02
    half_trace = 0.5 * (mu20 + mu02)
    spread = float(np.hypot(0.5 * (mu20 - mu02), mu11))
    lam_major = max(half_trace + spread, 0.0)
    lam_minor = max(half_trace - spread, 0.0)
    cu, cv = (float(c) for c in moments.centroid)
    return PolygonFeatures(
        centroid_uv=(cu, cv),
        area_px2=moments.area,
        orientation_rad=moments.orientation,
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
