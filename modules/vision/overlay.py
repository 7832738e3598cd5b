"""Drawing the snake for the operator: contour, offending vertices, bounding shapes, axes, text.

Colors are BGR. Pixel coordinates are drawn with 4 fractional bits, so sub-pixel contours are
placed where they are. Nothing here modifies its input image.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.modules.vision.features import PolygonFeatures
from umbra.modules.vision.sanity import OrientedBox, SanityResult

_SHIFT = 4
CONTOUR_BGR = (0, 255, 255)
VERTEX_BGR = (0, 200, 0)
OFFENDING_BGR = (0, 0, 255)
RECTANGLE_BGR = (255, 255, 0)
ELLIPSE_BGR = (255, 0, 255)
AXIS_BGR = (255, 128, 0)
TEXT_BGR = (255, 255, 255)


def _fixed(points: ArrayLike) -> NDArray[np.int32]:
    scaled = np.asarray(points, dtype=np.float64) * (1 << _SHIFT)
    limit = float(np.iinfo(np.int32).max // 2)
    return np.round(np.clip(np.nan_to_num(scaled, nan=0.0), -limit, limit)).astype(np.int32)


def _point(uv: ArrayLike) -> tuple[int, int]:
    fixed = _fixed(uv).reshape(2)
    return int(fixed[0]), int(fixed[1])


def draw_overlay(
    image: NDArray[np.uint8],
    vertices: ArrayLike | None = None,
    sanity: SanityResult | None = None,
    lines: Sequence[str] = (),
    features: PolygonFeatures | None = None,
    *,
    offending: ArrayLike | None = None,
    outer_rectangle: OrientedBox | None = None,
    inner_ellipse: OrientedBox | None = None,
) -> NDArray[np.uint8]:
    """A copy of ``image`` (H x W x 3 BGR) with the snake and its checks drawn on it.

    ``vertices`` N x 2 [px]; ``sanity`` supplies the outer rectangle, inner ellipse, offending
    vertices and features, each of which the keyword of the same name overrides; ``lines`` are
    text lines written at the top left (stage, status, errors).
    """
    import cv2

    canvas = np.ascontiguousarray(image).copy()
    if canvas.ndim == 2:
        canvas = cv2.cvtColor(canvas, cv2.COLOR_GRAY2BGR)
    if sanity is not None:
        offending = sanity.offending if offending is None else offending
        features = features or sanity.features
        outer_rectangle = outer_rectangle or sanity.outer_rectangle
        inner_ellipse = inner_ellipse or sanity.inner_ellipse
    offending = np.asarray([] if offending is None else offending, dtype=np.intp).ravel()
    if outer_rectangle is not None and _drawable(outer_rectangle):
        corners = outer_rectangle.corners()
        cv2.polylines(canvas, [_fixed(corners)], True, RECTANGLE_BGR, 1, cv2.LINE_AA, _SHIFT)
    if inner_ellipse is not None and _drawable(inner_ellipse):
        cv2.ellipse(
            canvas,
            _point(inner_ellipse.center_uv),
            _point(inner_ellipse.half_sizes),
            float(np.rad2deg(inner_ellipse.angle_rad)),
            0.0,
            360.0,
            ELLIPSE_BGR,
            1,
            cv2.LINE_AA,
            _SHIFT,
        )
    if vertices is not None:
        polygon = np.asarray(vertices, dtype=np.float64).reshape(-1, 2)
        if len(polygon) >= 2:
            cv2.polylines(canvas, [_fixed(polygon)], True, CONTOUR_BGR, 1, cv2.LINE_AA, _SHIFT)
        bad = np.zeros(len(polygon), dtype=bool)
        bad[offending[(offending >= 0) & (offending < len(polygon))]] = True
        for index, (u, v) in enumerate(_fixed(polygon).tolist()):  # one conversion for all
            color = OFFENDING_BGR if bad[index] else VERTEX_BGR
            radius = 3 if bad[index] else 2
            cv2.circle(canvas, (u, v), radius << _SHIFT, color, -1, cv2.LINE_AA, _SHIFT)
    if features is not None:
        _draw_axes(canvas, features)
    _draw_text(canvas, lines)
    return canvas


def _draw_axes(canvas: NDArray[np.uint8], features: PolygonFeatures) -> None:
    import cv2

    center = np.asarray(features.centroid_uv)
    c, s = np.cos(features.orientation_rad), np.sin(features.orientation_rad)
    major = 0.5 * features.major_axis_px * np.array([c, s])
    minor = 0.5 * features.minor_axis_px * np.array([-s, c])
    cv2.line(
        canvas, _point(center - major), _point(center + major), AXIS_BGR, 1, cv2.LINE_AA, _SHIFT
    )
    cv2.line(
        canvas, _point(center - minor), _point(center + minor), AXIS_BGR, 1, cv2.LINE_AA, _SHIFT
    )
    cv2.drawMarker(
        canvas,
        (round(center[0]), round(center[1])),
        AXIS_BGR,
        cv2.MARKER_CROSS,
        12,
        2,
    )


def _draw_text(canvas: NDArray[np.uint8], lines: Sequence[str]) -> None:
    import cv2

    font, scale, thickness = cv2.FONT_HERSHEY_SIMPLEX, 0.5, 1
    y = 6
    for line in lines:
        (width, height), baseline = cv2.getTextSize(line, font, scale, thickness)
        top, bottom = y, y + height + baseline + 4
        region = canvas[top:bottom, 4 : 4 + width + 8]
        region //= 3  # darken behind the text so it reads on any background
        cv2.putText(
            canvas, line, (8, y + height + 2), font, scale, TEXT_BGR, thickness, cv2.LINE_AA
        )
        y = bottom + 2


def _drawable(box: OrientedBox) -> bool:
    """False for the degenerate bounds of a collapsed contour (NaN or huge sizes): skip them."""
    values = np.array([*box.center_uv, *box.half_sizes, box.angle_rad], dtype=float)
    return bool(np.all(np.isfinite(values)) and np.all(np.abs(values[:4]) < 1e5))
