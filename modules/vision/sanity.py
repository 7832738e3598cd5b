"""Sanity checks of a tracked contour (Sandia report, section 2.3).

A snake that tracks a rectangular patch looks like a rounded rectangle. It must lie inside a
slightly larger rectangle and outside a slightly smaller ellipse, both built from the
contour's own moments: the rectangle with the same second moments as the contour (sides
``sqrt(12 eigenvalue)``, see :func:`umbra.modules.vision.features.equivalent_rectangle_sides`),
scaled up by ``1 + rectangle_margin``; and the ellipse inscribed in that same equivalent rectangle,
scaled down by ``ellipse_scale``. A patch seen obliquely is a quadrilateral, not a rectangle,
so when the contour follows a quadrilateral that a camera can see a rectangle as, the two
shapes are built and tested on the contour seen head-on (:mod:`umbra.modules.vision.rectify`:
mapped by the homography that makes that quadrilateral a square, the shapes from the mapped
contour's moments along the square's sides); the shapes a result reports for drawing are those
of the contour as the image shows it. On top of that the area and the aspect ratio must stay
within bounds, and so must the rates of change from the previous frame (centroid jump, relative
area change, rotation, relative aspect change) and the drift of the aspect ratio from the
contour acquired at the seed (approach and roll keep a patch's aspect ratio). Any failed check
means the snake may no longer be on the patch: the servo stops and the operator is asked.

Units: pixels, px², radians; image frame u right, v down.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.connectors.tracking import SnakeCheck, TrackStatus
from umbra.modules.vision.features import (
    PolygonFeatures,
    angle_difference,
    equivalent_rectangle_sides,
    polygon_features,
)
from umbra.modules.vision.polygon import as_polygon
from umbra.modules.vision.rectify import apply_homography, rectifying_homography

FloatArray = NDArray[np.float64]

TRACKING = TrackStatus.TRACKING
FAILED = TrackStatus.FAILED


@dataclass(frozen=True)
class SanityLimits:
    """Bounds of the sanity checks, built from validated settings
    (:class:`umbra.modules.vision.snake_config.SnakeSettings` holds their rules).

    - ``rectangle_margin``: the outer rectangle is the equivalent rectangle scaled by 1 + this.
    - ``ellipse_scale``: the inner ellipse is the one inscribed in the equivalent rectangle,
      scaled by this (< 1).
    - ``min_area_px2`` / ``max_area_px2``: area bounds [px²].
    - ``min_aspect`` / ``max_aspect``: bounds on major / minor axis length.
    - ``max_centroid_jump_px``: largest centroid motion between two frames [px].
    - ``max_area_change``: largest relative area change between two frames (0.3 = 30 %).
    - ``max_rotation_rad``: largest change of the principal axis between two frames [rad].
    - ``max_aspect_change``: largest relative change of the aspect ratio between two frames
      (approach and roll leave a patch's aspect alone; a leak into a neighbour does not).
    - ``max_aspect_drift``: largest relative difference of the aspect ratio from the reference
      contour (the one acquired at the seed), for leaks too slow for the per-frame check.
    - ``min_contour_vertices``: fewest vertices of a usable contour.
    """

    rectangle_margin: float = 0.12
    ellipse_scale: float = 0.85
    min_area_px2: float = 150.0
    max_area_px2: float = 250_000.0
    min_aspect: float = 1.0
    max_aspect: float = 4.0
    max_centroid_jump_px: float = 40.0
    max_area_change: float = 0.25
    max_rotation_rad: float = np.deg2rad(20.0)
    max_aspect_change: float = 0.12
    max_aspect_drift: float = 0.25
    min_contour_vertices: int = 4


@dataclass(frozen=True, eq=False)
class OrientedBox:
    """A rectangle or ellipse: centre [px], half-sizes along/across the axis [px], axis angle
    [rad] from u towards v."""

    center_uv: tuple[float, float]
    half_sizes: tuple[float, float]
    angle_rad: float

    def local(self, points: FloatArray) -> FloatArray:
        """Points (N x 2) in the box frame: coordinates along and across the axis [px]."""
        c, s = np.cos(self.angle_rad), np.sin(self.angle_rad)
        d = points - np.asarray(self.center_uv)
        return np.column_stack([d[:, 0] * c + d[:, 1] * s, -d[:, 0] * s + d[:, 1] * c])

    def corners(self) -> FloatArray:
        """The 4 corners (u, v) of the rectangle [px]."""
        c, s = np.cos(self.angle_rad), np.sin(self.angle_rad)
        a, b = self.half_sizes
        local = np.array([[-a, -b], [a, -b], [a, b], [-a, b]])
        return np.asarray(self.center_uv) + local @ np.array([[c, s], [-s, c]])


@dataclass(frozen=True, eq=False)
class SanityResult:
    """Outcome of the checks: ``status`` "tracking" or "failed"; ``reason`` all failed checks in
    words ("" when tracking); ``reasons`` one string per failed check and ``checks`` its code,
    in the same order; ``offending`` indices of vertices outside the rectangle or inside the
    ellipse; the ``outer_rectangle`` and ``inner_ellipse`` (None if the contour had no area); the
    contour's ``features``."""

    status: TrackStatus
    reason: str
    reasons: tuple[str, ...]
    offending: NDArray[np.intp]
    outer_rectangle: OrientedBox | None
    inner_ellipse: OrientedBox | None
    features: PolygonFeatures | None
    checks: tuple[SnakeCheck, ...] = ()

    @property
    def ok(self) -> bool:
        return self.status == TRACKING


def bounding_shapes(
    features: PolygonFeatures, limits: SanityLimits, axis_rad: float | None = None
) -> tuple[OrientedBox, OrientedBox]:
    """Outer rectangle and inner ellipse of a contour with these features, along its principal
    axis, or along ``axis_rad`` [rad] when the patch's sides are known (the principal axis of a
    square is any direction). The sides are those of the rectangle with the contour's second
    moments along that axis (``sqrt(12 variance)``)."""
    if axis_rad is None:
        angle = features.orientation_rad
        along, across = equivalent_rectangle_sides(features)
    else:
        angle = axis_rad
        mu20, mu11, mu02 = features.second_moments
        c, s = np.cos(angle), np.sin(angle)
        var_along = mu20 * c * c + 2.0 * mu11 * c * s + mu02 * s * s
        var_across = mu20 * s * s - 2.0 * mu11 * c * s + mu02 * c * c
        along, across = (float(np.sqrt(12.0 * max(v, 0.0))) for v in (var_along, var_across))
    grow = 1.0 + limits.rectangle_margin
    rectangle = OrientedBox(features.centroid_uv, (0.5 * along * grow, 0.5 * across * grow), angle)
    shrink = limits.ellipse_scale
    ellipse = OrientedBox(
        features.centroid_uv, (0.5 * along * shrink, 0.5 * across * shrink), angle
    )
    return rectangle, ellipse


def shape_offenders(
    polygon: FloatArray, features: PolygonFeatures, limits: SanityLimits
) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """Which vertices of ``polygon`` (N x 2 px, with these ``features``) lie outside the outer
    rectangle and which inside the inner ellipse. When the quadrilateral the contour follows is
    a view of a rectangle, judged on the contour seen head-on: mapped by the homography that
    makes that quadrilateral the unit square
    (:func:`umbra.modules.vision.rectify.rectifying_homography`), the shapes built from the
    mapped contour's moments along the square's sides. Otherwise on the contour as it is, the
    shapes along its principal axis."""
    homography = rectifying_homography(polygon)
    axis_rad = None
    if homography is not None:
        polygon = apply_homography(homography, polygon)
        features, axis_rad = polygon_features(polygon), 0.0
    rectangle, ellipse = bounding_shapes(features, limits, axis_rad)
    along_across = rectangle.local(polygon)
    outside = np.any(np.abs(along_across) > np.asarray(rectangle.half_sizes), axis=1)
    a, b = (max(half, 1e-9) for half in ellipse.half_sizes)
    e_local = ellipse.local(polygon)
    inside = (e_local[:, 0] / a) ** 2 + (e_local[:, 1] / b) ** 2 < 1.0
    return outside, inside


def check_contour(
    vertices: ArrayLike,
    limits: SanityLimits,
    previous: PolygonFeatures | None = None,
    reference: PolygonFeatures | None = None,
) -> SanityResult:
    """Run all checks on a contour (N x 2 vertices [px]); ``previous`` are the features of the
    last frame's contour (None for the first frame: no rate-of-change checks), ``reference``
    those of the contour acquired at the seed (None: no drift check)."""
    polygon = as_polygon(vertices)
    no_offenders = np.empty(0, dtype=np.intp)
    if polygon.shape[0] < limits.min_contour_vertices:
        reason = f"only {polygon.shape[0]} vertices (need {limits.min_contour_vertices})"
        few = (SnakeCheck.TOO_FEW_VERTICES,)
        return SanityResult(FAILED, reason, (reason,), no_offenders, None, None, None, few)
    try:
        features = polygon_features(polygon)
    except ValueError:
        reason = "contour has collapsed (zero area)"
        return SanityResult(
            FAILED, reason, (reason,), no_offenders, None, None, None, (SnakeCheck.ZERO_AREA,)
        )
    rectangle, ellipse = bounding_shapes(features, limits)
    reasons: list[str] = []
    checks: list[SnakeCheck] = []

    def fail(check: SnakeCheck, reason: str) -> None:
        checks.append(check)
        reasons.append(reason)

    area = features.area_px2
    if area < limits.min_area_px2:
        fail(
            SnakeCheck.AREA_BELOW_MIN,
            f"area {area:.0f} px² below the minimum {limits.min_area_px2:.0f} px²",
        )
    if area > limits.max_area_px2:
        fail(
            SnakeCheck.AREA_ABOVE_MAX,
            f"area {area:.0f} px² above the maximum {limits.max_area_px2:.0f} px²",
        )
    aspect = features.aspect_ratio
    if not limits.min_aspect <= aspect <= limits.max_aspect:
        fail(
            SnakeCheck.ASPECT_OUT_OF_BOUNDS,
            f"aspect ratio {aspect:.2f} outside [{limits.min_aspect:g}, {limits.max_aspect:g}]",
        )

    outside, inside = shape_offenders(polygon, features, limits)
    if np.any(outside):
        fail(
            SnakeCheck.OUTSIDE_RECTANGLE,
            f"{int(outside.sum())} vertices outside the outer rectangle",
        )
    if np.any(inside):
        fail(SnakeCheck.INSIDE_ELLIPSE, f"{int(inside.sum())} vertices inside the inner ellipse")

    if previous is not None:
        jump = float(np.hypot(*np.subtract(features.centroid_uv, previous.centroid_uv)))
        if jump > limits.max_centroid_jump_px:
            fail(SnakeCheck.CENTROID_JUMP, f"centroid jumped {jump:.0f} px in one frame")
        change = area / previous.area_px2 - 1.0 if previous.area_px2 > 0 else np.inf
        if abs(change) > limits.max_area_change:
            fail(SnakeCheck.AREA_CHANGE, f"area changed {100 * change:+.0f}% in one frame")
        turn = angle_difference(features.orientation_rad, previous.orientation_rad)
        if turn > limits.max_rotation_rad:
            fail(SnakeCheck.ROTATION, f"rotated {np.rad2deg(turn):.0f} deg in one frame")
        aspect_change = aspect / previous.aspect_ratio - 1.0
        if abs(aspect_change) > limits.max_aspect_change:
            fail(
                SnakeCheck.ASPECT_CHANGE,
                f"aspect ratio changed {100 * aspect_change:+.0f}% in one frame",
            )

    if reference is not None:
        drift = aspect / reference.aspect_ratio - 1.0
        if abs(drift) > limits.max_aspect_drift:
            fail(
                SnakeCheck.ASPECT_DRIFT,
                f"aspect ratio {100 * drift:+.0f}% from the acquired {reference.aspect_ratio:.2f}",
            )

    offending = np.flatnonzero(outside | inside).astype(np.intp)
    status = FAILED if reasons else TRACKING
    return SanityResult(
        status,
        "; ".join(reasons),
        tuple(reasons),
        offending,
        rectangle,
        ellipse,
        features,
        tuple(checks),
    )
