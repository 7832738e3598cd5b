"""Sketch primitives: point, line, plane (two connected lines), triad (three lines, one vertex).

A primitive is placed by its vertices in both images of a snapshot. Each right-hand vertex is
moved onto the epipolar line of its left-hand mate (the report's constraint), then each vertex
pair is triangulated with its covariance (:mod:`modules.sketch.stereo`). The result is a
:class:`connectors.sketch_messages.SketchPrimitive`; the helpers below read its geometry
(a line's axis, a plane's rectangle, a triad's box) in metres in the base frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from connectors.sketch_messages import SketchBox, SketchPrimitive
from modules.sketch.stereo import StereoNoise, StereoPair

FloatArray = NDArray[np.float64]

#: vertices and edges of each kind (vertex index pairs)
KINDS: dict[str, tuple[int, tuple[tuple[int, int], ...]]] = {
    "point": (1, ()),
    "line": (2, ((0, 1),)),
    "plane": (3, ((0, 1), (1, 2))),
    "triad": (4, ((0, 1), (0, 2), (0, 3))),
}


class PrimitiveError(ValueError):
    """A primitive that cannot be built or read as asked (wrong vertex count, degenerate)."""


def vertex_count(kind: str) -> int:
    """How many vertices a primitive of ``kind`` has."""
    try:
        return KINDS[kind][0]
    except KeyError:
        raise PrimitiveError(
            f"unknown primitive kind {kind!r}; expected one of {list(KINDS)}"
        ) from None


def place_primitive(
    pair: StereoPair,
    kind: str,
    pixels_a: ArrayLike,
    pixels_b: ArrayLike,
    noise: StereoNoise,
    *,
    primitive_id: str,
    snapshot_id: str = "",
    stamp: float = 0.0,
    frame: str = "base",
) -> SketchPrimitive:
    """Constrain the right-hand vertices to their epipolar lines and triangulate every vertex.

    Args:
        pair: the snapshot's stereo pair.
        kind: "point", "line", "plane" or "triad".
        pixels_a, pixels_b: (N, 2) image pixels of the vertices in images a and b.
        noise: pixel and calibration sigmas for the covariances.
    """
    n = vertex_count(kind)
    uv_a = np.asarray(pixels_a, dtype=float).reshape(-1, 2)
    uv_b = np.asarray(pixels_b, dtype=float).reshape(-1, 2)
    if uv_a.shape != (n, 2) or uv_b.shape != (n, 2):
        raise PrimitiveError(
            f"a {kind} has {n} vertices; got {uv_a.shape[0]} in image a and {uv_b.shape[0]} in b"
        )
    if not (np.all(np.isfinite(uv_a)) and np.all(np.isfinite(uv_b))):
        raise PrimitiveError(f"vertex pixels must be finite, got {uv_a.tolist()} {uv_b.tolist()}")
    uv_b = pair.constrain_b(uv_a, uv_b).reshape(n, 2)
    points, covariances, gaps = [], [], []
    for i in range(n):
        point, cov, gap = pair.triangulate_with_covariance(uv_a[i], uv_b[i], noise)
        points.append(point)
        covariances.append(cov)
        gaps.append(gap)
    return SketchPrimitive(
        stamp=stamp,
        primitive_id=primitive_id,
        kind=kind,
        snapshot_id=snapshot_id,
        pixels_a=uv_a,
        pixels_b=uv_b,
        points=np.stack(points),
        covariances=np.stack(covariances),
        gaps=np.asarray(gaps),
        edges=np.asarray(KINDS[kind][1], dtype=np.int64).reshape(-1, 2),
        frame=frame,
    )


def point_of(primitive: SketchPrimitive) -> FloatArray:
    """The 3-D point (m, base) of a point primitive."""
    _expect(primitive, "point")
    return np.asarray(primitive.points[0], dtype=float)


@dataclass(frozen=True)
class LineAxis:
    """A line primitive read as an axis: ``start``, ``end`` (m, base), ``middle``, unit
    ``direction`` (start to end) and ``length`` (m)."""

    start: FloatArray
    end: FloatArray

    @property
    def middle(self) -> FloatArray:
        return 0.5 * (self.start + self.end)

    @property
    def length(self) -> float:
        return float(np.linalg.norm(self.end - self.start))

    @property
    def direction(self) -> FloatArray:
        return (self.end - self.start) / self.length


def line_axis(primitive: SketchPrimitive) -> LineAxis:
    """The axis of a line primitive (vertex 0 to vertex 1)."""
    _expect(primitive, "line")
    axis = LineAxis(np.asarray(primitive.points[0]), np.asarray(primitive.points[1]))
    if axis.length < 1e-3:
        raise PrimitiveError(f"line {primitive.primitive_id} is {axis.length * 1e3:.2f} mm long")
    return axis


@dataclass(frozen=True)
class PlaneRect:
    """A plane primitive read as a parallelogram: ``corner`` (the shared vertex b, m, base) and
    edge vectors ``edge_u`` (b to a) and ``edge_v`` (b to c); ``normal`` is their unit cross
    product."""

    corner: FloatArray
    edge_u: FloatArray
    edge_v: FloatArray

    @property
    def normal(self) -> FloatArray:
        n = np.cross(self.edge_u, self.edge_v)
        return n / np.linalg.norm(n)

    def perimeter(self) -> FloatArray:
        """The four corners in order (4, 3), starting at ``corner``."""
        c = self.corner
        return np.stack([c, c + self.edge_u, c + self.edge_u + self.edge_v, c + self.edge_v])


def plane_rect(primitive: SketchPrimitive) -> PlaneRect:
    """The parallelogram of a plane primitive (vertices a, b, c; b shared by both lines)."""
    _expect(primitive, "plane")
    a, b, c = (np.asarray(p) for p in primitive.points)
    rect = PlaneRect(b, a - b, c - b)
    if np.linalg.norm(np.cross(rect.edge_u, rect.edge_v)) < 1e-6:
        raise PrimitiveError(f"plane {primitive.primitive_id}: its two lines are parallel")
    return rect


def triad_box(primitive: SketchPrimitive, box_id: str = "") -> SketchBox:
    """The box spanned by a triad's three edges from the common vertex (axes orthogonalized by
    the closest rotation; size = edge lengths)."""
    _expect(primitive, "triad")
    origin = np.asarray(primitive.points[0])
    edges = np.asarray(primitive.points[1:4]) - origin
    size = np.linalg.norm(edges, axis=1)
    if np.any(size < 1e-3):
        raise PrimitiveError(f"triad {primitive.primitive_id}: an edge is shorter than 1 mm")
    U, _, Vt = np.linalg.svd((edges / size[:, None]).T)
    R = U @ Vt
    if np.linalg.det(R) < 0:
        R[:, 2] *= -1.0
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = origin + 0.5 * (R @ size)
    return SketchBox(
        stamp=primitive.stamp,
        box_id=box_id or primitive.primitive_id,
        T_base_box=T,
        size=size,
        covariance=np.asarray(primitive.covariances[0]),
        frame=primitive.frame,
    )


def _expect(primitive: SketchPrimitive, kind: str) -> None:
    if primitive.kind != kind:
        raise PrimitiveError(f"expected a {kind} primitive, got a {primitive.kind}")
