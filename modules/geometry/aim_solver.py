"""Aiming a camera on a two-axis head with its whole camera model: Newton on the pixel error.

A head (pan-tilt unit, the Rochester head) carries a camera mount whose pose in the reference
frame depends on two angles, ``T_ref_mount(a, b)``. The closed-form aims put a point on the
mount's nominal axis; a real camera sits in its mount at a small rotation and offset (the zoom
file's ``SR_cam_ext``, different at each zoom), has its principal point off the image centre and
distorts. At a long focal length a hundredth of a radian of mount rotation moves the target
hundreds of pixels (0.02 rad at 29600 px is 590 px).

:func:`aim_pixel` starts from the closed form and corrects the two angles by Newton's method on
the projected pixel error: the pixel of the point, through the whole camera model at the current
zoom, minus the wanted pixel (by default the principal point, where the optic axis meets the
image). The 2x2 Jacobian is taken by central differences; a step that does not reduce the error
is halved. Metres, radians, pixels.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]

#: pixel error (px) at which the aim is done
TOLERANCE_PX = 0.01
#: angle step (rad) of the central-difference Jacobian
_STEP_RAD = 1e-6


class AimSolveError(ValueError):
    """The camera cannot be brought to look at the point (behind it, or no convergence)."""


def aim_pixel(
    T_ref_mount: Callable[[float, float], FloatArray],
    project_mount: Callable[[FloatArray], FloatArray],
    point_ref: ArrayLike,
    start: tuple[float, float],
    pixel: ArrayLike,
    *,
    tolerance_px: float = TOLERANCE_PX,
    max_iterations: int = 30,
) -> tuple[float, float]:
    """The two head angles ``(a, b)`` (rad) that show ``point_ref`` at ``pixel``.

    Args:
        T_ref_mount: the mount's 4x4 pose in the reference frame at angles ``(a, b)``.
        project_mount: pixels ``(2,)`` (as the image shows them, distortion included) of a point
            ``(3,)`` given in the mount frame (metres); NaN or an exception when the point is
            behind the camera.
        point_ref: the point (m, reference frame).
        start: initial angles, e.g. the closed-form aim of the mount's axis.
        pixel: the wanted pixel ``(u, v)`` (px).

    Raises:
        AimSolveError: when the error does not fall below ``tolerance_px``.
    """
    p = np.append(np.asarray(point_ref, dtype=float).reshape(3), 1.0)
    target = np.asarray(pixel, dtype=float).reshape(2)

    def error(angles: FloatArray) -> FloatArray:
        T = np.asarray(T_ref_mount(float(angles[0]), float(angles[1])), dtype=float)
        try:
            uv = np.asarray(project_mount(np.linalg.solve(T, p)[:3]), dtype=float).reshape(2)
        except ValueError:
            return np.full(2, np.nan)
        return uv - target

    angles = np.asarray(start, dtype=float).reshape(2)
    r = error(angles)
    if not np.all(np.isfinite(r)):
        raise AimSolveError(
            f"the point {np.round(p[:3], 4).tolist()} m is not in front of the camera at the "
            f"starting angles {np.round(np.degrees(angles), 2).tolist()} deg"
        )
    for _ in range(max_iterations):
        if np.linalg.norm(r) < tolerance_px:
            return float(angles[0]), float(angles[1])
        J = np.empty((2, 2))
        for k in range(2):
            h = np.zeros(2)
            h[k] = _STEP_RAD
            J[:, k] = (error(angles + h) - error(angles - h)) / (2.0 * _STEP_RAD)
        if not np.all(np.isfinite(J)) or abs(np.linalg.det(J)) < 1e-12:
            break
        step = np.linalg.solve(J, -r)
        for _halving in range(20):
            trial = angles + step
            r_trial = error(trial)
            if np.all(np.isfinite(r_trial)) and np.linalg.norm(r_trial) < np.linalg.norm(r):
                angles, r = trial, r_trial
                break
            step = step / 2.0
        else:
            break
    if np.linalg.norm(r) < tolerance_px:
        return float(angles[0]), float(angles[1])
    raise AimSolveError(
        f"cannot centre the point {np.round(p[:3], 4).tolist()} m: {np.linalg.norm(r):.2f} px "
        f"from pixel {np.round(target, 2).tolist()} after Newton's method"
    )
