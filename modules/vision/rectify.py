"""A contour seen head-on: the quadrilateral it follows, undone by the homography that makes that
quadrilateral a rectangle.

A rectangular patch on a plane seen obliquely is a convex quadrilateral in the image, not a
rectangle: its second moments describe a rectangle it does not fill, and its corners stand out of
that rectangle by more than the sanity check's margin once the plane tilts by a few tens of
degrees. The checks of :mod:`umbra.modules.vision.sanity` are therefore made on the contour
*rectified*: mapped by the plane homography that takes its quadrilateral onto the unit square,
the patch as it would look seen straight on, its sides scaled to one. A bulge, a notch or a cut
corner stays one under that map, so the checks judge the damage as they would judge it on a
patch facing the camera (each in proportion to the patch's side it lies across).

The quadrilateral is the one the contour's vertices lie closest to, of the convex ones with
corners among the vertices of the simplified contour where it turns by
:data:`MIN_CORNER_TURN_DEG` or more: a vertex along a straight run (the middle of the chord that
cuts a corner off) is no corner, and a quadrilateral with a corner there would fold the cut's two
ends into its sides, halving how far they stand out. It is taken as a view of a rectangle only
when a camera can see a rectangle so: every interior angle at least :data:`MIN_CORNER_DEG` (a
rectangle turned 45 deg in its plane and tilted 75 deg away still shows 30 deg) and no side
shorter than :data:`MIN_SIDE_RATIO` times the side opposite it (the far side of a plane twice as
far as its near side). Otherwise there is no rectification and the contour is judged as it is.

Pixels: u right, v down.
"""

from __future__ import annotations

import math
from functools import lru_cache
from itertools import combinations

import numpy as np
from numpy.typing import NDArray

from umbra.modules.vision.polygon import signed_area, turns

FloatArray = NDArray[np.float64]

#: Smallest interior angle of a quadrilateral taken as a view of a rectangle [deg].
MIN_CORNER_DEG = 30.0
#: Smallest ratio of two opposite sides of a quadrilateral taken as a view of a rectangle.
MIN_SIDE_RATIO = 0.5
#: Least turn of the simplified contour at a vertex that may be a corner [deg]: half the least
#: turn of a view of a rectangle at its corners (180 deg less its largest interior angle, 150 deg
#: at :data:`MIN_CORNER_DEG`), so that a rounded corner simplified to two vertices still counts.
#: On corners cut at a fifth of the sides, the vertices halfway along the cut turn by 2-11 deg.
MIN_CORNER_TURN_DEG = 15.0
#: The contour is simplified, from within this share of its perimeter up, to at most
#: ``_MAX_CANDIDATES`` vertices before the corners are chosen among them.
_TOLERANCE = 0.002
#: Most vertices of the simplified contour the corners are chosen among (all their quadruples
#: are tried).
_MAX_CANDIDATES = 8


def quadrilateral(polygon: FloatArray) -> FloatArray | None:
    """The quadrilateral (4 x 2 px, positive area) that ``polygon`` (N x 2 px) follows: of the
    convex ones with corners among the vertices of the simplified contour that turn by
    :data:`MIN_CORNER_TURN_DEG` or more (among all of them when fewer than four do), the one its
    vertices lie closest to (least sum of distances to its outline), so that a bulge, a notch or
    a cut corner stands off it rather than bending it; None when there is none."""
    import cv2

    outline = polygon.astype(np.float32).reshape(-1, 1, 2)
    simplified: NDArray[np.generic] = outline
    tolerance = _TOLERANCE * cv2.arcLength(outline, True)
    while len(simplified) > _MAX_CANDIDATES and tolerance > 0.0:
        simplified = cv2.approxPolyDP(outline, tolerance, True)
        tolerance *= 1.5
    if len(simplified) < 4:
        return None
    points: FloatArray = np.asarray(simplified, dtype=np.float64).reshape(-1, 2)
    if signed_area(points) < 0.0:
        points = points[::-1].copy()
    corners = points[turns(points) >= math.radians(MIN_CORNER_TURN_DEG)]
    if len(corners) >= 4:
        points = corners
    quads = points[_quadruples(len(points))]  # (K, 4, 2) in the outline's order
    quads = quads[_convex(quads)]
    if len(quads) == 0:
        return None
    edges = quads[:, [1, 2, 3, 0]] - quads
    normals = np.stack([edges[..., 1], -edges[..., 0]], axis=-1)  # outward
    normals /= np.maximum(np.hypot(normals[..., 0], normals[..., 1]), 1e-12)[..., None]
    offsets = np.einsum("kjc,kjc->kj", normals, quads)
    # Signed distance of each vertex outside each side line; its largest over the sides is the
    # distance to a convex outline (inside: to the nearest side).
    beyond = normals @ polygon.T - offsets[..., None]  # (K, 4, N); matmul: 3x einsum's speed
    cost = np.abs(beyond.max(axis=1)).sum(axis=1)
    return quads[int(np.argmin(cost))]


