"""Sensor and lighting effects of the simulated camera: gain, color cast, motion blur, noise.

All effects work on an H x W x 3 BGR image; gains are unitless, lengths in pixels, noise in
gray levels (0..255). Effects are applied in the order of the physics: the scene radiance is
scaled by the lighting (gain times per-channel cast), smeared by motion during the exposure,
then the sensor adds noise and quantizes to 8 bits with clipping at 0 and 255.
"""

from __future__ import annotations

from dataclasses import dataclass
from statistics import NormalDist

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class Lighting:
    """Lighting and sensor: ``gain`` (overall), ``cast_rgb`` (per-channel gains, R G B order),
    ``noise_sigma`` [gray levels], motion blur ``blur_length_px`` [px] along ``blur_angle_rad``
    (from the u axis towards v). Built from validated parameters (DigiCam's and SketchCam's
    ``Params`` hold their signs), not checked again here."""

    gain: float = 1.0
    cast_rgb: tuple[float, float, float] = (1.0, 1.0, 1.0)
    noise_sigma: float = 0.0
    blur_length_px: float = 0.0
    blur_angle_rad: float = 0.0


def motion_blur_kernel(length_px: float, angle_rad: float) -> NDArray[np.float32]:
    """Normalized kernel of a straight motion of ``length_px`` along ``angle_rad``."""
    size = 2 * int(np.ceil(length_px / 2.0)) + 3
    kernel = np.zeros((size, size), dtype=np.float64)
    centre = size // 2
    t = np.linspace(-length_px / 2.0, length_px / 2.0, max(int(8 * length_px), 2))
    x = centre + t * np.cos(angle_rad)
    y = centre + t * np.sin(angle_rad)
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = x - x0, y - y0
    for dx, dy, w in ((0, 0, (1 - fx) * (1 - fy)), (1, 0, fx * (1 - fy)), (0, 1, (1 - fx) * fy)):
        np.add.at(kernel, (y0 + dy, x0 + dx), w)
    np.add.at(kernel, (y0 + 1, x0 + 1), fx * fy)
    return (kernel / kernel.sum()).astype(np.float32)


def _noise_table() -> NDArray[np.float32]:
    """256 equiprobable standard-normal quantiles, rescaled to unit variance."""
    inverse_cdf = NormalDist().inv_cdf  # to 1e-15 of scipy's ndtri: the same float32 table
    quantiles = np.array([inverse_cdf(p) for p in (np.arange(256) + 0.5) / 256.0])
    table = (quantiles / quantiles.std()).astype(np.float32).reshape(1, 256)
    table.flags.writeable = False
    return table


_UNIT_NOISE = _noise_table()


class Sensor:
    """Applies :class:`Lighting` to frames of one size, reusing its scratch buffers (a fresh
    3.7 MB float image per step costs more in page faults than the arithmetic). Not thread-safe:
    one sensor per rendering thread.

    The sensor noise of a frame is a window of a fixed bank of ``NOISE_BANK_FRAMES`` frames'
    worth of 8-bit picks (seeded ``NOISE_BANK_SEED``), at an offset drawn per frame from the
    ``rng`` given to :meth:`apply`: each frame's noise is independent from pixel to pixel, the
    noise a pixel gets changes from frame to frame, and a frame depends on the ``rng`` alone, at
    a cost of one random integer per frame instead of one random byte per pixel and channel (7 ms
    of a 28 ms 720p render).
    """

    NOISE_BANK_FRAMES = 4
    NOISE_BANK_SEED = 20260

    def __init__(self, shape: tuple[int, int, int]) -> None:
        self.shape = shape
        self._scaled = np.empty(shape, dtype=np.float32)
        self._blurred = np.empty(shape, dtype=np.float32)
        self._noise = np.empty(shape, dtype=np.float32)
        self._bank: NDArray[np.uint8] | None = None

    def _picks(self, rng: np.random.Generator) -> NDArray[np.uint8]:
        """This frame's noise picks: uniform bytes, one per pixel and channel."""
        size = int(np.prod(self.shape))
        if self._bank is None:
            bank = np.random.default_rng(self.NOISE_BANK_SEED)
            self._bank = np.frombuffer(bank.bytes(size * self.NOISE_BANK_FRAMES), dtype=np.uint8)
        start = int(rng.integers(0, size * (self.NOISE_BANK_FRAMES - 1) + 1))
        return self._bank[start : start + size].reshape(self.shape)

    def apply(
        self, image_bgr: NDArray[np.uint8], lighting: Lighting, rng: np.random.Generator
    ) -> NDArray[np.uint8]:
        """The image as the sensor records it under ``lighting``; noise drawn from ``rng``.

        Noise is Gaussian with ``noise_sigma`` gray levels, per pixel and channel one of 256
        equiprobable normal quantiles (the variance is exact and the tails reach 2.9 sigma),
        picked from the noise bank (see the class). Returns a new uint8 image.
        """
        import cv2

        if image_bgr.shape != self.shape:
            raise ValueError(f"sensor is set up for shape {self.shape}, got {image_bgr.shape}")
        cast_bgr = np.array(lighting.cast_rgb[::-1], dtype=np.float64) * lighting.gain
        blur = lighting.blur_length_px >= 0.5
        unit_gain = bool(np.all(cast_bgr == 1.0))
        if lighting.noise_sigma == 0 and not blur and unit_gain:
            return image_bgr.copy()
        radiance: NDArray = image_bgr
        if not unit_gain or blur:
            # cv2's stubs omit the per-channel scalar (a tuple) that cv2.multiply takes as src2.
            scalar = (*cast_bgr.tolist(), 0.0)
            radiance = cv2.multiply(image_bgr, scalar, dst=self._scaled, dtype=cv2.CV_32F)  # type: ignore[call-overload]
        if blur:
            kernel = motion_blur_kernel(lighting.blur_length_px, lighting.blur_angle_rad)
            radiance = cv2.filter2D(
                radiance, -1, kernel, dst=self._blurred, borderType=cv2.BORDER_REFLECT
            )
        if lighting.noise_sigma == 0:
            # cv2's stubs omit the scalar src2; dtype=CV_8U makes the result uint8 (no copy here).
            quantized = cv2.add(radiance, 0.0, dtype=cv2.CV_8U)  # type: ignore[call-overload]
            return np.asarray(quantized, dtype=np.uint8)
        table = _UNIT_NOISE * np.float32(lighting.noise_sigma)
        noise = cv2.LUT(self._picks(rng), table, dst=self._noise)
        # Saturating conversion: rounds to the nearest gray level and clips to 0..255.
        return np.asarray(cv2.add(radiance, noise, dtype=cv2.CV_8U), dtype=np.uint8)


def apply_lighting(
    image_bgr: NDArray[np.uint8], lighting: Lighting, rng: np.random.Generator
) -> NDArray[np.uint8]:
    """One-off :meth:`Sensor.apply` (allocates its buffers; keep a :class:`Sensor` for video)."""
    return Sensor(image_bgr.shape).apply(image_bgr, lighting, rng)
