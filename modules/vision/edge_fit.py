"""Sub-pixel edges: each converged snake vertex is moved onto the colour edge along its normal.

The snake comes to rest where its pixel window is half target by the colour gate, which sits a
pixel or more inside a blurred edge (the gate counts a mixed pixel as target only when it is
mostly patch). At convergence every vertex is within a few pixels of the edge, so the edge
itself can be measured there: the image is sampled (bilinearly) along the vertex's outward
normal over ``[-L, L]`` pixels and the samples are reduced to the mixing fraction

    t(s) = (p(s) - c_out) . (c_in - c_out) / |c_in - c_out|²

between the colour at the inner end ``c_in`` and at the outer end ``c_out`` (1 inside, 0
outside; linear in the pixel, so a blurred or anti-aliased edge mixes linearly). Channels that
are clipped at either end (a saturated patch at a high lighting gain, a black background) do not
mix linearly and are left out of the contrast: a clipped channel's edge looks moved towards the
clipped side. A channel the patch saturates is first put back where the target's colour has it,
then where the edge's mixing of the unclipped channels draws it
(:mod:`umbra.modules.vision.edge_mixing`), and counts again. In the crossing passes below the
contrast is weighed by the inverse of the colours' covariance about the profiles' ends,
``t(s) = (p - c_out)ᵀ W Δ / Δᵀ W Δ`` with ``W = Σ⁻¹`` over the channels used (generalised least
squares): a channel that the background's texture or JPEG's half-resolution colour makes
noisier counts less (20 gray levels of texture in one channel: 0.14 px RMS off with ``W = I``,
0.05 px with it; JPEG at quality 70: 0.10 against 0.07 px).

1. *Centring*: the step of equal area ``e = ∫ t ds - L`` over the whole profile (on a coarse
   grid σ > 1, over a σ times longer profile). It is exact for a clean edge, but the whole
   profile's texture and an off-centre profile move it.
2. *Crossing*: on a profile centred there, the first point from the patch's side where t falls
   through one half (a straight line through the samples within a pixel of it): for an edge
   smeared by any symmetric kernel (lens, motion, the pixels' area, bilinear sampling) the
   half-contrast point is the edge, and texture beyond the edge cannot pull it out (the patch's
   side is even, the background's may not be).
3. *Refinement*: the step of equal area over a window of ``±window_px`` centred on the
   crossing alone (exact for a straight edge under symmetric blur held by the window, blind to
   what lies beyond it). Where the result lay more than ``recentre_px`` off its profile's
   centre, 2 and 3 are repeated on a profile centred on it, so that its ends lie as far out on
   either side of the edge (blur reaching one end more than the other biases c_in or c_out).
   Where every channel with contrast is clipped at an end (a white background, a patch
   saturated in all its bright channels), 2 and 3 give way to the profile's steepest point,
   channel by channel where the channel is not clipped (a symmetric blur's line spread peaks at
   the edge whatever the ends read).

A fitted point further than ``max_kink_px`` off the curve through its neighbours' (a speck of
texture, another edge in the profile) is dropped. Where there is no edge to measure (the ends
differ by less than ``min_contrast`` gray levels, the inner end is not the target colour or the
outer end is, no crossing), the vertex moves as the vertices on either side that found one,
interpolated across a gap of up to ``max_gap`` vertices, else it stays where the snake put it.
Last, where the edge is smooth (no corner within ``smooth_reach`` vertices, all of them on a
measured edge), each fitted point is put on the quadratic least-squares curve through it and
its neighbours: the noise of single profiles (sensor noise, JPEG blocks) averages out along the
edge, and a straight or evenly curved edge stays where it is.

All of this is measured on light: where the camera encodes it by a curve (sRGB), each pixel
read is turned back into light first (:mod:`umbra.modules.vision.transfer`); the colour tests
stay on the codes the colour model learned.

Only ``N x (2 L / step + 1) x 4`` pixels are read per pass for N vertices (three passes at
most), never the whole image. Pixels: u right, v down, pixel centres at integer coordinates.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from umbra.modules.vision.color import ColorModel, is_target, unclip
from umbra.modules.vision.edge_mixing import read_linearly, unclip_by_mixing
from umbra.modules.vision.polygon import following, turns
from umbra.modules.vision.transfer import Encoding, light_table, to_light

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class EdgeFitParams:
    """``half_length_px``: the profile spans ``[-L, L]`` about the vertex [px];
    ``sample_px``: spacing of the profile samples [px]; ``end_px``: the colour of each end is
    the mean over this length [px]; ``min_contrast``: smallest colour difference between the
    ends that counts as an edge [gray levels]; ``max_shift_px``: largest move of a vertex [px];
    ``crossing``: measure at the half-contrast crossing (else the step of equal area over the
    whole profile, as on the coarse grid); ``max_kink_px``: a fitted edge point further than
    this off the curve through its neighbours' is texture [px]; ``max_gap``: longest run of
    vertices without an edge that is interpolated from either side [vertices]; ``window_px``:
    half-width of the equal-area window about the crossing [px]; ``recentre_px``: a crossing
    further than this from its profile's centre is measured again on a centred profile [px];
    ``smooth_reach``: each fitted point is put on the quadratic through it and this many
    neighbours on either side where the edge is smooth (0: off) [vertices]; ``encoding``: how
    the image's codes stand for light (:mod:`umbra.modules.vision.transfer`): the edge is
    measured on light, the colour tests on the codes the colour model learned."""

    half_length_px: float = 4.0
    sample_px: float = 0.5
    end_px: float = 1.0
    min_contrast: float = 20.0
    max_shift_px: float = 4.0
    crossing: bool = True
    max_kink_px: float = 1.5
    max_gap: int = 4
    window_px: float = 2.5
    recentre_px: float = 0.5
    smooth_reach: int = 2
    encoding: Encoding = "linear"


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
    import cv2

    maps = points_uv.astype(np.float32)
    sampled = cv2.remap(
        image, maps[..., 0], maps[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
    )
    return sampled.reshape(*points_uv.shape[:-1], image.shape[2]).astype(np.float32)


def sample_light(
    image: NDArray[np.uint8], points_uv: FloatArray, encoding: Encoding
) -> NDArray[np.float32]:
    """The light (N, K, C float32, 0..255 scale) at points (N, K, 2 px) of an H x W x C uint8
    image whose codes are ``encoding``: each of the 4 pixels around a point is turned into light
    first, then interpolated bilinearly (light mixes linearly, codes of a curve do not); points
    outside read the border. With ``linear`` codes, :func:`sample_bilinear`."""
    return sample_codes_and_light(image, points_uv, encoding)[1]


def sample_codes_and_light(
    image: NDArray[np.uint8], points_uv: FloatArray, encoding: Encoding
) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """The codes and the light (each N, K, C float32) at points (N, K, 2 px), from one read of
    the 4 pixels around each point: codes interpolated as :func:`sample_bilinear` does, light as
    :func:`sample_light` does. With ``linear`` codes, both are the same array."""
    if encoding == "linear":
        codes = sample_bilinear(image, points_uv)
        return codes, codes
    height, width = image.shape[:2]
    u = np.clip(points_uv[..., 0], 0.0, width - 1.0)
    v = np.clip(points_uv[..., 1], 0.0, height - 1.0)
    u0 = np.minimum(np.floor(u).astype(np.intp), max(width - 2, 0))
    v0 = np.minimum(np.floor(v).astype(np.intp), max(height - 2, 0))
    u1, v1 = np.minimum(u0 + 1, width - 1), np.minimum(v0 + 1, height - 1)
    fu = (u - u0).astype(np.float32)[..., None]
    fv = (v - v0).astype(np.float32)[..., None]
    corners = (image[v0, u0], image[v0, u1], image[v1, u0], image[v1, u1])
    weights = ((1.0 - fv) * (1.0 - fu), (1.0 - fv) * fu, fv * (1.0 - fu), fv * fu)
    table = light_table(encoding)
    codes = sum(w * c for w, c in zip(weights, corners, strict=True))
    light = sum(w * table[c] for w, c in zip(weights, corners, strict=True))
    return np.asarray(codes, dtype=np.float32), np.asarray(light, dtype=np.float32)


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
    # Centring: the step of equal area over a profile σ times longer on a coarse grid (the
    # colour tests are made here); then, on a profile centred there, the first half-contrast
    # crossing from the patch's side, refined by the step of equal area over a window centred
    # on it alone.
    length = p.half_length_px * scale
    codes, profile = _profile(image, vertices, normals, shift, unit * length, p.encoding)
    inner, outer, summed = np.einsum("nkc,jk->jnc", codes, weights)
    contrast = inner - outer
    power = np.einsum("nc,nc->n", contrast, contrast)
    found = _an_edge_between(inner, outer, power, model, k_sigma, min_gray, p.min_contrast)
    if profile is not codes:  # the colour tests on codes; the step of equal area on light
        inner, outer, summed = np.einsum("nkc,jk->jnc", profile, weights)
        contrast = inner - outer
        power = np.einsum("nc,nc->n", contrast, contrast)
    # The integral of t = (p - outer) . contrast / power, by the trapezoid rule: linear in the
    # samples, so summed first.
    moment = np.einsum("nc,nc->n", summed - total * outer, contrast)
    integral = (p.sample_px * scale) * moment / np.where(found, power, 1.0)
    shift = np.where(found, integral - length, 0.0)
    found &= np.abs(shift) <= p.max_shift_px * scale
    shift = np.where(found, shift, 0.0)
    if p.crossing:
        _cross(image, vertices, normals, model, shift, found, p, p.max_shift_px * scale)
    found &= ~_off_the_curve(vertices + shift[:, None] * normals, normals, found, p.max_kink_px)
    shift = np.where(found, shift, 0.0)
    # A vertex without an edge of its own (a corner's diagonal profile that ends on the other
    # side, a speck of texture) moves as the vertices on either side that found one, across a
    # gap of up to ``max_gap`` vertices (interpolated along the contour).
    shift = _bridge(shift, found, p.max_gap)
    if p.smooth_reach > 0:
        shift += _along_the_curve(vertices + shift[:, None] * normals, normals, found, p)
    return EdgeFit(vertices + shift[:, None] * normals, shift, found)


def measure_near_edge(
    image: NDArray[np.uint8],
    points: FloatArray,
    normals: FloatArray,
    model: ColorModel,
    k_sigma: float,
    min_gray: float,
    params: EdgeFitParams | None = None,
) -> EdgeFit:
    """Edge points for ``points`` (N x 2 px) that already lie within about a pixel of the edge
    (on a side's fitted curve), along their unit outward ``normals`` (N x 2): the crossing
    passes of :func:`fit_edges` alone, the colour tests made on their profiles' ends, and no
    second profile centred on the edge found (a profile of ``±half_length_px`` holds an edge a
    pixel off its centre). Nothing is centred first, and nothing is done along a contour (no
    kinks dropped, gaps bridged or points smoothed): the caller fits a curve through them.
    ``found``: an edge was measured; ``vertices`` the points moved onto it."""
    p = params or EdgeFitParams()
    shift = np.zeros(len(points))
    found = np.ones(len(points), dtype=bool)
    if len(points):
        ends_test = (k_sigma, min_gray)
        _cross(image, points, normals, model, shift, found, p, p.max_shift_px, ends_test, turns=1)
    return EdgeFit(points + shift[:, None] * normals, shift, found)


def _an_edge_between(
    inner: NDArray[np.float32],
    outer: NDArray[np.float32],
    power: FloatArray,
    model: ColorModel,
    k_sigma: float,
    min_gray: float,
    min_contrast: float,
) -> NDArray[np.bool_]:
    """Whether each profile (its ``inner`` and ``outer`` end colours, N x C, and their step's
    squared length ``power``, N) holds an edge of the target: the ends differ by
    ``min_contrast`` gray levels or more, the inner end is the target's colour and the outer
    end is not."""
    target = is_target(model, np.concatenate([inner, outer]), k_sigma, min_gray)
    return (power >= min_contrast**2) & target[: len(inner)] & ~target[len(inner) :]


def _cross(
    image: NDArray[np.uint8],
    vertices: FloatArray,
    normals: FloatArray,
    model: ColorModel,
    shift: FloatArray,
    found: NDArray[np.bool_],
    p: EdgeFitParams,
    max_shift_px: float,
    test_ends: tuple[float, float] | None = None,
    turns: int = 2,
) -> None:
    """The crossing passes, in place on ``shift`` and ``found`` (N): on a profile centred on
    each vertex moved by its ``shift``, the first half-contrast crossing from the patch's side,
    refined by the step of equal area over a window centred on it (the steepest point where
    every channel with contrast clips); where that lay more than ``recentre_px`` off the
    profile's centre, once more on a profile centred there (``turns`` 2; 1: not). With
    ``test_ends`` (``k_sigma``, ``min_gray``), the first profile's ends are also tested for an
    edge of the target."""
    count = round(2.0 * p.half_length_px / p.sample_px) + 1
    ends = max(round(p.end_px / p.sample_px) + 1, 1)
    weights, unit = _profile_weights(count, ends)
    # The second profile is centred on the first one's edge, so that its ends lie as far out
    # on either side; only where that edge lay more than ``recentre_px`` off the centre.
    offsets = unit * p.half_length_px
    at = np.arange(len(vertices))
    spread: FloatArray | None = None
    for turn in range(turns):
        raw, light = _profile(image, vertices[at], normals[at], shift[at], offsets, p.encoding)
        if turn == 0 and test_ends is not None:
            # The ends' colours as the sensor read them, in the codes the colour model knows.
            read_inner, read_outer = raw[:, :ends].mean(axis=1), raw[:, -ends:].mean(axis=1)
            step = read_inner - read_outer
            power = np.einsum("nc,nc->n", step, step)
            found &= _an_edge_between(
                read_inner, read_outer, power, model, *test_ends, p.min_contrast
            )
        profile = _unclipped(model, raw, light, ends, p.min_contrast, p.encoding)
        inner, outer, _ = np.einsum("nkc,jk->jnc", profile, weights)
        contrast, power, clipped = _contrast(inner, outer, found[at], p.encoding)
        if turn == 0:  # measured over every profile; the second turn redoes a few
            spread = _spread(profile, inner, outer, ends, found[at])
        contrast, power = _noise_weighted(contrast, power, spread)
        fraction = np.einsum("nkc,nc->nk", profile - outer[:, None, :], contrast)
        fraction /= power[:, None]
        edge, crossed = _half_crossing(fraction, offsets, p.sample_px)
        edge = _centred_step(fraction, offsets, edge, p.window_px)
        if np.any(clipped):
            steep, ok = _steepest(
                profile[clipped],
                inner[clipped] - outer[clipped],
                offsets,
                edge[clipped],
                p.window_px,
                p.encoding,
            )
            edge[clipped] = np.where(ok, steep, edge[clipped])
        found[at] &= crossed
        shift[at] = np.where(found[at], shift[at] + edge, 0.0)
        found &= np.abs(shift) <= max_shift_px
        shift[:] = np.where(found, shift, 0.0)
        at = at[found[at] & (np.abs(edge) > p.recentre_px)]
        if at.size == 0:
            break


def _along_the_curve(
    fitted: FloatArray, normals: FloatArray, found: NDArray[np.bool_], p: EdgeFitParams
) -> FloatArray:
    """The move (N px, along each normal) that puts each fitted point on the quadratic
    least-squares curve through it and its ``smooth_reach`` neighbours on either side (a
    Savitzky-Golay filter of their offsets along its normal): the noise of single profiles
    (sensor noise, JPEG blocks) averages out along the edge, and a straight or evenly curved
    edge is left where it is. Only where all of them measured an edge and the normals turn by
    less than ``_STRAIGHT`` across them (never across a corner); 0 elsewhere."""
    count = len(fitted)
    reach = p.smooth_reach
    if count < 2 * reach + 3:
        return np.zeros(count)
    weights = _savitzky_golay(reach)
    index = (np.arange(count)[:, None] + np.arange(-reach, reach + 1)[None, :]) % count
    offsets = np.einsum("nkc,nc->nk", fitted[index] - fitted[:, None, :], normals)
    cos_turn = np.einsum("nc,nc->n", normals[index[:, 0]], normals[index[:, -1]])
    smooth = found[index].all(axis=1) & (cos_turn > _STRAIGHT)
    return np.where(smooth, offsets @ weights, 0.0)


@lru_cache(maxsize=4)
def _savitzky_golay(reach: int) -> FloatArray:
    """Weights (2 reach + 1) of the quadratic least-squares fit's value at the centre of evenly
    spaced samples: (sum k⁴ - sum k² · k²) / (m sum k⁴ - (sum k²)²) over k = -reach..reach."""
    k2 = np.arange(-reach, reach + 1, dtype=np.float64) ** 2
    s2, s4 = k2.sum(), (k2 * k2).sum()
    weights = (s4 - s2 * k2) / (len(k2) * s4 - s2 * s2)
    weights.flags.writeable = False
    return weights


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
    count = len(fitted)
    index = (np.arange(count)[:, None] + np.array([-2, -1, 1, 2])[None, :]) % count
    offsets = np.einsum("nkc,nc->nk", fitted[index] - fitted[:, None, :], normals)
    # The median of four: their sum less the largest and the smallest, halved.
    middle = 0.5 * (offsets.sum(axis=1) - offsets.max(axis=1) - offsets.min(axis=1))
    around = found[index].sum(axis=1) >= 3
    cos_turn = np.einsum("nc,nc->n", normals[index[:, 1]], normals[index[:, 2]])
    smooth = cos_turn > _STRAIGHT
    # On a curve of turn θ [rad] between the neighbours' normals and segment L, the neighbours
    # sit ~1.25 θ L / 2 behind the tangent (θ ~ sqrt(2 (1 - cos θ)) at small turns).
    turn = np.sqrt(np.maximum(2.0 * (1.0 - cos_turn), 0.0))
    chord = fitted[index[:, 2]] - fitted[index[:, 1]]
    allowance = 0.3125 * turn * np.hypot(chord[:, 0], chord[:, 1])
    return found & around & smooth & (np.abs(middle) > max_kink_px + allowance)


def _profile(
    image, vertices, normals, shift, offsets, encoding: Encoding
) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Codes and light (each N, K, C; :func:`sample_codes_and_light`) sampled at ``offsets``
    (K px) along each normal about the vertex moved by ``shift`` (N px)."""
    centres = vertices + shift[:, None] * normals
    points = centres[:, None, :] + offsets[None, :, None] * normals[:, None, :]
    return sample_codes_and_light(image, points, encoding)


def _unclipped(
    model: ColorModel,
    raw: NDArray[np.float32],
    light: NDArray[np.float32],
    ends: int,
    min_contrast: float,
    encoding: Encoding,
) -> NDArray[np.float32]:
    """Profiles (N, K, C: ``light``, the light of the ``raw`` codes) with each sample's clipped
    channel put back where the target's colour has it
    (:func:`umbra.modules.vision.color.unclip`, on the codes the colour model knows: on the
    patch's side of the edge of a patch whose brightest channel saturates), then, where the
    channels that do not clip tell how the edge mixes, on the line that mixing draws
    (:func:`umbra.modules.vision.edge_mixing.unclip_by_mixing`, from the means of the profiles'
    ``ends`` samples and ``min_contrast`` gray levels of their step), so that channel mixes
    linearly across the edge and its half-contrast point is the edge's, not one moved out to
    where the clip ends."""
    flat = raw.reshape(-1, raw.shape[-1])
    by_model = unclip(model, flat).reshape(raw.shape)
    if encoding != "linear":  # the light of a put-back sample; every other one as sampled
        changed = by_model != raw
        by_model = (
            np.where(changed, to_light(by_model, encoding), light) if changed.any() else light
        )
    inner, outer = light[:, :ends].mean(axis=1), light[:, -ends:].mean(axis=1)
    top, floor, _ = _clip_levels(encoding)
    return unclip_by_mixing(light, by_model, inner, outer, top, floor, min_contrast)


@lru_cache(maxsize=4)
def _clip_levels(encoding: Encoding) -> tuple[float, float, float]:
    """The light of ``_CLIP_HIGH``, ``_CLIP_LOW`` and ``_PUT_BACK`` under ``encoding``."""
    levels = to_light(np.array([_CLIP_HIGH, _CLIP_LOW, _PUT_BACK]), encoding)
    return float(levels[0]), float(levels[1]), float(levels[2])


def _contrast(
    inner, outer, found, encoding: Encoding
) -> tuple[NDArray, NDArray, NDArray[np.bool_]]:
    """The colour step between the profile's ends (N x C, light under ``encoding``) over the
    channels that are not clipped at either end (a saturated or black channel does not mix
    linearly: its edge looks shifted towards the clipped side), its squared length (N; 1 where
    none), and where the full step had to be taken instead (N: every channel with contrast
    clipped)."""
    top, floor, put_back = _clip_levels(encoding)
    outer_linear = read_linearly(outer, top, floor)
    # A channel put back above the sensor's top (see _unclipped) mixes linearly again on the
    # patch's side.
    linear = (read_linearly(inner, top, floor) | (inner > put_back)) & outer_linear
    step = inner - outer
    contrast = np.where(linear, step, 0.0)
    power = np.einsum("nc,nc->n", contrast, contrast)
    # Where every channel with contrast is clipped, the full step is the best there is.
    weak = power < 0.25 * np.einsum("nc,nc->n", step, step)
    if np.any(weak):
        contrast = np.where(weak[:, None], step, contrast)
        power = np.einsum("nc,nc->n", contrast, contrast)
    return contrast, np.where(found & (power > 0.0), power, 1.0), weak & found


def _spread(
    profile: NDArray[np.float32],
    inner: NDArray[np.float32],
    outer: NDArray[np.float32],
    ends: int,
    found: NDArray[np.bool_],
) -> FloatArray | None:
    """The colours' covariance (C x C, gray levels²) about the profiles' end levels, over the
    ends of the profiles that found an edge: the sensor's noise, JPEG's coarser colour and the
    background's texture, channel by channel and between channels. None with fewer than
    :data:`_MIN_SPREAD_PROFILES` profiles."""
    if int(found.sum()) < _MIN_SPREAD_PROFILES:
        return None
    channels = profile.shape[-1]
    if not found.all():
        profile, inner, outer = profile[found], inner[found], outer[found]
    inside = (profile[:, :ends] - inner[:, None]).reshape(-1, channels)
    outside = (profile[:, -ends:] - outer[:, None]).reshape(-1, channels)
    moments = inside.T @ inside + outside.T @ outside
    spread = moments.astype(np.float64) / (len(inside) + len(outside))
    return spread + _SPREAD_FLOOR * np.eye(channels)


def _noise_weighted(
    contrast: FloatArray, power: FloatArray, spread: FloatArray | None
) -> tuple[FloatArray, FloatArray]:
    """The direction each profile is read along (N x C) and its product with the step (N):
    the step weighted by the inverse of the colours' ``spread`` over the channels the step uses
    (generalised least squares: a channel that JPEG or the background's texture makes noisier,
    or two that vary together, count less), scaled so that the mean channel counts as before.
    As it was without a spread."""
    if spread is None:
        return contrast, power
    used = contrast != 0.0
    if used.all():  # the usual case: every channel in every profile
        direction = contrast @ _scaled_inverse(spread)
    else:
        codes = used @ (1 << np.arange(used.shape[1]))  # which channels each profile uses
        direction = np.zeros_like(contrast)
        for code in np.unique(codes):
            pattern = (int(code) >> np.arange(used.shape[1])) & 1 == 1
            if pattern.any():
                rows = codes == code
                weight = _scaled_inverse(spread[np.ix_(pattern, pattern)])
                direction[np.ix_(rows, pattern)] = contrast[np.ix_(rows, pattern)] @ weight
    product = np.einsum("nc,nc->n", contrast, direction)
    return direction, np.where(product > 0.0, product, power)


def _scaled_inverse(spread: FloatArray) -> FloatArray:
    """``spread``'s inverse, scaled so that a channel of the mean variance weighs one."""
    return np.linalg.inv(spread) * (np.trace(spread) / len(spread))


def _centred_step(
    fraction: FloatArray, offsets: FloatArray, centre: FloatArray, window_px: float
) -> FloatArray:
    """The step of equal area within ``centre ± window_px`` (N px) of each profile (N, K,
    mixing fraction at evenly spaced ``offsets``, taken as linear between samples): exact for a
    straight edge under any symmetric blur that the window holds, whatever lies beyond it."""
    spacing = float(offsets[1] - offsets[0])
    lo, hi = offsets[0] + window_px, offsets[-1] - window_px
    centre = np.clip(centre, lo, hi)
    steps = 0.5 * spacing * (fraction[:, 1:] + fraction[:, :-1])
    cumulative = np.concatenate([np.zeros((len(fraction), 1)), np.cumsum(steps, axis=1)], axis=1)

    def area_to(s: FloatArray) -> FloatArray:
        x = (s - offsets[0]) / spacing
        i = np.clip(np.floor(x).astype(np.intp), 0, len(offsets) - 2)
        f = x - i
        rows = np.arange(len(fraction))
        t0, t1 = fraction[rows, i], fraction[rows, i + 1]
        return cumulative[rows, i] + spacing * (f * t0 + 0.5 * f * f * (t1 - t0))

    area = area_to(centre + window_px) - area_to(centre - window_px)
    return np.clip(centre - window_px + area, centre - window_px, centre + window_px)


def _steepest(
    profile: NDArray[np.float32],
    step: FloatArray,
    offsets: FloatArray,
    centre: FloatArray,
    reach_px: float,
    encoding: Encoding,
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Where each profile (N, K, C light under ``encoding`` at ``offsets`` K px) falls fastest
    within ``reach_px`` of ``centre`` (N px), channel by channel: a symmetric blur's line spread
    peaks at the edge, whatever the colours at the ends. Where every channel with contrast clips (a
    white background, a patch saturated in all its bright channels), the half-contrast point between
    the clipped ends lies towards the clipped side; a channel's steepest point does not, as long as
    the channel reads below the sensor's top there. Each channel's peak of its central difference
    (in the direction of its ``step``, N x C: inner minus outer) is placed by a parabola through it
    and its neighbours. Where the clip hides the difference just past the steepest one seen, the
    parabola goes through that one and the two before it and may place the peak up to one sample
    beyond it (against a wall at 1.14x the sensor's top, edges at any angle: 0.05-0.09 px inside the
    edge on average, up to 0.24 px when such peaks were left out). The channels whose peak is placed
    are averaged, weighted by their step squared. Returns (edge px, found: a channel's peak placed
    within the reach)."""
    spacing = float(offsets[1] - offsets[0])
    sign = np.sign(step)[:, None, :]
    slope = sign * (profile[:, :-2] - profile[:, 2:])  # (N, K - 2, C), at offsets[1:-1]
    middle = offsets[1:-1]
    top, floor, _ = _clip_levels(encoding)
    lit = read_linearly(profile, top, floor)
    seen = lit[:, :-2] & lit[:, 1:-1] & lit[:, 2:]  # the difference reads no clipped sample
    near = np.abs(middle[None, :] - centre[:, None]) <= reach_px  # (N, K - 2)
    candidates = np.where(seen & near[:, :, None], slope, -np.inf)
    k = np.argmax(candidates, axis=1)  # (N, C)
    rows = np.arange(len(profile))[:, None]
    channels = np.arange(profile.shape[2])[None, :]
    # Two places more on either side, none of them a difference or clipped: index i is i + 2.
    margin = ((0, 0), (2, 2), (0, 0))
    padded = np.pad(candidates, margin, constant_values=-np.inf)
    hidden = np.pad(~seen, margin, constant_values=False)

    def value(index: NDArray[np.intp]) -> FloatArray:
        """The candidate difference at ``index`` (N x C); -inf outside the profile."""
        return padded[rows, index + 2, channels]

    def clipped(index: NDArray[np.intp]) -> NDArray[np.bool_]:
        """Whether the difference at ``index`` (N x C) reads a clipped sample."""
        return hidden[rows, index + 2, channels]

    before, at, after = value(k - 1), value(k), value(k + 1)
    both = np.isfinite(before) & np.isfinite(after)
    # The clip hides the next difference outwards (inwards): the peak lies that way.
    out = ~both & clipped(k + 1) & np.isfinite(before) & np.isfinite(value(k - 2))
    into = ~both & ~out & clipped(k - 1) & np.isfinite(after) & np.isfinite(value(k + 2))
    middle_index = k - out + into  # the parabola's middle sample
    y0, y1, y2 = value(middle_index - 1), value(middle_index), value(middle_index + 1)
    peak = (both | out | into) & np.isfinite(y0) & np.isfinite(y1) & np.isfinite(y2) & (at > 0.0)
    y0, y1, y2 = (np.where(peak, y, 0.0) for y in (y0, y1, y2))
    curvature = y0 - 2.0 * y1 + y2
    peak &= curvature < 0.0
    delta = np.where(peak, 0.5 * (y0 - y2) / np.where(peak, curvature, -1.0), 0.0)
    # Between the neighbours of the steepest difference seen, or up to one sample past it.
    low = np.where(into, -2.0, -0.5)
    high = np.where(out, 2.0, 0.5)
    peak &= (delta >= low) & (delta <= high)
    position = middle[middle_index] + delta * spacing  # (N, C)
    weight = np.where(peak, step * step, 0.0)
    total = weight.sum(axis=1)
    found = total > 0.0
    edge = (weight * position).sum(axis=1) / np.where(found, total, 1.0)
    return np.where(found, edge, centre), found


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
    t = fraction[np.arange(len(fraction))[:, None], index]
    s_mean = s.mean(axis=1, keepdims=True)
    t_mean = t.mean(axis=1, keepdims=True)
    slope = ((s - s_mean) * (t - t_mean)).sum(axis=1) / ((s - s_mean) ** 2).sum(axis=1)
    crossed &= slope < 0.0
    safe = np.where(crossed, slope, -1.0)
    crossing = s_mean[:, 0] + (0.5 - t_mean[:, 0]) / safe
    return np.where(crossed, crossing, 0.0), crossed


#: Cosine of the largest turn between two neighbours' normals where a contour is taken as smooth.
_STRAIGHT = float(np.cos(np.deg2rad(20.0)))
#: Fewest profiles with an edge whose ends measure the colours' spread (fewer: channels weigh
#: by their step alone).
_MIN_SPREAD_PROFILES = 8
#: Added to each channel's measured variance [gray levels²]: a channel flat at its ends (a
#: clipped one, a uniform background) is not trusted without bound.
_SPREAD_FLOOR = 1.0
#: Channel levels beyond which a sample is taken as clipped by the sensor [gray levels].
_CLIP_HIGH, _CLIP_LOW = 240.0, 2.0
#: An 8-bit sensor reads at most this: an end's channel above it was put back (see
#: :func:`_unclipped`) [gray levels].
_PUT_BACK = float(np.iinfo(np.uint8).max)


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
    before = following(edges, -1)  # the edge into vertex i
    turn = turns(vertices)  # at vertex i, outward (convex) positive
    # Cyclic windows by slicing arrays extended past the end: column k is vertex i + k.
    reach = max_cut + 2
    index = np.arange(count)[:, None] + np.arange(-1, reach)[None, :]
    index %= count
    around = turn[index]  # (N, max_cut + 3): vertex i - 1 .. i + max_cut + 1
    good = found[index]
    straight = np.abs(around) < _STRAIGHT_TURN
    convex = np.cumprod(around[:, 1:] > -_STRAIGHT_TURN, axis=1).astype(bool)
    total = np.cumsum(around[:, 1:], axis=1)
    starts, cuts, tips = [], [], []
    for g in range(1, max_cut + 1):  # the shortest stretches first
        ok = (total[:, g] > min_turn_rad) & convex[:, g]
        ok &= straight[:, 0] & straight[:, g + 2]  # runs into b and out of c
        ok &= good[:, 0] & good[:, 1] & good[:, g + 1] & good[:, g + 2]
        b = np.flatnonzero(ok)
        if b.size == 0:
            continue
        c = (b + g) % count
        # b + s d1 = c - r d2  ->  [d1, d2] [s, r] = c - b
        d1, d2, gap = before[b], edges[c], vertices[c] - vertices[b]
        det = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
        det = np.where(np.abs(det) < 1e-12, np.nan, det)
        s_ = (gap[:, 0] * d2[:, 1] - gap[:, 1] * d2[:, 0]) / det
        r_ = (d1[:, 0] * gap[:, 1] - d1[:, 1] * gap[:, 0]) / det
        limit = max_reach_px * g
        ok = (s_ > 0) & (r_ > 0)
        ok &= s_ * np.hypot(d1[:, 0], d1[:, 1]) <= limit
        ok &= r_ * np.hypot(d2[:, 0], d2[:, 1]) <= limit
        starts.extend(b[ok].tolist())
        cuts.extend([g] * int(ok.sum()))
        tips.extend((vertices[b[ok]] + s_[ok, None] * d1[ok]).tolist())
    if not starts:
        return vertices
    keep = np.ones(count, dtype=bool)
    taken: set[int] = set()
    after: dict[int, list[float]] = {}
    points = vertices.tolist()
    for start, cut, corner in zip(starts, cuts, tips, strict=True):
        span = [(start + k) % count for k in range(cut + 1)]
        if taken.intersection(span):
            continue
        taken.update(span)
        keep[span[1:-1]] = False
        # b and c lie on the lines through the corner: one within a pixel of it adds nothing
        # but a sliver of a segment.
        for end in (span[0], span[-1]):
            if math.hypot(points[end][0] - corner[0], points[end][1] - corner[1]) < 1.0:
                keep[end] = False
        after[start] = corner
    at = np.fromiter(after, dtype=np.intp)
    placed = np.insert(vertices, at + 1, np.array(list(after.values())), axis=0)
    return placed[np.insert(keep, at + 1, True)]


#: A turn below this between two segments is a straight run [rad].
_STRAIGHT_TURN = float(np.deg2rad(12.0))
