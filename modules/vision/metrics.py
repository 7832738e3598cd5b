"""Agreement between polygons, measured on the pixel grid (for tests and benchmarks).

Polygons are rasterized with ``cv2.fillPoly`` on a grid ``SUPERSAMPLE`` times finer than the
image, cropped to the polygons' bounding box: fillPoly covers every pixel an edge touches, which
on the image grid alone would grow each polygon by about half a pixel per side and bias an IoU.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

SUPERSAMPLE = 4
_SHIFT = 4


def polygon_mask(polygon: ArrayLike, shape: tuple[int, int]) -> NDArray[np.bool_]:
    """Pixels (H x W) covered by the polygon (N x 2 [px], sub-pixel vertices), with cv2.fillPoly."""
    mask = np.zeros(shape, dtype=np.uint8)
    points = np.asarray(polygon, dtype=np.float64).reshape(-1, 2)
    if len(points) >= 3:
        fixed = np.round(points * (1 << _SHIFT)).astype(np.int32)
        cv2.fillPoly(mask, [fixed], 1, cv2.LINE_8, _SHIFT)
    return mask.astype(bool)


def _fine_mask(points: NDArray, origin: NDArray, size: tuple[int, int]) -> NDArray[np.bool_]:
    mask = np.zeros(size, dtype=np.uint8)
    if len(points) >= 3:
        # Fine pixel centres sit at (i + 0.5) / S - 0.5 in image pixels.
        fine = (points - origin + 0.5) * SUPERSAMPLE - 0.5
        fixed = np.round(fine * (1 << _SHIFT)).astype(np.int32)
        cv2.fillPoly(mask, [fixed], 1, cv2.LINE_8, _SHIFT)
    return mask.astype(bool)


def polygon_iou(a: ArrayLike, b: ArrayLike, shape: tuple[int, int] | None = None) -> float:
    """Intersection over union of two polygons (N x 2 [px]); 0 if either is empty.

    ``shape`` (H, W), when given, clips both polygons to the image.
    """
    pa = np.asarray(a, dtype=np.float64).reshape(-1, 2)
    pb = np.asarray(b, dtype=np.float64).reshape(-1, 2)
    if len(pa) < 3 or len(pb) < 3:
        return 0.0
    both = np.vstack([pa, pb])
    low = np.floor(both.min(axis=0)) - 1
    high = np.ceil(both.max(axis=0)) + 1
    if shape is not None:
        low = np.maximum(low, -0.5)
        high = np.minimum(high, np.array([shape[1], shape[0]]) - 0.5)
        if np.any(high <= low):
            return 0.0
    width, height = (int(s) for s in np.ceil((high - low) * SUPERSAMPLE))
    size = (height, width)
    mask_a = _fine_mask(pa, low, size)
    mask_b = _fine_mask(pb, low, size)
    union = np.count_nonzero(mask_a | mask_b)
    return np.count_nonzero(mask_a & mask_b) / union if union else 0.0
