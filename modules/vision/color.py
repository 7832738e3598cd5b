"""Color statistics of the tracked patch: normalized chromaticity, mean, covariance, Mahalanobis.

Color space. A pixel (R, G, B) is reduced to its normalized chromaticity

    (r, g) = (R, G) / (R + G + B)

which is exactly invariant to a lighting gain (auto-iris, exposure, distance to the lamp all
scale R, G and B together): the Sandia authors moved the snake to color precisely because
brightness is what changes most between frames. A color cast (per-channel gains, a change of
illuminant) moves the chromaticity of a patch by a small, smooth shift; rather than a space
that is invariant to casts too (log-chromaticity ratios are, in theory, but they explode on the
near-zero channels of a saturated patch under sensor noise), the statistics are adapted online
from pixels just inside the tracked contour (:func:`adapt`), which absorbs a slow cast or an
illuminant drift while the snake is tracking. Dark pixels carry no usable chromaticity (the
ratio of noise to noise), so pixels whose mean gray level is below ``min_gray`` never count as
the target. Saturation (a channel clipped at 255) also moves the chromaticity; adaptation
follows that too.

The model is the mean and covariance of (r, g) over the seed pixels; a pixel belongs to the
target when its Mahalanobis distance to the mean is within ``k`` standard deviations.

Images are H x W x 3 uint8 in BGR order (OpenCV's).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]

#: Smallest standard deviation of a chromaticity coordinate the model will assume. Without it a
#: noiseless synthetic seed would give a singular covariance that rejects the patch's own edges.
DEFAULT_SIGMA_FLOOR = 0.006


@dataclass(frozen=True, eq=False)
class ColorModel:
    """Gaussian model of the target's chromaticity: ``mean`` (r, g) and 2x2 ``covariance``."""

    mean: FloatArray
    covariance: FloatArray

    def __post_init__(self) -> None:
        mean = np.asarray(self.mean, dtype=np.float64).reshape(2)
        cov = np.asarray(self.covariance, dtype=np.float64).reshape(2, 2)
        if not np.all(np.isfinite(cov)) or np.linalg.det(cov) <= 0.0 or cov[0, 0] <= 0.0:
            raise ValueError(f"color covariance must be positive definite, got {cov.tolist()}")
        object.__setattr__(self, "mean", mean)
        object.__setattr__(self, "covariance", 0.5 * (cov + cov.T))

    @property
    def information(self) -> tuple[float, float, float]:
        """Entries (a, b, c) of the inverse covariance [[a, b], [b, c]]."""
        (s_rr, s_rg), (_, s_gg) = self.covariance
        det = s_rr * s_gg - s_rg * s_rg
        return s_gg / det, -s_rg / det, s_rr / det


def chromaticity(bgr: ArrayLike) -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray]:
    """(r, g, gray) of BGR pixels (any leading shape, last axis 3): chromaticity and mean gray."""
    pixels = np.asarray(bgr, dtype=np.float32)
    total = pixels.sum(axis=-1)
    safe = np.maximum(total, 1.0)
    return pixels[..., 2] / safe, pixels[..., 1] / safe, total / 3.0


def fit(
    bgr_samples: ArrayLike,
    min_gray: float = 20.0,
    sigma_floor: float = DEFAULT_SIGMA_FLOOR,
) -> ColorModel:
    """Mean and covariance of the chromaticity of ``bgr_samples`` (K x 3, or any shape ending in 3).

    Dark samples (mean gray below ``min_gray``) are left out. Raises ValueError if fewer than 3
    usable samples remain.
    """
    r, g, gray = chromaticity(np.asarray(bgr_samples).reshape(-1, 3))
    usable = gray >= min_gray
    if int(usable.sum()) < 3:
        raise ValueError(
            f"need at least 3 seed pixels brighter than gray level {min_gray:g}, "
            f"found {int(usable.sum())} of {r.size}"
        )
    rg = np.column_stack([r[usable], g[usable]]).astype(np.float64)
    mean = rg.mean(axis=0)
    cov = np.cov(rg, rowvar=False) if rg.shape[0] > 1 else np.zeros((2, 2))
    return ColorModel(mean, cov + sigma_floor**2 * np.eye(2))


