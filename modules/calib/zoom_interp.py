"""Interpolation of zoom-camera parameters between tabulated normalized zooms: the one rule.

Every parameter (intrinsics, distortion, extrinsics) is linear between the two neighbouring
tabulated zooms, as the Sandia report does (section 5.6); ``zoom`` must lie in
``[zooms[0], zooms[-1]]`` (no extrapolation). CamCalib, ``umbra calib zoom``, the cameras file of
``umbra calib pose`` and the Active Sketch rig all interpolate through :func:`interpolate`
(via :meth:`umbra.modules.calib.zoom_table.ZoomTable.sample`).

Other laws for the focal length (geometric in the zoom, a monotone cubic through ``log f``) predict
the report's own interior zooms better when each is left out (``benchmarks/bench_calib.py``:
max 1.4 % against 77.5 %), but they were chosen on that same table, and there is no second bench
calibration to test them on; they also disagree with the report's cameras where it matters (at
zoom 0.5, 5150 px against the report's 7850 px). Until a calibration they were not tuned on shows
otherwise, one rule, the report's, everywhere.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]

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


def interpolate(
    zooms: ArrayLike,
    intrinsics: ArrayLike,
    extrinsics: ArrayLike,
    zoom: float,
) -> tuple[FloatArray, FloatArray]:
    """Parameters at ``zoom``, each linear between the neighbouring tabulated zooms.

    Args:
        zooms: ``(n,)`` tabulated normalized zooms, increasing.
        intrinsics: ``(n, 9)`` rows ``fx fy skew u0 v0 k1 k2 p1 p2`` (pixels; distortion unitless).
        extrinsics: ``(n, 6)`` rows ``dx dy dz rx ry rz`` (the table's units).
        zoom: the query, in 0..1 and within the tabulated range.

    Returns:
        ``(intrinsics (9,), extrinsics (6,))``.
    """
    z_tab = check_zooms(zooms)
    intr = np.asarray(intrinsics, dtype=float)
    extr = np.asarray(extrinsics, dtype=float)
    z = _check_query(z_tab, zoom)
    exact = np.flatnonzero(z_tab == z)
    if len(exact):  # a tabulated zoom: the table's own values, bit for bit
        return intr[exact[0]].copy(), extr[exact[0]].copy()
    return _linear(z_tab, intr, z), _linear(z_tab, extr, z)


def leave_one_out(
    zooms: ArrayLike, intrinsics: ArrayLike, extrinsics: ArrayLike
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
        got_i, got_e = interpolate(z_tab[keep], intr[keep], extr[keep], z_tab[i])
        rows["zoom"].append(z_tab[i])
        rows["fx_rel"].append(got_i[FX] / intr[i, FX] - 1.0)
        rows["fy_rel"].append(got_i[FY] / intr[i, FY] - 1.0)
        rows["principal_px"].append(float(np.linalg.norm(got_i[3:5] - intr[i, 3:5])))
        rows["skew_px"].append(abs(got_i[SKEW] - intr[i, SKEW]))
        rows["translation"].append(float(np.linalg.norm(got_e[:3] - extr[i, :3])))
        rows["rotation"].append(float(np.max(np.abs(got_e[3:] - extr[i, 3:]))))
    return {k: np.asarray(v, dtype=float) for k, v in rows.items()}
