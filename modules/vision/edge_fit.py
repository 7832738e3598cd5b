"""Sub-pixel edges: each converged snake vertex is moved onto the colour edge along its normal.

The snake comes to rest where its pixel window is half target by the colour gate, which sits a
few tenths of a pixel inside a sharp edge (the gate counts a mixed pixel as target only when it
is mostly patch). At convergence every vertex is within a pixel or so of the edge, so the edge
itself can be measured there: the image is sampled (bilinearly) along the vertex's outward
normal over ``[-L, L]`` pixels, the samples are reduced to the mixing fraction

    t(s) = (p(s) - c_out) . (c_in - c_out) / |c_in - c_out|²

between the colour at the inner end ``c_in`` and at the outer end ``c_out`` (1 inside, 0
outside; linear in the pixel, so a blurred or anti-aliased edge mixes linearly), and the edge is
where a step with the same integral would be:

    e = ∫_{-L}^{L} t(s) ds - L,

which holds while the blurred edge lies wholly within the profile (a converged snake rests
within a pixel of the edge: blur up to ~1 px sigma with L = 4). A snake working on a coarser grid
(σ > 1, further from the edge) is measured twice: first over a profile σ times longer, then over
``[-L, L]`` centred on that first estimate.

A step at ``e`` smeared by any symmetric kernel (the lens, motion blur, the pixels' own area,
the bilinear interpolation) keeps that integral, so ``e`` carries no bias from the blur; sensor
noise averages over the ~4 L samples. Where there is no edge to measure (the ends differ by
less than ``min_contrast`` gray levels, the inner end is not the target colour or the outer end
is), the vertex moves as its two neighbours do when both found an edge, else it stays where
the snake put it.

Only ``N x (2 L / step + 1) x 4`` pixels are read for N vertices (twice that on a coarse
grid), never the whole image. Pixels: u right, v down, pixel centres at integer coordinates.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np
from numpy.typing import NDArray

from modules.vision.color import ColorModel, is_target
from modules.vision.polygon import following

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class EdgeFitParams:
    """``half_length_px``: the profile spans ``[-L, L]`` about the vertex [px];
    ``sample_px``: spacing of the profile samples [px]; ``end_px``: the colour of each end is
    the mean over this length [px]; ``min_contrast``: smallest colour difference between the
    ends that counts as an edge [gray levels]; ``max_shift_px``: largest move of a vertex [px]."""

    half_length_px: float = 4.0
    sample_px: float = 0.5
    end_px: float = 1.0
    min_contrast: float = 20.0
    max_shift_px: float = 4.0


@dataclass(frozen=True, eq=False)
class EdgeFit:
    """Outcome: ``vertices`` (N x 2 px) moved onto the edge, ``shift_px`` (N) the move along
    the outward normal [px] (0 where no edge was found), ``found`` (N bool) where an edge was
    measured."""

    vertices: FloatArray
    shift_px: FloatArray
    found: NDArray[np.bool_]

    @property
    def found_fraction(self) -> float:
        """Share of the vertices that found an edge under them."""
        return np.count_nonzero(self.found) / self.found.size if self.found.size else 0.0


def sample_bilinear(image: NDArray[np.uint8], points_uv: FloatArray) -> NDArray[np.float32]:
    """Bilinear colour (N, K, C float32) at points (N, K, 2 px) of an H x W x C uint8 image;
    points outside read the border. One ``cv2.remap`` over the points alone: only the 4 pixels
    around each point are read (positions to 1/32 px, values to the gray level)."""
    maps = points_uv.astype(np.float32)
    sampled = cv2.remap(
        image, maps[..., 0], maps[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
    )
    return sampled.reshape(*points_uv.shape[:-1], image.shape[2]).astype(np.float32)


def fit_edges(
    image: NDArray[np.uint8],
    vertices: FloatArray,
    normals: FloatArray,
    model: ColorModel,
    k_sigma: float,
    min_gray: float,
    params: EdgeFitParams | None = None,
    scale: int = 1,
) -> EdgeFit:
    """Move each vertex (N x 2 px) along its unit outward normal (N x 2) onto the edge. With a
    grid ``scale`` σ > 1 (a snake working on every σ-th pixel, so up to σ times further from
    the edge) the first pass spans σ times more, with samples σ times further apart."""
    p = params or EdgeFitParams()
    count = round(2.0 * p.half_length_px / p.sample_px) + 1
    ends = max(round(p.end_px / p.sample_px) + 1, 1)
    weights, unit = _profile_weights(count, ends)
    total = float(count - 1)  # the trapezoid weights' sum
    shift = np.zeros(len(vertices))
    found = np.ones(len(vertices), dtype=bool)
    # On a coarse grid two passes: the second centres the profile on the first estimate. The
    # colour tests are made on the first.
    for reach in (scale, 1) if scale > 1 else (1,):
        length = p.half_length_px * reach
        s = unit * length
        centres = vertices + shift[:, None] * normals
        points = centres[:, None, :] + s[None, :, None] * normals[:, None, :]
        profile = sample_bilinear(image, points)  # (N, K, C)
        inner, outer, summed = np.einsum("nkc,jk->jnc", profile, weights)
        contrast = inner - outer
        power = np.einsum("nc,nc->n", contrast, contrast)
        if reach == scale:
            found &= power >= p.min_contrast**2
            target = is_target(model, np.concatenate([inner, outer]), k_sigma, min_gray)
            found &= target[: len(inner)] & ~target[len(inner) :]
        # The integral of t = (p - outer) . contrast / power, by the trapezoid rule: linear in
        # the samples, so summed first.
        moment = np.einsum("nc,nc->n", summed - total * outer, contrast)
        integral = (p.sample_px * reach) * moment / np.where(found, power, 1.0)
        shift = np.where(found, shift + integral - length, 0.0)
        found &= np.abs(shift) <= p.max_shift_px * scale
        shift = np.where(found, shift, 0.0)
    # A vertex without an edge of its own between two that found one (a corner's diagonal
    # profile that ends on the other side, a speck of texture) moves as its neighbours do.
    before, after = following(found, -1), following(found)
    bridged = ~found & before & after
    if np.any(bridged):
        mean = 0.5 * (following(shift, -1) + following(shift))
        shift = np.where(bridged, mean, shift)
    return EdgeFit(vertices + shift[:, None] * normals, shift, found)


@lru_cache(maxsize=8)
def _profile_weights(count: int, ends: int) -> tuple[NDArray[np.float32], FloatArray]:
    """Weights over ``count`` profile samples (rows: mean of the inner end, mean of the outer
    end, trapezoid rule in samples) and the sample positions over [-1, 1]; read-only."""
    weights = np.zeros((3, count), dtype=np.float32)
    weights[0, :ends] = 1.0 / ends
    weights[1, -ends:] = 1.0 / ends
    weights[2] = 1.0
    weights[2, [0, -1]] = 0.5
    unit = np.linspace(-1.0, 1.0, count)
    weights.flags.writeable = False
    unit.flags.writeable = False
    return weights, unit


def complete_corners(
    vertices: FloatArray, found: NDArray[np.bool_], min_turn_rad: float, max_reach_px: float
) -> FloatArray:
    """Put back the sharp convex corners that a polygon of evenly spaced vertices cuts off.

    Between two vertices ``b -> c`` whose neighbouring segments ``a -> b`` and ``c -> d`` turn
    by more than ``min_turn_rad`` (outwards), the lines through ``a, b`` and ``c, d`` meet at the
    corner; it is inserted when it lies ahead of ``b`` and behind ``c`` within ``max_reach_px``
    of both, and all four vertices lie on a measured edge (``found``). A smooth contour (turn
    per segment below the threshold: radius of curvature above segment / turn) is unchanged.
    """
    count = len(vertices)
    if count < 4:
        return vertices
    edges = following(vertices) - vertices  # edge i runs from vertex i to vertex i + 1
    d1 = following(edges, -1)  # a -> b, for b = vertex i
    d2 = following(edges)  # c -> d
    u, v = vertices[:, 0], vertices[:, 1]
    orientation = 1.0 if np.dot(u, following(v)) >= np.dot(following(u), v) else -1.0
    cross = orientation * (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])
    len1 = np.hypot(d1[:, 0], d1[:, 1])
    len2 = np.hypot(d2[:, 0], d2[:, 1])
    dot = d1[:, 0] * d2[:, 0] + d1[:, 1] * d2[:, 1]
    # A convex turn (cross > 0) by more than min_turn_rad: cos(turn) < cos(min_turn_rad).
    sharp = (cross > 0) & (dot < np.cos(min_turn_rad) * len1 * len2)
    both = found & following(found)
    sharp &= both & following(both, -1) & following(both)
    if not np.any(sharp):
        return vertices
    # b + s d1 = c - r d2  ->  [d1, d2] [s, r] = c - b = edges
    d1, d2, gap, cross = d1[sharp], d2[sharp], edges[sharp], cross[sharp] * orientation
    s_ = (gap[:, 0] * d2[:, 1] - gap[:, 1] * d2[:, 0]) / cross
    r_ = (d1[:, 0] * gap[:, 1] - d1[:, 1] * gap[:, 0]) / cross
    reach = (s_ > 0) & (r_ > 0)
    reach &= (s_ * len1[sharp] <= max_reach_px) & (r_ * len2[sharp] <= max_reach_px)
    if not np.any(reach):
        return vertices
    at = np.flatnonzero(sharp)[reach]
    corners = vertices[at] + s_[reach, None] * d1[reach]
    return np.insert(vertices, at + 1, corners, axis=0)
