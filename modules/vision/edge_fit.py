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
    crossing: bool = True
    max_kink_px: float = 1.5
    max_gap: int = 4
    window_px: float = 2.5


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
    # Centring passes (the step of equal area), each centred on the last estimate: on a coarse
    # grid first over a σ times longer profile; then the half-contrast crossing on a profile
    # centred on the edge. The colour tests are made on the first.
    reaches = (scale, 1, 1) if scale > 1 else (1, 1)
    for reach in reaches:
        length = p.half_length_px * reach
        profile = _profile(image, vertices, normals, shift, unit * length)
        inner, outer, summed = np.einsum("nkc,jk->jnc", profile, weights)
        if reach == scale:
            contrast = inner - outer
            found &= np.einsum("nc,nc->n", contrast, contrast) >= p.min_contrast**2
            target = is_target(model, np.concatenate([inner, outer]), k_sigma, min_gray)
            found &= target[: len(inner)] & ~target[len(inner) :]
        contrast, power = _contrast(profile, inner, outer, found)
        # The integral of t = (p - outer) . contrast / power, by the trapezoid rule: linear in
        # the samples, so summed first.
        moment = np.einsum("nc,nc->n", summed - total * outer, contrast)
        integral = (p.sample_px * reach) * moment / power
        shift = np.where(found, shift + integral - length, 0.0)
        found &= np.abs(shift) <= p.max_shift_px * scale
        shift = np.where(found, shift, 0.0)
    if p.crossing:
        profile = _profile(image, vertices, normals, shift, unit * p.half_length_px)
        inner, outer, _ = np.einsum("nkc,jk->jnc", profile, weights)
        contrast, power = _contrast(profile, inner, outer, found)
        fraction = np.einsum("nkc,nc->nk", profile - outer[:, None, :], contrast) / power[:, None]
        crossing, crossed = _half_crossing(fraction, unit * p.half_length_px, p.sample_px)
        found &= crossed
        shift = np.where(found, shift + crossing, 0.0)
        # Then the step of equal area over a window centred on the edge alone (exact for any
        # symmetric blur of a straight edge, blind to the texture beyond the window).
        offsets = unit * p.half_length_px
        central = np.abs(offsets) <= p.window_px + 1e-9
        trapezoid = np.where(central, 1.0, 0.0)
        edge_ends = np.flatnonzero(central)[[0, -1]]
        trapezoid[edge_ends] = 0.5
        half = 0.5 * p.sample_px * float(trapezoid.sum())
        for _ in range(2):
            profile = _profile(image, vertices, normals, shift, offsets)
            inner, outer, _ = np.einsum("nkc,jk->jnc", profile, weights)
            contrast, power = _contrast(profile, inner, outer, found)
            moment = np.einsum("nkc,nc,k->n", profile - outer[:, None, :], contrast, trapezoid)
            step = p.sample_px * moment / power - half
            shift = np.where(found, shift + np.clip(step, -p.window_px, p.window_px), 0.0)
        found &= np.abs(shift) <= p.max_shift_px * scale
        shift = np.where(found, shift, 0.0)
    found &= ~_off_the_curve(vertices + shift[:, None] * normals, normals, found, p.max_kink_px)
    shift = np.where(found, shift, 0.0)
    # A vertex without an edge of its own (a corner's diagonal profile that ends on the other
    # side, a speck of texture) moves as the vertices on either side that found one, across a
    # gap of up to ``max_gap`` vertices (interpolated along the contour).
    shift = _bridge(shift, found, p.max_gap)
    return EdgeFit(vertices + shift[:, None] * normals, shift, found)


def _off_the_curve(
    fitted: FloatArray, normals: FloatArray, found: NDArray[np.bool_], max_kink_px: float
) -> NDArray[np.bool_]:
    """Vertices whose fitted edge lies more than ``max_kink_px`` (plus what the contour's own
    curvature explains) off the curve through their neighbours' within two places, where the
    contour is smooth: a speck of texture or another edge in the profile, not the patch's edge.
    The median of the four neighbours' offsets along the vertex's normal stands for the curve,
    so a run of two such vertices is caught too."""
    if len(fitted) < 7:
        return np.zeros(len(fitted), dtype=bool)
    ring = [following(fitted, k) - fitted for k in (-2, -1, 1, 2)]
    offsets = np.stack([np.einsum("nc,nc->n", r, normals) for r in ring])
    middle = np.median(offsets, axis=0)
    around = np.stack([following(found, k) for k in (-2, -1, 1, 2)]).sum(axis=0) >= 3
    cos_turn = np.einsum("nc,nc->n", following(normals, -1), following(normals))
    smooth = cos_turn > _STRAIGHT
    # On a curve of turn θ [rad] between the neighbours' normals and segment L, the neighbours
    # sit ~1.25 θ L / 2 behind the tangent.
    turn = np.arccos(np.clip(cos_turn, -1.0, 1.0))
    step = np.hypot(*(following(fitted) - following(fitted, -1)).T) / 2.0
    allowance = 0.625 * turn * step
    return found & around & smooth & (np.abs(middle) > max_kink_px + allowance)


