"""Exact pixel coverage of a convex polygon, for the renderer's ground truth.

A pixel is the unit square around its centre (integer coordinates, OpenCV's convention). The
share of it on the inner side of one straight edge ``n . x <= c`` (``n`` a unit normal) depends
only on the signed distance ``d = n . p - c`` of its centre ``p`` and on the edge's direction:
``n . (x - p)`` over the square is the sum of two uniform variables of widths ``a = |n_u|`` and
``b = |n_v|``, whose distribution is a trapezoid, so the covered share is its cumulative
distribution at ``-d`` -- a quadratic ramp, a linear part, a quadratic ramp. Exact for a pixel
crossed by one edge; at a corner the product of the edges' shares stands in for the exact
intersection (a few pixels per corner, hundredths of a pixel of area). Lengths in pixels.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from umbra.modules.vision.polygon import following, with_positive_area

FloatArray = NDArray[np.float64]


def half_plane_share(distance: NDArray, a: float, b: float) -> NDArray:
    """Share of unit pixels whose centres lie ``distance`` [px] outside an edge (negative:
    inside) that is on the inner side, for an edge normal with ``a = |n_u|``, ``b = |n_v|``."""
    a, b = max(a, b), min(a, b)
    t = -np.asarray(distance, dtype=np.float64)
    low, mid = 0.5 * (a + b), 0.5 * (a - b)
    linear = np.clip((t + 0.5 * a) / a, 0.0, 1.0)
    if b < 1e-9:
        return linear
    ramp_in = np.square(np.clip(t + low, 0.0, b)) / (2.0 * a * b)
    ramp_out = 1.0 - np.square(np.clip(low - t, 0.0, b)) / (2.0 * a * b)
    return np.where(t <= -mid, ramp_in, np.where(t >= mid, ramp_out, linear))


def convex_coverage(polygon_px: FloatArray, origin: tuple[int, int], shape: tuple[int, int]):
    """Coverage (``shape`` = rows x cols float32 in [0, 1]) of the pixels ``origin`` = (u0, v0)
    onwards by the convex polygon (N x 2 px, either orientation)."""
    points = with_positive_area(np.asarray(polygon_px, dtype=np.float64))
    edges = following(points) - points
    lengths = np.hypot(edges[:, 0], edges[:, 1])
    keep = lengths > 1e-9
    points, edges, lengths = points[keep], edges[keep], lengths[keep]
    rows, cols = shape
    u = np.arange(cols, dtype=np.float64) + origin[0]
    v = np.arange(rows, dtype=np.float64) + origin[1]
    coverage = np.ones(shape, dtype=np.float64)
    for point, edge, length in zip(points, edges, lengths, strict=True):
        normal = np.array([edge[1], -edge[0]]) / length  # outward for a positive area
        offset = float(normal @ point)
        distance = (normal[0] * u)[None, :] + (normal[1] * v)[:, None] - offset
        coverage *= half_plane_share(distance, abs(normal[0]), abs(normal[1]))
    return coverage.astype(np.float32)
