"""OpenCV's lens distortion model (Brown-Conrady): distort, undistort points and images.

On normalized image coordinates ``(x, y)`` (metres over metres, camera frame, ideal pin-hole),
with ``r^2 = x^2 + y^2`` and coefficients ``(k1, k2, p1, p2[, k3])``:

    x_d = x (1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x y + p2 (r^2 + 2 x^2)
    y_d = y (1 + k1 r^2 + k2 r^4 + k3 r^6) + p1 (r^2 + 2 y^2) + 2 p2 x y

the model of section 5.1 of the Sandia report (which uses OpenCV's) and of ``cv2.projectPoints``.
Pixels are ``u = fx x + skew y + u0``, ``v = fy y + v0`` (``skew`` is 0 in OpenCV).

Two inversions of the model, for two uses:

* :func:`undistort_normalized_newton` (measurements: points, calibration, the servo): Newton's
  method to ``1e-14`` in normalized coordinates; a point with no inverse (beyond the fold of a
  strong barrel distortion, where the map stops being one-to-one) comes back as NaN.
* :func:`undistort_normalized_fixed_point` (images: the simulated camera's remap tables): OpenCV's
  ``undistortPoints`` iteration, a fixed number of steps, finite everywhere, if meaningless beyond
  the fold.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


def _coefficients(distortion: ArrayLike) -> tuple[float, float, float, float, float]:
    values = np.zeros(5)
    given = np.asarray(distortion, dtype=float).ravel()
    if given.size not in (0, 4, 5):
        raise ValueError(f"distortion needs 4 (k1 k2 p1 p2) or 5 (+k3) values, got {given.size}")
    values[: given.size] = given
    k1, k2, p1, p2, k3 = (float(v) for v in values)
    return k1, k2, p1, p2, k3


def distort_normalized(normalized: ArrayLike, distortion: ArrayLike) -> FloatArray:
    """Ideal normalized coordinates ``(..., 2)`` to distorted normalized coordinates."""
    k1, k2, p1, p2, k3 = _coefficients(distortion)
    xy = np.asarray(normalized, dtype=float)
    x, y = xy[..., 0], xy[..., 1]
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
    return np.stack([xd, yd], axis=-1)


def _jacobian(x: FloatArray, y: FloatArray, coefficients: tuple[float, ...]) -> tuple:
    k1, k2, p1, p2, k3 = coefficients
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    slope = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)  # d radial / d r^2
    dxx = radial + 2.0 * x * x * slope + 2.0 * p1 * y + 6.0 * p2 * x
    dxy = 2.0 * x * y * slope + 2.0 * p1 * x + 2.0 * p2 * y
    dyy = radial + 2.0 * y * y * slope + 6.0 * p1 * y + 2.0 * p2 * x
    return dxx, dxy, dxy, dyy


def undistort_normalized_newton(
    distorted: ArrayLike, distortion: ArrayLike, tolerance: float = 1e-14, max_iterations: int = 50
) -> FloatArray:
    """Distorted normalized coordinates ``(..., 2)`` to ideal ones (Newton's method).

    Exact to ``tolerance`` (the distorted residual, normalized coordinates); points where Newton's
    method does not get there, or lands beyond the fold (no inverse), are NaN.
    """
    coefficients = _coefficients(distortion)
    target = np.asarray(distorted, dtype=float)
    if not any(coefficients):
        return target.copy()
    xy = target.copy()
    for _ in range(max_iterations):
        residual = distort_normalized(xy, coefficients) - target
        if np.all(np.abs(residual) < tolerance):
            break
        a, b, c, d = _jacobian(xy[..., 0], xy[..., 1], coefficients)
        det = a * d - b * c
        step_x = (d * residual[..., 0] - b * residual[..., 1]) / det
        step_y = (a * residual[..., 1] - c * residual[..., 0]) / det
        xy = xy - np.stack([step_x, step_y], axis=-1)
    residual = np.abs(distort_normalized(xy, coefficients) - target).max(axis=-1)
    a, b, c, d = _jacobian(xy[..., 0], xy[..., 1], coefficients)
    # Beyond the fold the map reverses (an eigenvalue of its Jacobian turns negative): a solution
    # there is not the preimage the lens formed; the Jacobian must have det > 0 and trace > 0.
    unfolded = (a * d - b * c > 0) & (a + d > 0)
    xy[~((residual < 1e-9) & unfolded)] = np.nan
    return xy


def undistort_normalized_fixed_point(
    distorted: ArrayLike, distortion: ArrayLike, iterations: int = 30
) -> FloatArray:
    """Distorted normalized coordinates ``(..., 2)`` to ideal ones by ``iterations`` fixed-point
    steps ``x <- (x_d - tangential(x)) / radial(x)``, as OpenCV's ``undistortPoints``.

    Finite everywhere, also beyond the fold where no inverse exists (the renderer's margin and
    remap tables take such values; :func:`undistort_normalized_newton` gives NaN there). Its
    accuracy depends on the lens: over a 640 x 480 image at f = 600 px, 30 steps leave a distorted
    residual below ``1e-15`` for ``k1 = -0.12, k2 = 0.03, p1 = 0.001, p2 = -0.0007`` and for
    ``k1 = -0.3, k2 = 0.1`` (10 steps: ``2e-12`` and ``6e-8``); use the Newton one when the
    answer must be exact.
    """
    k1, k2, p1, p2, k3 = _coefficients(distortion)
    target = np.asarray(distorted, dtype=float)
    x_d, y_d = target[..., 0], target[..., 1]
    x, y = x_d.copy(), y_d.copy()
    for _ in range(iterations):
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        delta_x = 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
        delta_y = p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
        x = (x_d - delta_x) / radial
        y = (y_d - delta_y) / radial
    return np.stack([x, y], axis=-1)


def _normalized(pixels: FloatArray, K: FloatArray) -> FloatArray:
    y = (pixels[..., 1] - K[1, 2]) / K[1, 1]
    x = (pixels[..., 0] - K[0, 2] - K[0, 1] * y) / K[0, 0]
    return np.stack([x, y], axis=-1)


def _pixels(normalized: FloatArray, K: FloatArray) -> FloatArray:
    x, y = normalized[..., 0], normalized[..., 1]
    return np.stack([K[0, 0] * x + K[0, 1] * y + K[0, 2], K[1, 1] * y + K[1, 2]], axis=-1)


def distort_points(pixels: ArrayLike, K: ArrayLike, distortion: ArrayLike) -> FloatArray:
    """Ideal pin-hole pixels ``(..., 2)`` of camera ``K`` to the pixels the lens actually shows."""
    K = np.asarray(K, dtype=float)
    normalized = _normalized(np.asarray(pixels, dtype=float), K)
    return _pixels(distort_normalized(normalized, distortion), K)


def undistort_points(
    pixels: ArrayLike,
    K: ArrayLike,
    distortion: ArrayLike,
    new_K: ArrayLike | None = None,
    normalized: bool = False,
) -> FloatArray:
    """Measured pixels ``(..., 2)`` to ideal pin-hole pixels.

    Args:
        pixels: distorted pixels of camera ``K``.
        K: 3x3 intrinsic matrix.
        distortion: ``(k1, k2, p1, p2[, k3])``.
        new_K: intrinsics of the returned pixels (default ``K``).
        normalized: return normalized coordinates instead of pixels (as ``cv2.undistortPoints``
            does without its ``P`` argument).
    """
    K = np.asarray(K, dtype=float)
    ideal = undistort_normalized_newton(_normalized(np.asarray(pixels, dtype=float), K), distortion)
    if normalized:
        return ideal
    return _pixels(ideal, K if new_K is None else np.asarray(new_K, dtype=float))


def undistortion_maps(
    K: ArrayLike, distortion: ArrayLike, size: tuple[int, int], new_K: ArrayLike | None = None
) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Remap tables for undistorting an image of ``size = (width, height)`` pixels.

    For each pixel of the undistorted image (intrinsics ``new_K``, default ``K``) the tables give
    the position in the distorted source image; use them with ``cv2.remap``.
    """
    K = np.asarray(K, dtype=float)
    target_K = K if new_K is None else np.asarray(new_K, dtype=float)
    width, height = size
    u, v = np.meshgrid(np.arange(width, dtype=float), np.arange(height, dtype=float))
    ideal = _normalized(np.stack([u, v], axis=-1), target_K)
    source = _pixels(distort_normalized(ideal, distortion), K)
    return source[..., 0].astype(np.float32), source[..., 1].astype(np.float32)


def undistort_image(
    image: NDArray,
    K: ArrayLike,
    distortion: ArrayLike,
    new_K: ArrayLike | None = None,
    interpolation: int | None = None,
) -> NDArray:
    """Undistorted copy of ``image`` (any dtype and channel count), pixels outside set to 0;
    ``interpolation`` is an OpenCV flag (``None``: ``cv2.INTER_LINEAR``)."""
    import cv2  # lazy: tests/runtime/test_start_imports.py

    height, width = image.shape[:2]
    map_x, map_y = undistortion_maps(K, distortion, (width, height), new_K)
    if interpolation is None:
        interpolation = cv2.INTER_LINEAR
    return cv2.remap(image, map_x, map_y, interpolation, borderMode=cv2.BORDER_CONSTANT)
