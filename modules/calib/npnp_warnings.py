"""What an nPnP solution must say: a bad given start, a rival minimum, residuals above noise.

``found`` holds the converged starts of :func:`umbra.modules.calib.npnp.solve_npnp`, best first, as
``(start name, R, d, residuals (px, flat), iterations)``; ``failed`` the starts that did not
converge, with the reason.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

#: the name of the caller's own start
GIVEN = "the given initial pose"
#: Least click noise assumed [px per coordinate]: the noise estimated from the best residual (or
#: a ``pixel_sigma`` of 0) is floored here, about the precision of the best sub-pixel corner
#: detection. Noise-free clicks (a zero residual) then give a finite rival-minimum test: a rival
#: pose counts as fitting "about as well" only if its extra cost is within what 0.01 px explains.
MIN_PIXEL_SIGMA = 0.01


def _angle_deg(R_a: FloatArray, R_b: FloatArray) -> float:
    """The angle [deg] of the rotation between two rotation matrices (from the trace: exact
    enough away from 0 and 180 deg, where these messages only need a rounded figure)."""
    cos = 0.5 * (float(np.trace(R_a.T @ R_b)) - 1.0)
    return float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))


@lru_cache(maxsize=256)
def _chi2_quantile(probability: float, dof: int) -> float:
    """The chi-square quantile (cached: the same few are asked for on every solve)."""
    from scipy.stats import chi2

    return float(chi2.ppf(probability, dof))


def pose_warnings(
    found: list[tuple[str, FloatArray, FloatArray, FloatArray, int]],
    failed: dict[str, str],
    given: bool,
    pixel_sigma: float | None,
) -> tuple[str, ...]:
    """Messages for the caller (empty: nothing to say), each naming what went wrong.

    The rival-minimum test divides by the click noise variance [px^2]: ``pixel_sigma`` squared
    when given, else the best cost per degree of freedom; either is floored at
    ``MIN_PIXEL_SIGMA`` squared, so a zero residual (noise-free clicks) gives a finite test.
    """
    out = []
    name, R, _, r, _ = found[0]
    best_cost = float(r @ r)
    dof = max(r.size - 6, 1)
    rms = float(np.sqrt(best_cost / (r.size / 2)))
    if given and name != GIVEN:
        if GIVEN in failed:
            out.append(
                f"bad start: from the given initial pose the solver failed ({failed[GIVEN]}); "
                f"the pose comes from {name} (RMS {rms:.2f} px)"
            )
        else:
            mine = next(f for f in found if f[0] == GIVEN)
            mine_rms = float(np.sqrt(float(mine[3] @ mine[3]) / (r.size / 2)))
            if mine_rms > rms * (1 + 1e-6) + 1e-9:
                out.append(
                    f"bad start: the given initial pose led to a worse minimum (RMS "
                    f"{mine_rms:.2f} px, {_angle_deg(mine[1], R):.1f} deg from the best); the "
                    f"pose comes from {name} (RMS {rms:.2f} px)"
                )
    # another minimum, clearly elsewhere, that fits within what the noise allows
    noise_var = best_cost / dof if pixel_sigma is None else pixel_sigma**2
    noise_var = max(noise_var, MIN_PIXEL_SIGMA**2)
    for other in found[1:]:
        angle = _angle_deg(other[1], R)
        extra = (float(other[3] @ other[3]) - best_cost) / noise_var
        if angle > 2.0 and extra < _chi2_quantile(0.95, 6):
            other_rms = float(np.sqrt(float(other[3] @ other[3]) / (r.size / 2)))
            out.append(
                f"degenerate geometry: another pose {angle:.1f} deg away ({other[0]}) fits the "
                f"clicks about as well (RMS {other_rms:.2f} vs {rms:.2f} px); add points or "
                "snapshots that tell them apart"
            )
            break
    if pixel_sigma is not None and pixel_sigma > 0:
        limit = _chi2_quantile(0.999, dof)
        if best_cost / pixel_sigma**2 > limit:
            expected = pixel_sigma * np.sqrt(2.0 * limit / r.size)
            out.append(
                f"residuals above the click noise: RMS {rms:.2f} px where clicks of "
                f"{pixel_sigma:g} px explain at most {expected:.2f} px (99.9 %): a wrong click or "
                "camera model, or no start reached the true minimum"
            )
    return tuple(out)
