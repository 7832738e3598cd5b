"""Which distortion model the calibration data hold: the Bayesian information criterion.

Fitting distortion terms the data do not hold trades them against the focal length and the
principal point (on undistorted data, 40 points at 0.3 px, the report's four-term model came out
with ``k2 = -0.87`` and ``fx`` 792.5 px against 800). :func:`calibrate_choosing_distortion` fits
each candidate model (none, ``k1 k2``, ``k1 k2 p1 p2``) and keeps the one with the lowest

    BIC = m ln(SSR / m) + p ln(m)

over ``m = 2n`` pixel coordinates, ``p`` fitted parameters and the sum of squared residuals
``SSR`` (px²): each extra term must lower the residuals by more than chance would (about a factor
``m^(1/m)`` per parameter) to be kept. The reason printed names every candidate's BIC and RMS.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from umbra.modules.calib.errors import DegenerateGeometryError
from umbra.modules.calib.refine import CalibrationResult, calibrate

#: candidate models: name -> number of distortion terms (OpenCV's order k1 k2 p1 p2)
CANDIDATES = {"none": 0, "k1k2": 2, "k1k2p1p2": 4}


@dataclass(frozen=True)
class DistortionChoice:
    """The chosen model's name, each candidate's BIC (lower is better) and RMS (px), and why."""

    chosen: str
    bic: dict[str, float]
    rms_px: dict[str, float]

    @property
    def reason(self) -> str:
        rows = ", ".join(
            f"{name} {self.bic[name]:.1f} (RMS {self.rms_px[name]:.3f} px)" for name in self.bic
        )
        return (
            f"distortion {self.chosen}: lowest Bayesian information criterion "
            f"m ln(SSR/m) + p ln(m) among {rows}; terms that do not lower the residuals by more "
            "than noise would are left out"
        )


def information_criterion(result: CalibrationResult) -> float:
    """BIC of a refined fit (see the module docstring)."""
    m = result.residuals.size
    return float(m * np.log(result.ssr_px2 / m) + result.parameter_count * np.log(m))


def calibrate_choosing_distortion(
    points: ArrayLike, pixels: ArrayLike, fix_skew: bool = False
) -> tuple[CalibrationResult, DistortionChoice]:
    """Fit every candidate distortion model and return the fit the BIC prefers, with the table.

    Candidates with more parameters than the pairs can fix are skipped.
    """
    fits: dict[str, CalibrationResult] = {}
    for name, terms in CANDIDATES.items():
        try:
            fits[name] = calibrate(points, pixels, distortion_terms=terms, fix_skew=fix_skew)
        except DegenerateGeometryError:
            if not fits:
                raise
    bic = {name: information_criterion(fit) for name, fit in fits.items()}
    chosen = min(bic, key=bic.get)
    rms = {name: fit.rms_px for name, fit in fits.items()}
    return fits[chosen], DistortionChoice(chosen, bic, rms)
