"""The snake's pressure: the share of target-coloured pixels in a window around each vertex.

Each vertex reads a window of ``2 r + 1`` cells on the grid of every σ-th pixel (σ the snake's
grid scale, 1 at full resolution), as a ``(2 r + 2)²`` block with area weights on its first and
last rows and columns (a box filter followed by bilinear interpolation, so the pressure is
continuous in the vertex position). Each pixel votes target when it passes the colour gate of
:func:`umbra.modules.vision.color.gate_test`, its clipped channels put back first
(:func:`umbra.modules.vision.color.unclip`); ``p = 2 f - 1`` with ``f`` the weighted share of
votes.

:class:`PressureField` holds what does not change between the iterations of one frame (the
image viewed as rows of pixels, the gate's constants, index steps), so an iteration costs a few
vectorised operations on the ``N (2 r + 2)²`` pixels it reads and nothing else: never the whole
image. Pixels: u right, v down, pixel centres at integer coordinates.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from umbra.modules.vision.color import ColorModel, offset_matrix, unclip

FloatArray = NDArray[np.float64]


class PressureField:
    """Pressure of one image (H x W x 3 uint8 BGR, read in place when contiguous) for one colour
    model, gate radius ``k_sigma``, dark floor ``min_gray``, window radius ``radius`` [cells]
    and grid ``scale`` [px per cell]."""

    def __init__(
        self,
        image: NDArray[np.uint8],
        model: ColorModel,
        k_sigma: float,
        min_gray: float,
        radius: int,
        scale: int = 1,
    ) -> None:
        self.height, self.width = image.shape[:2]
        self.flat = np.ascontiguousarray(image).reshape(-1, image.shape[2])
        self.radius = radius
        self.scale = scale
        self.span = 2 * radius + 2
        self.steps = np.arange(self.span) - radius
        self.model = model
        self.matrix = offset_matrix(model)
        (a11, a12), (_, a22) = model.offset_covariance
        self.floor = np.float32(model.chroma_floor**2)
        self.a11, self.a12, self.a22 = np.float32(a11), np.float32(a12), np.float32(a22)
        self.k2 = np.float32(k_sigma * k_sigma)
        self.dark = np.float32(3.0 * min_gray)
        self.norm = 1.0 / float((2 * radius + 1) ** 2)

    def __call__(self, vertices: FloatArray) -> FloatArray:
        """Pressure in [-1, 1] at each vertex (N x 2 px)."""
        count = len(vertices)
        scale = self.scale
        grid = vertices / scale if scale != 1 else vertices
        base = np.floor(grid)
        frac = (grid - base).astype(np.float32)
        cells = base.astype(np.intp)
        cols = (cells[:, 0:1] + self.steps) * scale
        rows = (cells[:, 1:2] + self.steps) * scale
        if (
            cols.min() < 0
            or rows.min() < 0
            or cols.max() >= self.width
            or rows.max() >= self.height
        ):
            cols = np.clip(cols, 0, self.width - 1)
            rows = np.clip(rows, 0, self.height - 1)
        index = (rows * self.width)[:, :, None] + cols[:, None, :]
        pixels = unclip(self.model, self.flat.take(index.ravel(), axis=0).astype(np.float32))
        x1, x2, total = (pixels @ self.matrix).T
        # The gate x^T (A + floor s² I)^-1 x <= k², multiplied out (no division).
        floor = self.floor * total * total
        q11 = floor + self.a11
        q22 = floor + self.a22
        lhs = q22 * x1 * x1 - 2.0 * self.a12 * x1 * x2 + q11 * x2 * x2
        target = (lhs <= self.k2 * (q11 * q22 - self.a12 * self.a12)) & (total >= self.dark)
        votes = target.reshape(count, self.span, self.span).astype(np.float32)
        # Area weights: 1 - f on the first row/column of the block, f on the last, 1 between.
        w_u = np.ones((count, self.span), dtype=np.float32)
        w_v = np.ones((count, self.span), dtype=np.float32)
        w_u[:, 0] = 1.0 - frac[:, 0]
        w_u[:, -1] = frac[:, 0]
        w_v[:, 0] = 1.0 - frac[:, 1]
        w_v[:, -1] = frac[:, 1]
        fraction = np.einsum("nij,ni,nj->n", votes, w_v, w_u, optimize=False) * self.norm
        return 2.0 * fraction.astype(np.float64) - 1.0
