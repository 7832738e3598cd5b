"""Exact area moments of a closed polygon (Green's theorem, the shoelace sums).

A polygon is an ``(n, 2)`` array of vertices ``(x, y)``, n >= 3, the last joined to the first,
in any 2-D coordinates: pixels ``(u, v)`` (u right, v down) for the tracker and the overlay,
normalized image coordinates for the servo. Results are in those coordinates' units: area
[unit²], centroid [unit], central second moments per unit area [unit²]. Either winding gives the
same moments; the orientation is the principal (major) axis's angle from +x towards +y [rad], in
(-pi/2, pi/2]. An axis has no direction: angles between axes are taken modulo pi
(:func:`wrap_axis_angle`).

The sums are taken about the first vertex, so that polygons far from the origin (pixel
coordinates) keep their digits; they agree with ``cv2.moments`` (tests/geometry).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


class DegeneratePolygonError(ValueError):
    """The polygon has no moments: fewer than 3 vertices, or (numerically) zero area."""


@dataclass(frozen=True)
class PolygonMoments:
    """Area, centroid and central second moments (per unit area) of a polygon.

    ``area`` [unit²] is unsigned; ``signed_area`` is positive for counter-clockwise order in the
    ``(x, y)`` axes (clockwise on screen when y points down); ``centroid`` [unit]; ``mu20``,
    ``mu11``, ``mu02`` [unit²] the central second moments divided by the area.
    """

    area: float
    signed_area: float
    centroid: FloatArray
    mu20: float
    mu11: float
    mu02: float

    @property
    def orientation(self) -> float:
        """Principal-axis angle [rad] in (-pi/2, pi/2], from +x towards +y."""
        angle = float(0.5 * np.arctan2(2.0 * self.mu11, self.mu20 - self.mu02))
        return angle + np.pi if angle <= -np.pi / 2 else angle


def polygon_moments(vertices: ArrayLike) -> PolygonMoments:
    """Exact moments of the region inside a simple closed polygon (either winding).

    Args:
        vertices: ``(n, 2)`` polygon vertices, n >= 3, the last joined to the first.

    Raises:
        DegeneratePolygonError: fewer than 3 vertices, not ``(n, 2)``, or an area not above
            ``1e-12`` of the vertices' bounding box (collinear or repeated vertices).
    """
    p = np.asarray(vertices, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2 or p.shape[0] < 3:
        raise DegeneratePolygonError(
            f"a polygon needs at least 3 vertices as (n, 2), got shape {p.shape}"
        )
    origin = p[0]
    x, y = (p - origin).T
    x1, y1 = np.concatenate((x[1:], x[:1])), np.concatenate((y[1:], y[:1]))
    cross = x * y1 - x1 * y
    m00 = cross.sum() / 2.0
    extent = float((x.max() - x.min()) * (y.max() - y.min()))
    if not np.isfinite(m00) or abs(m00) <= 1e-12 * extent:
        raise DegeneratePolygonError("the polygon has zero area: its moments are undefined")
    m10 = ((x + x1) * cross).sum() / 6.0
    m01 = ((y + y1) * cross).sum() / 6.0
    m20 = ((x * x + x * x1 + x1 * x1) * cross).sum() / 12.0
    m02 = ((y * y + y * y1 + y1 * y1) * cross).sum() / 12.0
    m11 = ((x * y1 + 2 * x * y + 2 * x1 * y1 + x1 * y) * cross).sum() / 24.0
    xg, yg = m10 / m00, m01 / m00
    return PolygonMoments(
        area=float(abs(m00)),
        signed_area=float(m00),
        centroid=np.array([xg, yg]) + origin,
        mu20=float(m20 / m00 - xg * xg),
        mu11=float(m11 / m00 - xg * yg),
        mu02=float(m02 / m00 - yg * yg),
    )


def wrap_axis_angle(angle: float) -> float:
    """An angle between two axes [rad] (defined modulo pi: an axis has no direction) wrapped into
    (-pi/2, pi/2]."""
    wrapped = float(np.mod(angle + np.pi / 2, np.pi) - np.pi / 2)
    return np.pi / 2 if wrapped == -np.pi / 2 else wrapped
