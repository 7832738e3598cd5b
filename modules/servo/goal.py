"""The servo goal ``s* = (x_n*, y_n*, a_n*, alpha*)`` from user-facing settings.

Two ways to say where the camera should end the approach:

* in pixels: the patch's target area (px^2), centre (px) and roll (rad) in the image, as an
  operator would read them off a teach image;
* in metres: a standoff (patch depth along the optical axis at the goal), with the patch
  centred on a pixel (default the principal point) and at a roll.

Both need the patch's physical area (m^2) and the intrinsics, because the features measure
absolute distance: ``a_n* = sqrt(A / a*)`` (= the standoff), ``x_n* = a_n* x_g*``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from umbra.modules.calib.camera_model import Intrinsics
from umbra.modules.servo.features import FeatureError, MomentFeatures


def goal_from_pixels(
    area_px: float,
    centre_px: ArrayLike,
    roll: float,
    intrinsics: Intrinsics,
    patch_area_m2: float,
) -> MomentFeatures:
    """Goal features from a target image of the patch.

    Args:
        area_px: patch area in the image at the goal (px^2).
        centre_px: patch centroid ``(u, v)`` at the goal (px).
        roll: principal-axis angle at the goal (rad, from +u towards +v).
        intrinsics: camera intrinsics (px).
        patch_area_m2: physical patch area (m^2).
    """
    if not area_px > 0:
        raise FeatureError(f"goal area must be positive, got {area_px} px^2")
    if not patch_area_m2 > 0:
        raise FeatureError(f"patch area must be positive, got {patch_area_m2} m^2")
    area = area_px / (intrinsics.fx * intrinsics.fy)  # affine map: det = fx fy
    xg, yg = intrinsics.normalized_from_pixels(np.asarray(centre_px, dtype=float))
    a_n = float(np.sqrt(patch_area_m2 / area))
    return MomentFeatures(x_n=a_n * float(xg), y_n=a_n * float(yg), a_n=a_n, alpha=float(roll))


def goal_from_standoff(
    standoff_m: float,
    intrinsics: Intrinsics,
    centre_px: ArrayLike | None = None,
    roll: float = 0.0,
) -> MomentFeatures:
    """Goal features for a patch at depth ``standoff_m`` centred on ``centre_px``.

    Args:
        standoff_m: depth of the patch along the optical axis at the goal (m).
        intrinsics: camera intrinsics (px).
        centre_px: pixel the patch centre should sit on (default: the principal point).
        roll: principal-axis angle at the goal (rad).
    """
    if not standoff_m > 0:
        raise FeatureError(f"standoff must be positive, got {standoff_m} m")
    centre = (intrinsics.u0, intrinsics.v0) if centre_px is None else centre_px
    xg, yg = intrinsics.normalized_from_pixels(np.asarray(centre, dtype=float))
    return MomentFeatures(
        x_n=standoff_m * float(xg), y_n=standoff_m * float(yg), a_n=standoff_m, alpha=float(roll)
    )


def goal_area_px(standoff_m: float, intrinsics: Intrinsics, patch_area_m2: float) -> float:
    """Image area (px^2) of the patch at ``standoff_m``: ``fx fy A / Z^2``."""
    return intrinsics.fx * intrinsics.fy * patch_area_m2 / standoff_m**2
