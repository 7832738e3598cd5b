"""Which distortion model the calibration data hold: tangential terms kept, radial terms tested.

Radial terms the data do not hold trade against the focal length and the principal point (on
undistorted data, 40 points at 0.3 px, the report's four-term model came out with
``k2 = -0.87`` and ``fx`` 792.5 px against 800). Tangential terms trade against the principal
point alone, and a real decentring of a few thousandths moves the pixels by a few tenths of a
pixel in a pattern that a few dozen points cannot tell from a shifted principal point: no test
on the residuals keeps them at 0.3-0.5 px of click noise, and dropping real ones moves ``u0 v0``
by more than their stated errors. So :func:`calibrate_choosing_distortion` always fits the
tangential terms ``p1 p2`` (the report's model has them; where they are absent the fit's
standard errors say what they cost), and adds the radial terms ``k1 k2`` only when they lower
the residuals by more than chance would: the F test

    F = ((SSR_t - SSR_rt) / 2) / (SSR_rt / (m - p_rt))

of the fit with them (``rt``, ``p_rt`` parameters) against the fit without (``t``) over ``m =
2n`` pixel coordinates, at the ``RADIAL_P_VALUE`` level (1 %: at most about one undistorted rig
in a hundred gains radial terms). With fewer pairs than the tangential model needs, the camera
without distortion is fitted. The reason printed names each candidate's RMS and the test.
"""

from __future__ import annotations

from dataclasses import dataclass

from numpy.typing import ArrayLike

from umbra.modules.calib.errors import DegenerateGeometryError
from umbra.modules.calib.refine import CalibrationResult, DistortionTerms, calibrate

#: candidate models: name -> the distortion terms refined (OpenCV's order k1 k2 p1 p2)
CANDIDATES: dict[str, DistortionTerms] = {
    "none": 0,
    "p1p2": ("p1", "p2"),
    "k1k2": 2,
    "k1k2p1p2": 4,
}
#: the radial terms are kept when the F test's p-value is below this
RADIAL_P_VALUE = 0.01


@dataclass(frozen=True)
class DistortionChoice:
    """The chosen model's name, each fitted candidate's RMS (px), the radial terms' F statistic
    and p-value (None when not tested), and why."""

    chosen: str
    rms_px: dict[str, float]
    radial_f: float | None = None
    radial_p_value: float | None = None

    @property
    def reason(self) -> str:
        rows = ", ".join(f"{name} RMS {rms:.3f} px" for name, rms in self.rms_px.items())
        if self.radial_p_value is None:
            return f"distortion {self.chosen}: too few pairs for the tangential terms ({rows})"
        verdict = "kept" if self.radial_p_value < RADIAL_P_VALUE else "left out"
        return (
            f"distortion {self.chosen}: tangential p1 p2 always fitted; radial k1 k2 {verdict} "
            f"(F test of the residuals F = {self.radial_f:.2f}, p = {self.radial_p_value:.3g}, "
            f"kept below {RADIAL_P_VALUE:g}); {rows}"
        )


def radial_test(without: CalibrationResult, with_radial: CalibrationResult) -> tuple[float, float]:
    """The F statistic and p-value of the radial terms: ``with_radial`` against ``without``
    (see the module docstring)."""
    from scipy.stats import f as f_distribution

    m = with_radial.residuals.size
    extra = with_radial.parameter_count - without.parameter_count
    dof = m - with_radial.parameter_count
    if dof <= 0 or with_radial.ssr_px2 <= 0.0:
        return float("inf"), 0.0
    drop = max(without.ssr_px2 - with_radial.ssr_px2, 0.0)
    statistic = (drop / extra) / (with_radial.ssr_px2 / dof)
    return float(statistic), float(f_distribution.sf(statistic, extra, dof))


def calibrate_choosing_distortion(
    points: ArrayLike, pixels: ArrayLike, fix_skew: bool = False
) -> tuple[CalibrationResult, DistortionChoice]:
    """Fit the tangential model and the radial-and-tangential one and return the fit the F test
    prefers, with the table (the camera without distortion when the pairs cannot fix p1 p2)."""
    try:
        tangential = calibrate(points, pixels, CANDIDATES["p1p2"], fix_skew=fix_skew)
    except DegenerateGeometryError:
        bare = calibrate(points, pixels, CANDIDATES["none"], fix_skew=fix_skew)
        return bare, DistortionChoice("none", {"none": bare.rms_px})
    try:
        both = calibrate(points, pixels, CANDIDATES["k1k2p1p2"], fix_skew=fix_skew)
    except DegenerateGeometryError:
        return tangential, DistortionChoice("p1p2", {"p1p2": tangential.rms_px})
    statistic, p_value = radial_test(tangential, both)
    chosen = "k1k2p1p2" if p_value < RADIAL_P_VALUE else "p1p2"
    rms = {"p1p2": tangential.rms_px, "k1k2p1p2": both.rms_px}
    fit = both if chosen == "k1k2p1p2" else tangential
    return fit, DistortionChoice(chosen, rms, statistic, p_value)
