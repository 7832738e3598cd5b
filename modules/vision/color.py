"""Color statistics of the tracked patch: normalized chromaticity, its spread, Mahalanobis gate.

Color space. A pixel (R, G, B) is reduced to its normalized chromaticity

    (r, g) = (R, G) / s,   s = R + G + B

which is exactly invariant to a lighting gain (auto-iris, exposure, distance to the lamp all
scale R, G and B together): the Sandia authors moved the snake to color precisely because
brightness is what changes most between frames. A color cast (per-channel gains, a change of
illuminant) moves the chromaticity of a patch by a small, smooth shift; rather than a space
that is invariant to casts too (log-chromaticity ratios are, in theory, but they explode on the
near-zero channels of a saturated patch under sensor noise), the statistics are adapted online
from pixels just inside the tracked contour (:func:`adapt`), which absorbs a slow cast or an
illuminant drift while the snake is tracking.

Spread. Sensor noise is additive in gray levels, so the chromaticity of a dim pixel scatters
more than that of a bright one: ``(r, g) - mean`` scales as 1/s. The model therefore keeps the
covariance of ``x = ((r, g) - mean) * s`` -- the pixel's offset from the patch's color ray
through black, in gray levels -- which stays the same at any gain, plus a small chromaticity
floor for the patch's own color variation (texture, clipping), which scales with ``s``. A pixel
with offset ``x`` and sum ``s`` belongs to the target when

    x^T (A + s² f I)^-1 x <= k²

with ``A`` the offset covariance [gray levels²] and ``f`` the floor [chromaticity²]. A model
learned at one gain thus holds at another. Dark pixels carry no usable chromaticity, so pixels
whose mean gray level is below ``min_gray`` never count as the target.

Clipping. A channel at the sensor's top (``CLIP_GRAY``) no longer scales with the light, so a
bright patch whose strongest channel saturates drifts off its own chromaticity. Before the gate,
such a pixel's clipped channel is put back where the target's colour ray through its unclipped
channels has it (:func:`unclip`), when that is above the clip and below ``UNCLIP_MAX``; any other
clipped pixel is judged as it is.

Images are H x W x 3 uint8 in BGR order (OpenCV's).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]

#: Default chromaticity floor (standard deviation of the patch's own chromaticity, unitless).
DEFAULT_CHROMA_FLOOR = 0.006
#: Default smallest offset spread [gray levels]: a noiseless synthetic seed would otherwise give a
#: singular covariance that rejects the patch's own anti-aliased edges.
DEFAULT_NOISE_FLOOR = 1.5


@dataclass(frozen=True, eq=False)
class ColorModel:
    """Target color: ``mean`` chromaticity (r, g); ``offset_covariance`` (2x2, gray levels²) of
    ``((r, g) - mean) * (R + G + B)``; ``chroma_floor`` (standard deviation, unitless)."""

    mean: FloatArray
    offset_covariance: FloatArray
    chroma_floor: float = DEFAULT_CHROMA_FLOOR

    def __post_init__(self) -> None:
        mean = np.asarray(self.mean, dtype=np.float64).reshape(2)
        cov = np.asarray(self.offset_covariance, dtype=np.float64).reshape(2, 2)
        cov = 0.5 * (cov + cov.T)
        if not np.all(np.isfinite(cov)) or np.linalg.det(cov) <= 0.0 or cov[0, 0] <= 0.0:
            raise ValueError(f"color covariance must be positive definite, got {cov.tolist()}")
        if self.chroma_floor < 0:
            raise ValueError(f"chroma floor must be >= 0, got {self.chroma_floor}")
        object.__setattr__(self, "mean", mean)
        object.__setattr__(self, "offset_covariance", cov)

    def covariance_at(self, total: float) -> FloatArray:
        """Chromaticity covariance (2x2, unitless) expected for pixels with R + G + B = total."""
        return self.offset_covariance / total**2 + self.chroma_floor**2 * np.eye(2)


def chromaticity(bgr: ArrayLike) -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray]:
    """(r, g, s) of BGR pixels (any leading shape, last axis 3): chromaticity and R + G + B."""
    pixels = np.asarray(bgr, dtype=np.float32)
    total = pixels.sum(axis=-1)
    safe = np.maximum(total, 1.0)
    return pixels[..., 2] / safe, pixels[..., 1] / safe, total


def _offsets(rg: FloatArray, total: FloatArray, mean: FloatArray) -> FloatArray:
    return (rg - mean) * total[:, None]


def fit(
    bgr_samples: ArrayLike,
    min_gray: float = 20.0,
    noise_floor: float = DEFAULT_NOISE_FLOOR,
    chroma_floor: float = DEFAULT_CHROMA_FLOOR,
) -> ColorModel:
    """Learn the model from ``bgr_samples`` (K x 3, or any shape ending in 3): the mean
    chromaticity and the covariance of the offsets, plus ``noise_floor``² [gray levels²].

    Dark samples (mean gray below ``min_gray``) are left out. Raises ValueError if fewer than 3
    usable samples remain.
    """
    r, g, total = chromaticity(np.asarray(bgr_samples).reshape(-1, 3))
    usable = total >= 3.0 * min_gray
    if int(usable.sum()) < 3:
        raise ValueError(
            f"need at least 3 seed pixels brighter than gray level {min_gray:g}, "
            f"found {int(usable.sum())} of {r.size}"
        )
    rg = np.column_stack([r[usable], g[usable]]).astype(np.float64)
    mean = rg.mean(axis=0)
    offsets = _offsets(rg, total[usable].astype(np.float64), mean)
    cov = np.cov(offsets, rowvar=False)
    return ColorModel(mean, cov + noise_floor**2 * np.eye(2), chroma_floor)


def from_rgb(
    rgb: ArrayLike, noise_gray: float = 6.0, chroma_floor: float = DEFAULT_CHROMA_FLOOR
) -> ColorModel:
    """A model centred on the chromaticity of one RGB color (0..255), with an isotropic offset
    spread of ``noise_gray`` gray levels."""
    red, green, blue = (float(c) for c in np.asarray(rgb, dtype=np.float64).reshape(3))
    total = red + green + blue
    if total <= 0.0:
        raise ValueError("a black target color has no chromaticity")
    if noise_gray <= 0:
        raise ValueError(f"noise_gray must be > 0, got {noise_gray}")
    return ColorModel(
        np.array([red / total, green / total]), noise_gray**2 * np.eye(2), chroma_floor
    )


def mahalanobis_squared(model: ColorModel, r: NDArray, g: NDArray, total: NDArray) -> NDArray:
    """Squared Mahalanobis distance (unitless) of pixels with chromaticity (r, g) and sum
    ``total`` = R + G + B to the model, with the spread expected at that brightness."""
    x1 = (r - model.mean[0]) * total
    x2 = (g - model.mean[1]) * total
    floor = model.chroma_floor**2 * np.square(total)
    (a11, a12), (_, a22) = model.offset_covariance
    q11, q22 = a11 + floor, a22 + floor
    det = q11 * q22 - a12 * a12
    return (q22 * x1 * x1 - 2.0 * a12 * x1 * x2 + q11 * x2 * x2) / det


def is_target(
    model: ColorModel, bgr: ArrayLike, k_sigma: float = 3.0, min_gray: float = 20.0
) -> NDArray[np.bool_]:
    """True where a BGR pixel is within ``k_sigma`` Mahalanobis of the model and not dark."""
    pixels = np.asarray(bgr, dtype=np.float32)
    r, g, total = chromaticity(unclip(model, pixels.reshape(-1, 3)).reshape(pixels.shape))
    inside = mahalanobis_squared(model, r, g, total) <= k_sigma * k_sigma
    return inside & (total >= 3.0 * min_gray)


#: A channel at or above this gray level is taken as clipped by the sensor: its true value is
#: that or more.
CLIP_GRAY = 250.0
#: Highest value a clipped channel is put back at [gray levels]: a lighting gain of 1.6 on a
#: full channel. A pixel whose unclipped channels would put it higher is brighter than any
#: target seen so and stays as it is (a white background behind a red patch: its green and blue
#: are the red patch's at four times the gain).
UNCLIP_MAX = 1.6 * 255.0
#: Least length of the target's colour ray (unit sum) over the unclipped channels: below it they
#: carry too little of the target's colour to stand for it.
_MIN_UNCLIPPED_SHARE = 0.1


def unclip(model: ColorModel, pixels: NDArray[np.float32]) -> NDArray[np.float32]:
    """``pixels`` (K x 3 BGR, float) with each clipped channel put back where the target's
    colour would have it, on the pixels whose unclipped channels fit the target's colour ray at
    a brightness that clips those channels, and at most ``UNCLIP_MAX`` (a bright patch whose
    strongest channel saturates: its chromaticity is the target's again); every other pixel is
    returned as it is, so a clipped pixel of another colour stays as far from the target as it
    was. The gate then judges the pixel's unclipped channels."""
    top = np.float32(CLIP_GRAY)
    if pixels.size == 0 or pixels.max() < top:  # the usual case: nothing clipped
        return pixels
    b, g, r = pixels[:, 0], pixels[:, 1], pixels[:, 2]  # (a max over axis 1 is 100x slower)
    some = (b >= top) | (g >= top) | (r >= top)
    rows = np.flatnonzero(some & ((b < top) | (g < top) | (r < top)))
    if rows.size == 0:
        return pixels
    red, green = model.mean
    ray = np.array([1.0 - red - green, green, red], dtype=np.float32)  # B, G, R per unit sum
    sub = pixels[rows]
    off = sub >= top
    on = np.where(off, np.float32(0.0), ray)
    weight = np.einsum("kc,kc->k", on, on)
    scale = np.einsum("kc,kc->k", sub, on) / np.maximum(weight, np.float32(1e-12))
    expected = scale[:, None] * ray
    put_back = (expected >= np.float32(CLIP_GRAY)) & (expected <= np.float32(UNCLIP_MAX))
    fits = (weight >= np.float32(_MIN_UNCLIPPED_SHARE**2)) & np.all(~off | put_back, axis=1)
    if not fits.any():
        return pixels
    out = pixels.copy()
    fixed = rows[fits]
    out[fixed] = np.where(off[fits], expected[fits], sub[fits])
    return out


def offset_matrix(model: ColorModel) -> NDArray[np.float32]:
    """3x3 matrix ``M`` with ``p @ M = [x1, x2, s]`` for a BGR row vector ``p``: the two offsets
    ``((r, g) - mean) * s`` are linear in the pixel (no division), and ``s = R + G + B``."""
    mean_r, mean_g = model.mean
    # Rows: B, G, R. Columns: (r - mean_r) s, (g - mean_g) s, s.
    return np.array(
        [[-mean_r, -mean_g, 1.0], [-mean_r, 1.0 - mean_g, 1.0], [1.0 - mean_r, -mean_g, 1.0]],
        dtype=np.float32,
    )


def gate_test(
    model: ColorModel,
    offsets: NDArray[np.float32],
    k_sigma: float,
    min_gray: float,
) -> NDArray[np.bool_]:
    """Target test for rows ``[x1, x2, s]`` from :func:`offset_matrix`, without division."""
    x1, x2, total = offsets[:, 0], offsets[:, 1], offsets[:, 2]
    (a11, a12), (_, a22) = model.offset_covariance
    floor = np.float32(model.chroma_floor**2) * total * total
    q11 = floor + np.float32(a11)
    q22 = floor + np.float32(a22)
    a12 = np.float32(a12)
    lhs = q22 * x1 * x1 - 2.0 * a12 * x1 * x2 + q11 * x2 * x2
    rhs = np.float32(k_sigma * k_sigma) * (q11 * q22 - a12 * a12)
    return (lhs <= rhs) & (total >= np.float32(3.0 * min_gray))


def adapt(
    model: ColorModel,
    bgr_samples: ArrayLike,
    rate: float,
    gate_sigma: float = 6.0,
    min_gray: float = 20.0,
    noise_floor: float = DEFAULT_NOISE_FLOOR,
) -> ColorModel:
    """Blend the statistics of new target samples into the model (exponential forgetting).

    Only samples within ``gate_sigma`` of the current model and brighter than ``min_gray`` count,
    so background pixels near a mis-placed vertex cannot drag the model away. ``rate`` in [0, 1]
    is the weight of the new samples. Returns the model unchanged when fewer than 8 samples pass.
    """
    if not 0.0 <= rate <= 1.0:
        raise ValueError(f"adaptation rate must be within [0, 1], got {rate}")
    pixels = unclip(model, np.asarray(bgr_samples, dtype=np.float32).reshape(-1, 3))
    r, g, total = chromaticity(pixels)
    distance = mahalanobis_squared(model, r, g, total)
    keep = (distance <= gate_sigma * gate_sigma) & (total >= 3.0 * min_gray)
    if rate == 0.0 or int(keep.sum()) < 8:
        return model
    rg = np.column_stack([r[keep], g[keep]]).astype(np.float64)
    sums = total[keep].astype(np.float64)
    sample_mean = rg.mean(axis=0)
    mean = (1.0 - rate) * model.mean + rate * sample_mean
    # Both covariances are taken about the blended mean, in offset units (gray levels²).
    offsets = _offsets(rg, sums, mean)
    offsets -= offsets.mean(axis=0)
    sample_cov = offsets.T @ offsets / len(offsets)  # np.cov(..., bias=True), without overhead
    shift = (model.mean - mean) * float(np.mean(sums))
    old_cov = model.offset_covariance + np.outer(shift, shift)
    cov = (1.0 - rate) * old_cov + rate * (sample_cov + noise_floor**2 * np.eye(2))
    return ColorModel(mean, cov, model.chroma_floor)