def from_rgb(
    rgb: ArrayLike, sigma: float = 0.02, sigma_floor: float = DEFAULT_SIGMA_FLOOR
) -> ColorModel:
    """A model centred on the chromaticity of one RGB color (0..255), isotropic spread ``sigma``."""
    red, green, blue = (float(c) for c in np.asarray(rgb, dtype=np.float64).reshape(3))
    total = red + green + blue
    if total <= 0.0:
        raise ValueError("a black target color has no chromaticity")
    spread = max(sigma, sigma_floor) ** 2
    return ColorModel(np.array([red / total, green / total]), spread * np.eye(2))


def gate_matrix(model: ColorModel, k_sigma: float) -> NDArray[np.float32]:
    """A 3x3 matrix ``M`` that turns the Mahalanobis gate into one product per pixel.

    For a BGR pixel ``p`` (row vector, float), ``[y0, y1, s] = p @ M`` has ``s = R + G + B`` and
    ``y0² + y1² <= s²`` exactly when the pixel's chromaticity is within ``k_sigma`` of the model:
    ``(r - mean) * s`` is linear in ``p``, and the Cholesky factor of the inverse covariance,
    divided by ``k_sigma``, whitens it. No division per pixel.
    """
    mean_r, mean_g = model.mean
    # Rows: B, G, R. Columns: (r - mean_r) s, (g - mean_g) s.
    deviation = np.array(
        [[-mean_r, -mean_g], [-mean_r, 1.0 - mean_g], [1.0 - mean_r, -mean_g]], dtype=np.float64
    )
    a, b, c = model.information
    cholesky = np.linalg.cholesky(np.array([[a, b], [b, c]]))  # inverse covariance = C C^T
    matrix = np.empty((3, 3), dtype=np.float64)
    matrix[:, :2] = deviation @ cholesky / k_sigma
    matrix[:, 2] = 1.0
    return matrix.astype(np.float32)


def mahalanobis_squared(model: ColorModel, r: NDArray, g: NDArray) -> NDArray:
    """Squared Mahalanobis distance of chromaticities (r, g) to the model (unitless)."""
    a, b, c = model.information
    dr = r - model.mean[0]
    dg = g - model.mean[1]
    return a * dr * dr + 2.0 * b * dr * dg + c * dg * dg


def is_target(
    model: ColorModel, bgr: ArrayLike, k_sigma: float = 3.0, min_gray: float = 20.0
) -> NDArray[np.bool_]:
    """True where a BGR pixel is within ``k_sigma`` Mahalanobis of the model and not dark."""
    r, g, gray = chromaticity(bgr)
    return (mahalanobis_squared(model, r, g) <= k_sigma * k_sigma) & (gray >= min_gray)


def adapt(
    model: ColorModel,
    bgr_samples: ArrayLike,
    rate: float,
    gate_sigma: float = 6.0,
    min_gray: float = 20.0,
    sigma_floor: float = DEFAULT_SIGMA_FLOOR,
) -> ColorModel:
    """Blend the statistics of new target samples into the model (exponential forgetting).

    Only samples within ``gate_sigma`` of the current model and brighter than ``min_gray`` count,
    so background pixels near a mis-placed vertex cannot drag the model away. ``rate`` in [0, 1]
    is the weight of the new samples. Returns the model unchanged when fewer than 8 samples pass.
    """
    if not 0.0 <= rate <= 1.0:
        raise ValueError(f"adaptation rate must be within [0, 1], got {rate}")
    r, g, gray = chromaticity(np.asarray(bgr_samples).reshape(-1, 3))
    keep = (mahalanobis_squared(model, r, g) <= gate_sigma * gate_sigma) & (gray >= min_gray)
    if rate == 0.0 or int(keep.sum()) < 8:
        return model
    rg = np.column_stack([r[keep], g[keep]]).astype(np.float64)
    sample_mean = rg.mean(axis=0)
    sample_cov = np.cov(rg, rowvar=False) + sigma_floor**2 * np.eye(2)
    mean = (1.0 - rate) * model.mean + rate * sample_mean
    shift_old = np.outer(model.mean - mean, model.mean - mean)
    shift_new = np.outer(sample_mean - mean, sample_mean - mean)
    cov = (1.0 - rate) * (model.covariance + shift_old) + rate * (sample_cov + shift_new)
    return ColorModel(mean, cov)