def _profile(image, vertices, normals, shift, offsets) -> NDArray[np.float32]:
    """Colours (N, K, C) sampled at ``offsets`` (K px) along each normal about the vertex moved
    by ``shift`` (N px)."""
    centres = vertices + shift[:, None] * normals
    points = centres[:, None, :] + offsets[None, :, None] * normals[:, None, :]
    return sample_bilinear(image, points)


def _contrast(profile, inner, outer, found) -> tuple[NDArray, NDArray]:
    """The colour step between the profile's ends (N x C) over the channels that are never
    clipped along the profile (a saturated or black channel does not mix linearly: its edge
    looks shifted towards the clipped side), and its squared length (N; 1 where none)."""
    low = profile.min(axis=1)
    high = profile.max(axis=1)
    linear = (high < _CLIP_HIGH) & (low > _CLIP_LOW)
    contrast = np.where(linear, inner - outer, 0.0)
    power = np.einsum("nc,nc->n", contrast, contrast)
    # Where every channel with contrast is clipped, the full step is the best there is.
    weak = power < 0.25 * np.einsum("nc,nc->n", inner - outer, inner - outer)
    contrast = np.where(weak[:, None], inner - outer, contrast)
    power = np.einsum("nc,nc->n", contrast, contrast)
    return contrast, np.where(found & (power > 0.0), power, 1.0)