def _convex(quads: FloatArray) -> NDArray[np.bool_]:
    """Which quadrilaterals (K, 4, 2) turn the same way as a positive area at every corner."""
    edges = quads[:, [1, 2, 3, 0]] - quads
    following = edges[:, [1, 2, 3, 0]]
    cross = edges[..., 0] * following[..., 1] - edges[..., 1] * following[..., 0]
    return np.all(cross > 0.0, axis=1)


@lru_cache(maxsize=_MAX_CANDIDATES + 1)
def _quadruples(count: int) -> NDArray[np.intp]:
    """Every increasing quadruple of indices below ``count`` (K x 4, read-only)."""
    index = np.array(list(combinations(range(count), 4)), dtype=np.intp)
    index.flags.writeable = False
    return index


def is_rectangle_view(quad: FloatArray) -> bool:
    """Whether a convex quadrilateral (4 x 2 px) can be a camera's view of a rectangle: interior
    angles of at least :data:`MIN_CORNER_DEG` and opposite sides within :data:`MIN_SIDE_RATIO`
    of each other."""
    corners = quad.tolist()
    edges = [
        (b[0] - a[0], b[1] - a[1]) for a, b in zip(corners, corners[1:] + corners[:1], strict=True)
    ]
    lengths = [math.hypot(*edge) for edge in edges]
    if min(lengths) <= 1e-9:
        return False
    smallest = math.cos(math.radians(MIN_CORNER_DEG))
    for k in range(4):  # corner k + 1, between edge k (in) and edge k + 1 (out)
        (ax, ay), (bx, by) = edges[k], edges[(k + 1) % 4]
        if -(ax * bx + ay * by) / (lengths[k] * lengths[(k + 1) % 4]) > smallest:
            return False
    return all(
        min(lengths[k], lengths[k + 2]) >= MIN_SIDE_RATIO * max(lengths[k], lengths[k + 2])
        for k in range(2)
    )


def rectifying_homography(polygon: FloatArray) -> FloatArray | None:
    """The homography (3 x 3, image px to unit square) that maps the quadrilateral ``polygon``
    (N x 2 px) follows onto the unit square, its corners in order onto (0, 0), (1, 0), (1, 1),
    (0, 1); None when that quadrilateral is not a view of a rectangle
    (:func:`is_rectangle_view`)."""
    import cv2

    quad = quadrilateral(polygon)
    if quad is None or not is_rectangle_view(quad):
        return None
    homography = cv2.getPerspectiveTransform(quad.astype(np.float32), _UNIT_SQUARE)
    return np.asarray(homography, dtype=np.float64)


#: The rectified rectangle's corners.
_UNIT_SQUARE = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]], dtype=np.float32)


def apply_homography(homography: FloatArray, points: FloatArray) -> FloatArray:
    """Points (N x 2 px) mapped by a 3 x 3 homography."""
    mapped = np.column_stack([points, np.ones(len(points))]) @ homography.T
    return mapped[:, :2] / mapped[:, 2:3]
