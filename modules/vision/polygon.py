"""Closed polygons in image coordinates: signed area, orientation, arc-length resampling.

A polygon is an (N, 2) float array of vertices ``(u, v)`` in pixels (u right, v down), closed
implicitly (the last vertex joins the first). The signed area follows the shoelace formula in the
``(u, v)`` axes, so a positive area means counter-clockwise in those axes, which is clockwise as
seen on screen (v points down).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


def as_polygon(points: ArrayLike) -> FloatArray:
    """``points`` as an (N, 2) float64 array; raises ValueError if the shape is wrong."""
    polygon = np.asarray(points, dtype=np.float64)
    if polygon.ndim != 2 or polygon.shape[1] != 2:
        raise ValueError(
            f"a polygon is an (N, 2) array of (u, v) pixels, got shape {polygon.shape}"
        )
    return polygon


def following(values: NDArray, k: int = 1) -> NDArray:
    """``values`` moved ``k`` places back along the first axis, cyclically: row i of the result
    is row i + k (``np.roll(values, -k, axis=0)``, without its overhead on short arrays)."""
    k %= len(values) if len(values) else 1
    return np.concatenate((values[k:], values[:k]))


def signed_area(polygon: FloatArray) -> float:
    """Shoelace signed area [px²]; positive for counter-clockwise order in (u, v) axes."""
    u = polygon[:, 0]
    v = polygon[:, 1]
    return 0.5 * float(np.dot(u, following(v)) - np.dot(following(u), v))


def with_positive_area(polygon: FloatArray) -> FloatArray:
    """The polygon in the vertex order that gives a positive signed area."""
    return polygon if signed_area(polygon) >= 0.0 else polygon[::-1].copy()


def turns(polygon: FloatArray) -> FloatArray:
    """How far the outline turns at each vertex [rad, in (-pi, pi]]: from the segment into vertex
    i to the segment out of it, positive where it turns as a convex corner of the polygon does
    (whichever its vertex order)."""
    out = following(polygon) - polygon  # segment i runs from vertex i to vertex i + 1
    into = following(out, -1)
    cross = into[:, 0] * out[:, 1] - into[:, 1] * out[:, 0]
    dot = into[:, 0] * out[:, 0] + into[:, 1] * out[:, 1]
    orientation = 1.0 if signed_area(polygon) >= 0.0 else -1.0
    return orientation * np.arctan2(cross, dot)


def segment_lengths(polygon: FloatArray) -> FloatArray:
    """Length [px] of each segment ``i -> i+1`` (the last one closes the polygon)."""
    step = following(polygon) - polygon
    return np.hypot(step[:, 0], step[:, 1])


def resample_uniform(polygon: FloatArray, count: int) -> FloatArray:
    """``count`` vertices evenly spaced by arc length along the closed polygon, from vertex 0."""
    if count < 3:
        raise ValueError(f"a closed polygon needs at least 3 vertices, asked for {count}")
    closed = np.vstack([polygon, polygon[:1]])
    arc = np.concatenate([[0.0], np.cumsum(segment_lengths(polygon))])
    if arc[-1] <= 0.0:
        return np.repeat(polygon[:1], count, axis=0)
    s = np.linspace(0.0, arc[-1], count, endpoint=False)
    return np.column_stack([np.interp(s, arc, closed[:, 0]), np.interp(s, arc, closed[:, 1])])


def circle(center_uv: ArrayLike, radius_px: float, count: int) -> FloatArray:
    """A regular ``count``-gon of radius ``radius_px`` around ``center_uv``, positive area."""
    center = np.asarray(center_uv, dtype=np.float64).reshape(2)
    angle = np.linspace(0.0, 2.0 * np.pi, count, endpoint=False)
    return center + radius_px * np.column_stack([np.cos(angle), np.sin(angle)])


def rectangle(center_uv: ArrayLike, size_px: ArrayLike, angle_rad: float = 0.0) -> FloatArray:
    """The 4 corners of a rectangle (sides ``size_px`` = [along the angle, across]), positive area.

    ``angle_rad`` is measured from the u axis towards the v axis (clockwise on screen).
    """
    center = np.asarray(center_uv, dtype=np.float64).reshape(2)
    half = 0.5 * np.asarray(size_px, dtype=np.float64).reshape(2)
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    axes = np.array([[c, s], [-s, c]])  # rows: along, across
    corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], dtype=np.float64) * half
    return center + corners @ axes


def is_convex(polygon: FloatArray) -> bool:
    """True if the turns at all vertices have the same sign (collinear vertices allowed)."""
    edges = np.roll(polygon, -1, axis=0) - polygon
    turns = (
        edges[:, 0] * np.roll(edges, -1, axis=0)[:, 1]
        - edges[:, 1] * np.roll(edges, -1, axis=0)[:, 0]
    )
    return bool(np.all(turns >= -1e-12) or np.all(turns <= 1e-12))


def inset_convex(polygon: FloatArray, distance_px: float) -> FloatArray:
    """Move every edge of a convex polygon inwards by ``distance_px`` (outwards if negative).

    Each new vertex is the intersection of its two neighbouring offset edges. Degenerate edges
    (zero length) are dropped first.
    """
    points = with_positive_area(polygon)
    keep = segment_lengths(points) > 1e-9
    points = points[keep]
    edges = np.roll(points, -1, axis=0) - points
    normals = np.column_stack([edges[:, 1], -edges[:, 0]])
    normals /= np.hypot(normals[:, 0], normals[:, 1])[:, None]  # outward for positive area
    offsets = np.einsum("ij,ij->i", normals, points) - distance_px
    n_prev, c_prev = np.roll(normals, 1, axis=0), np.roll(offsets, 1)
    det = n_prev[:, 0] * normals[:, 1] - n_prev[:, 1] * normals[:, 0]
    parallel = np.abs(det) < 1e-12
    det = np.where(parallel, 1.0, det)
    u = (c_prev * normals[:, 1] - n_prev[:, 1] * offsets) / det
    v = (n_prev[:, 0] * offsets - c_prev * normals[:, 0]) / det
    moved = np.column_stack([u, v])
    # Between two parallel edges (a collinear vertex) just shift the vertex along the normal.
    moved[parallel] = points[parallel] - distance_px * normals[parallel]
    return moved
