"""Sketch primitives: point, line, plane (two connected lines), triad (three lines, one vertex).

A primitive is placed by its vertices in both images of a snapshot. Each right-hand vertex is
moved onto the epipolar line of its left-hand mate (the report's constraint), then each vertex
pair is triangulated with its covariance (:mod:`umbra.modules.sketch.stereo`; a vertex on a
featureless edge carries the operator's handle error along it,
:mod:`umbra.modules.sketch.depth_check`). The result is a
:class:`umbra.connectors.sketch_messages.SketchPrimitive`; the helpers below read its geometry
(a line's axis, a plane's rectangle, a triad's box) in metres in the base frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.connectors.sketch_messages import PrimitiveKind, SketchBox, SketchPrimitive
from umbra.modules.sketch.depth_check import handle_spread
from umbra.modules.sketch.stereo import StereoNoise, StereoPair

FloatArray = NDArray[np.float64]

#: vertices and edges of each kind (vertex index pairs)
KINDS: dict[PrimitiveKind, tuple[int, tuple[tuple[int, int], ...]]] = {
    PrimitiveKind.POINT: (1, ()),
    PrimitiveKind.LINE: (2, ((0, 1),)),
    PrimitiveKind.PLANE: (3, ((0, 1), (1, 2))),
    PrimitiveKind.TRIAD: (4, ((0, 1), (0, 2), (0, 3))),
}


class PrimitiveError(ValueError):
    """A primitive that cannot be built or read as asked (wrong vertex count, degenerate)."""


def primitive_kind(kind: str) -> PrimitiveKind:
    """``kind`` as written (a command, a file), typed; PrimitiveError unless it is one."""
    return PrimitiveKind.named(kind, "unknown primitive kind", PrimitiveError)


def vertex_count(kind: str) -> int:
    """How many vertices a primitive of ``kind`` has."""
    return KINDS[primitive_kind(kind)][0]


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
        kind: a :class:`PrimitiveKind` ("point", "line", "plane" or "triad").
        pixels_a, pixels_b: (N, 2) image pixels of the vertices in images a and b.
        noise: pixel, handle and calibration sigmas for the covariances.
    """
    kind = primitive_kind(kind)
    n = vertex_count(kind)
    uv_a = np.asarray(pixels_a, dtype=float).reshape(-1, 2)
    uv_b = np.asarray(pixels_b, dtype=float).reshape(-1, 2)
    if uv_a.shape != (n, 2) or uv_b.shape != (n, 2):
        raise PrimitiveError(
            f"a {kind} has {n} vertices; got {uv_a.shape[0]} in image a and {uv_b.shape[0]} in b"
        )
    if not (np.all(np.isfinite(uv_a)) and np.all(np.isfinite(uv_b))):
        raise PrimitiveError(f"vertex pixels must be finite, got {uv_a.tolist()} {uv_b.tolist()}")
    # the clicks in b on their epipolar lines (the derivative of that projection is the same
    # at the click and on the line: the covariance is the clicks' either way)
    uv_b = pair.constrain_b(uv_a, uv_b).reshape(n, 2)
    edges = np.asarray(KINDS[kind][1], dtype=np.int64).reshape(-1, 2)
    spread = handle_spread(uv_b, edges, noise)
    points, joint, gaps = pair.triangulate_constrained(uv_a, uv_b, noise, spread)
    covariances = [joint[3 * i : 3 * i + 3, 3 * i : 3 * i + 3] for i in range(n)]
    return SketchPrimitive(
        stamp=stamp,
        primitive_id=primitive_id,
        kind=kind,
        snapshot_id=snapshot_id,
        pixels_a=uv_a,
        pixels_b=uv_b,
        points=points,
        covariances=np.stack(covariances),
        gaps=np.asarray(gaps),
        edges=edges,
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


def _box_frame(points: FloatArray, primitive_id: str) -> tuple[FloatArray, FloatArray]:
    """``(T_base_box, size)`` of the box a triad's vertices ``(4, 3)`` span."""
    origin = points[0]
    edges = points[1:4] - origin
    size = np.linalg.norm(edges, axis=1)
    if np.any(size < 1e-3):
        raise PrimitiveError(f"triad {primitive_id}: an edge is shorter than 1 mm")
    U, _, Vt = np.linalg.svd((edges / size[:, None]).T)
    R = U @ Vt
    if np.linalg.det(R) < 0:
        R[:, 2] *= -1.0
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = origin + 0.5 * (R @ size)
    return T, size


def vertex_covariance(
    primitive: SketchPrimitive, pair: StereoPair | None = None, noise: StereoNoise | None = None
) -> FloatArray:
    """Joint covariance ``(3N, 3N)`` (m²) of a primitive's vertices.

    With the snapshot's ``pair`` and the ``noise`` it was placed with, the vertices' shared
    calibration errors correlate them (:meth:`StereoPair.triangulate_constrained`); without,
    only the per-vertex blocks are known and the vertices are taken as independent.
    """
    if pair is not None and noise is not None:
        a, b = primitive.pixels_a, primitive.pixels_b
        spread = handle_spread(b, primitive.edges, noise)
        return pair.triangulate_constrained(a, b, noise, spread)[1]
    n = len(primitive.points)
    joint = np.zeros((3 * n, 3 * n))
    for i, block in enumerate(np.asarray(primitive.covariances, dtype=float)):
        joint[3 * i : 3 * i + 3, 3 * i : 3 * i + 3] = block
    return joint


def propagate(
    function, points: FloatArray, joint: FloatArray, step_m: float = 1e-6
) -> tuple[FloatArray, FloatArray]:
    """``(value, covariance)`` of ``function(points (N, 3)) -> (k,)`` to first order (central
    differences of ``step_m`` on each vertex coordinate)."""
    value = np.asarray(function(points), dtype=float)
    J = np.zeros((value.size, points.size))
    for i in range(points.size):
        delta = np.zeros(points.size)
        delta[i] = step_m
        plus = function(points + delta.reshape(points.shape))
        minus = function(points - delta.reshape(points.shape))
        J[:, i] = (np.asarray(plus) - np.asarray(minus)).ravel() / (2.0 * step_m)
    covariance = J @ joint @ J.T
    return value, 0.5 * (covariance + covariance.T)


def line_direction_covariance(
    primitive: SketchPrimitive, pair: StereoPair | None = None, noise: StereoNoise | None = None
) -> tuple[FloatArray, FloatArray]:
    """A line's unit direction (start to end) and its 3 x 3 covariance (rank 2: across the
    line; radians² for small angles), from the vertices' joint covariance."""
    axis = line_axis(primitive)
    points = np.stack([axis.start, axis.end])

    def direction(p: FloatArray) -> FloatArray:
        return (p[1] - p[0]) / np.linalg.norm(p[1] - p[0])

    return propagate(direction, points, vertex_covariance(primitive, pair, noise))


def triad_box(
    primitive: SketchPrimitive,
    box_id: str = "",
    pair: StereoPair | None = None,
    noise: StereoNoise | None = None,
) -> SketchBox:
    """The box spanned by a triad's three edges from the common vertex (axes orthogonalized by
    the closest rotation; size = edge lengths). Its ``covariance`` is the box centre's (m²),
    propagated from the vertices' joint covariance (see :func:`vertex_covariance`: give the
    snapshot's ``pair`` and the ``noise`` for the correlation through the calibration)."""
    _expect(primitive, "triad")
    points = np.asarray(primitive.points, dtype=float)
    T, size = _box_frame(points, primitive.primitive_id)
    _, centre_covariance = propagate(
        lambda p: _box_frame(p, primitive.primitive_id)[0][:3, 3],
        points,
        vertex_covariance(primitive, pair, noise),
    )
    return SketchBox(
        stamp=primitive.stamp,
        box_id=box_id or primitive.primitive_id,
        T_base_box=T,
        size=size,
        covariance=centre_covariance,
        frame=primitive.frame,
    )


def _expect(primitive: SketchPrimitive, kind: str) -> None:
    if primitive.kind != kind:
        raise PrimitiveError(f"expected a {kind} primitive, got a {primitive.kind}")
