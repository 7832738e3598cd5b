"""Pixel windows around sub-pixel points, read with fancy indexing (never the whole image).

A window of radius ``h`` is the (2h+1) x (2h+1) pixel box centred on a continuous point. To keep
the result continuous in the point's position, the box is read as a (2h+2) x (2h+2) block with
area weights: the edge rows and columns get the fraction of the pixel the box covers (the box
filter followed by bilinear interpolation). Pixel centres are at integer coordinates (OpenCV's
convention); points outside the image read the nearest border pixel.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray


def window_blocks(
    image: NDArray[np.uint8], points_uv: NDArray[np.float64], radius: int
) -> tuple[NDArray[np.uint8], NDArray[np.float32]]:
    """Pixels and weights of the windows around ``points_uv`` (N x 2, pixels).

    Returns ``pixels`` (N, B, B, C) and ``weights`` (N, B, B) with ``B = 2 radius + 2``; each
    window's weights sum to ``(2 radius + 1)²``.
    """
    height, width = image.shape[:2]
    span = 2 * radius + 2
    base = np.floor(points_uv).astype(np.intp)
    frac = (points_uv - base).astype(np.float32)
    steps = np.arange(span) - radius
    cols = np.clip(base[:, 0:1] + steps, 0, width - 1)
    rows = np.clip(base[:, 1:2] + steps, 0, height - 1)
    pixels = image[rows[:, :, None], cols[:, None, :]]
    w_u = np.ones((points_uv.shape[0], span), dtype=np.float32)
    w_v = np.ones((points_uv.shape[0], span), dtype=np.float32)
    # The box [x - h - 1/2, x + h + 1/2] covers (1 - f) of the first pixel and f of the last.
    w_u[:, 0] = 1.0 - frac[:, 0]
    w_u[:, -1] = frac[:, 0]
    w_v[:, 0] = 1.0 - frac[:, 1]
    w_v[:, -1] = frac[:, 1]
    return pixels, w_v[:, :, None] * w_u[:, None, :]