def _half_crossing(
    fraction: FloatArray, offsets: FloatArray, sample_px: float
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Where each profile's mixing fraction (N, K, falling from 1 inside to 0 outside at
    ``offsets`` K px) crosses one half: the first sign change from the inner end (the patch's
    side is even, the background's may be textured: a speck that looks like the patch beyond the
    edge must not pull it out), placed by a straight line fitted to the samples within one
    pixel of it. Returns (crossing px, found)."""
    above = fraction >= 0.5
    change = above[:, :-1] & ~above[:, 1:]  # from above to below between k and k + 1
    k = np.argmax(change, axis=1)  # the first from the inside
    crossed = change[np.arange(len(k)), k]
    reach = max(round(1.0 / sample_px), 1)
    window = np.arange(-reach + 1, reach + 1)  # samples k - reach + 1 .. k + reach
    index = np.clip(k[:, None] + window[None, :], 0, len(offsets) - 1)
    s = offsets[index]
    t = np.take_along_axis(fraction, index, axis=1)
    s_mean = s.mean(axis=1, keepdims=True)
    t_mean = t.mean(axis=1, keepdims=True)
    slope = ((s - s_mean) * (t - t_mean)).sum(axis=1) / ((s - s_mean) ** 2).sum(axis=1)
    crossed &= slope < 0.0
    safe = np.where(crossed, slope, -1.0)
    crossing = s_mean[:, 0] + (0.5 - t_mean[:, 0]) / safe
    return np.where(crossed, crossing, 0.0), crossed


#: Cosine of the largest turn between two neighbours' normals where a contour is taken as smooth.
_STRAIGHT = float(np.cos(np.deg2rad(20.0)))
#: Channel levels beyond which a sample is taken as clipped by the sensor [gray levels].
_CLIP_HIGH, _CLIP_LOW = 240.0, 2.0


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


def _bridge(shift: FloatArray, found: NDArray[np.bool_], max_gap: int) -> FloatArray:
    """``shift`` with the runs of at most ``max_gap`` vertices without an edge filled by linear
    interpolation (along the vertex index, cyclically) between the found ones around them."""
    count = len(shift)
    known = np.flatnonzero(found)
    if known.size < 2 or known.size == count:
        return shift
    index = np.arange(count)
    pos = np.searchsorted(known, index)
    right = np.where(pos < known.size, known[pos % known.size], known[0] + count)
    left = np.where(pos > 0, known[pos - 1], known[-1] - count)
    gap = right - left - 1
    filled = np.interp(index, known, shift[known], period=count)
    return np.where(~found & (gap <= max_gap), filled, shift)


def complete_corners(
    vertices: FloatArray,
    found: NDArray[np.bool_],
    min_turn_rad: float,
    max_reach_px: float,
    max_cut: int = 3,
) -> FloatArray:
    """Put back the sharp convex corners that a polygon of evenly spaced vertices cuts off.

    A corner is a stretch ``b -> ... -> c`` of at most ``max_cut`` segments that turns by more
    than ``min_turn_rad`` in all (outwards at every vertex) between two straight runs ``a -> b``
    and ``c -> d`` (each segment within ``_STRAIGHT_TURN`` of the segment before ``a`` and
    after ``d``). The lines through ``a, b`` and ``c, d`` meet at the corner; it replaces the
    vertices between ``b`` and ``c`` when it lies ahead of ``b`` and behind ``c`` within
    ``max_reach_px`` per segment of the stretch of both, and ``a, b, c, d`` lie on a measured
    edge (``found``). Where the snake's tension rounded a corner over one to ``max_cut``
    segments, this puts its tip back. A smooth contour (turn per segment below
    ``_STRAIGHT_TURN``) is unchanged.
    """
    count = len(vertices)
    if count < max(4, max_cut + 3):
        return vertices
    edges = following(vertices) - vertices  # edge i runs from vertex i to vertex i + 1
    u, v = vertices[:, 0], vertices[:, 1]
    orientation = 1.0 if np.dot(u, following(v)) >= np.dot(following(u), v) else -1.0
    before = following(edges, -1)  # the edge into vertex i
    cross = before[:, 0] * edges[:, 1] - before[:, 1] * edges[:, 0]
    dot = before[:, 0] * edges[:, 0] + before[:, 1] * edges[:, 1]
    turn = orientation * np.arctan2(cross, dot)  # at vertex i, outward (convex) positive
    straight = np.abs(turn) < _STRAIGHT_TURN
    # For each b and cut length g (c = b + g): turn from edge (b-1 -> b) to edge (c -> c+1).
    taken = np.zeros(count, dtype=bool)
    corners: list[tuple[int, int, FloatArray]] = []
    index = np.arange(count)
    for g in range(1, max_cut + 1):
        total = sum(following(turn, k) for k in range(g + 1))
        convex = np.all([following(turn, k) > -_STRAIGHT_TURN for k in range(g + 1)], axis=0)
        ok = (total > min_turn_rad) & convex
        ok &= following(straight, -1) & following(straight, g + 1)  # runs into b and out of c
        ok &= following(found, -1) & found & following(found, g) & following(found, g + 1)
        for b in np.flatnonzero(ok):
            c = (b + g) % count
            span = (index[b : b + g + 1] if b + g < count else np.r_[b:count, 0 : c + 1]) % count
            if taken[span].any():
                continue
            d1, d2, gap = before[b], edges[c], vertices[c] - vertices[b]
            det = d1[0] * d2[1] - d1[1] * d2[0]
            if abs(det) < 1e-12:
                continue
            s_ = (gap[0] * d2[1] - gap[1] * d2[0]) / det
            r_ = (d1[0] * gap[1] - d1[1] * gap[0]) / det
            reach_b, reach_c = s_ * np.hypot(*d1), r_ * np.hypot(*d2)
            if s_ <= 0 or r_ <= 0 or max(reach_b, reach_c) > max_reach_px * g:
                continue
            taken[span] = True
            corners.append((int(b), g, vertices[b] + s_ * d1))
    if not corners:
        return vertices
    keep = np.ones(count, dtype=bool)
    inserted: list[tuple[int, FloatArray]] = []
    for b, g, corner in corners:
        for k in range(1, g):
            keep[(b + k) % count] = False
        # b and c lie on the lines through the corner: one within a pixel of it adds nothing
        # but a sliver of a segment.
        for end in (b, (b + g) % count):
            if np.hypot(*(vertices[end] - corner)) < 1.0:
                keep[end] = False
        inserted.append((b, corner))
    out: list[FloatArray] = []
    after = dict(inserted)
    for i in range(count):
        if keep[i]:
            out.append(vertices[i])
        if i in after:
            out.append(after[i])
    return np.array(out)


#: A turn below this between two segments is a straight run [rad].
_STRAIGHT_TURN = float(np.deg2rad(12.0))
