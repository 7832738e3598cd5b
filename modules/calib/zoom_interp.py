"""Interpolation of zoom-camera parameters between tabulated normalized zooms.

Methods (``zoom`` in ``[zooms[0], zooms[-1]]``; no extrapolation):

* ``"linear"`` — every parameter linear between the two neighbouring zooms, as the Sandia report
  does (section 5.6).
* ``"geometric"`` — focal lengths linear in ``log f`` (a zoom lens's focal length grows roughly
  geometrically with the zoom setting); skew as a fraction of ``fx``; the rest linear.
* ``"pchip"`` — focal lengths by a monotone cubic (PCHIP) through ``log f``, which follows the
  curvature of the focal-length law without overshooting; skew as a fraction of ``fx``; the rest
  linear (principal point, distortion and extrinsics are noisy bench measurements with no smooth
  law to follow).

:func:`leave_one_out` measures each method on a table by predicting each interior zoom from the
others.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import PchipInterpolator

FloatArray = NDArray[np.float64]

METHODS = ("linear", "geometric", "pchip")
#: Default method, chosen by leave-one-out on the report's table (see benchmarks/bench_calib.py).
DEFAULT_METHOD = "pchip"

FX, FY, SKEW = 0, 1, 2


def check_zooms(zooms: ArrayLike) -> FloatArray:
    """Validate tabulated zooms: finite, within 0..1, strictly increasing, at least one."""
    z = np.asarray(zooms, dtype=float)
    if z.ndim != 1 or len(z) == 0:
        raise ValueError("a zoom table needs at least one zoom")
    if not np.all(np.isfinite(z)) or z.min() < 0.0 or z.max() > 1.0:
        raise ValueError(f"tabulated zooms must lie in 0..1, got {z.tolist()}")
    if np.any(np.diff(z) <= 0):
        raise ValueError(f"tabulated zooms must increase strictly, got {z.tolist()}")
    return z


def _check_query(zooms: FloatArray, zoom: float) -> float:
    z = float(zoom)
    if not np.isfinite(z) or z < 0.0 or z > 1.0:
        raise ValueError(f"zoom must be a normalized value in 0..1, got {zoom}")
    if z < zooms[0] - 1e-12 or z > zooms[-1] + 1e-12:
        raise ValueError(
            f"zoom {z:g} is outside the calibrated range {zooms[0]:g}..{zooms[-1]:g} "
            "(the table is not extrapolated)"
        )
    return min(max(z, float(zooms[0])), float(zooms[-1]))


def _linear(zooms: FloatArray, values: FloatArray, z: float) -> FloatArray:
    return np.array([np.interp(z, zooms, column) for column in values.T])


def _focal(zooms: FloatArray, focal: FloatArray, z: float, method: str) -> float:
    if np.any(focal <= 0):
        raise ValueError("focal lengths must be positive to interpolate them geometrically")
    logs = np.log(focal)
    if method == "geometric" or len(zooms) < 3:
        return float(np.exp(np.interp(z, zooms, logs)))
    return float(np.exp(PchipInterpolator(zooms, logs)(z)))


def interpolate(
    zooms: ArrayLike,
    intrinsics: ArrayLike,
    extrinsics: ArrayLike,
    zoom: float,
    method: str = DEFAULT_METHOD,
) -> tuple[FloatArray, FloatArray]:
    """Parameters at ``zoom``.

    Args:
        zooms: ``(n,)`` tabulated normalized zooms, increasing.
        intrinsics: ``(n, 9)`` rows ``fx fy skew u0 v0 k1 k2 p1 p2`` (pixels; distortion unitless).
        extrinsics: ``(n, 6)`` rows ``dx dy dz rx ry rz`` (the table's units).
        zoom: the query, in 0..1 and within the tabulated range.
        method: one of :data:`METHODS`.

    Returns:
        ``(intrinsics (9,), extrinsics (6,))``.
    """
    if method not in METHODS:
        raise ValueError(f"unknown interpolation method {method!r}; expected one of {METHODS}")
    z_tab = check_zooms(zooms)
    intr = np.asarray(intrinsics, dtype=float)
    extr = np.asarray(extrinsics, dtype=float)
    z = _check_query(z_tab, zoom)
    exact = np.flatnonzero(z_tab == z)
    if len(exact):  # a tabulated zoom: the table's own values, bit for bit
        return intr[exact[0]].copy(), extr[exact[0]].copy()
    out_intr = _linear(z_tab, intr, z)
    out_extr = _linear(z_tab, extr, z)
    if method != "linear":
        out_intr[FX] = _focal(z_tab, intr[:, FX], z, method)
        out_intr[FY] = _focal(z_tab, intr[:, FY], z, method)
        skew_ratio = np.interp(z, z_tab, intr[:, SKEW] / intr[:, FX])
        out_intr[SKEW] = skew_ratio * out_intr[FX]
    return out_intr, out_extr


def leave_one_out(
    zooms: ArrayLike, intrinsics: ArrayLike, extrinsics: ArrayLike, method: str
) -> dict[str, FloatArray]:
    """Predict each interior tabulated zoom from the others.

    Returns arrays over the interior zooms: ``zoom``, ``fx_rel`` and ``fy_rel`` (relative focal
    errors, signed), ``principal_px`` (principal-point error, pixels), ``skew_px``,
    ``translation`` (extrinsic translation error, table units) and ``rotation`` (largest angle
    error, table units).
    """
    z_tab = check_zooms(zooms)
    intr = np.asarray(intrinsics, dtype=float)
    extr = np.asarray(extrinsics, dtype=float)
    rows: dict[str, list[float]] = {
        k: []
        for k in ("zoom", "fx_rel", "fy_rel", "principal_px", "skew_px", "translation", "rotation")
    }
    for i in range(1, len(z_tab) - 1):
        keep = np.arange(len(z_tab)) != i
        got_i, got_e = interpolate(z_tab[keep], intr[keep], extr[keep], z_tab[i], method)
        rows["zoom"].append(z_tab[i])
        rows["fx_rel"].append(got_i[FX] / intr[i, FX] - 1.0)
        rows["fy_rel"].append(got_i[FY] / intr[i, FY] - 1.0)
        rows["principal_px"].append(float(np.linalg.norm(got_i[3:5] - intr[i, 3:5])))
        rows["skew_px"].append(abs(got_i[SKEW] - intr[i, SKEW]))
        rows["translation"].append(float(np.linalg.norm(got_e[:3] - extr[i, :3])))
        rows["rotation"].append(float(np.max(np.abs(got_e[3:] - extr[i, 3:]))))
    return {k: np.asarray(v, dtype=float) for k, v in rows.items()}
