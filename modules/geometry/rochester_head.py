"""The Rochester camera head: CamPos from altitude and azimuth, and aiming a camera at a point.

The chain of Table 1, links A9..A14 (section 6), all in FLANGE coordinates (Z out of the head,
Y down, X right)::

    CamPos = A9 A10 A11 A12 A13 A14
    A9  = Trans(0, NECK_OFFSET, 0)              neck offset
    A10 = Trans(LEFT_OFFSET or RIGHT_OFFSET, 0, 0)  eye offset: -> CamAxis (L, R)
    A11 = Rot_x(phi)                            altitude (pitch), shared by both cameras
    A12 = Trans(0, ALT_OFFSET, 0)               camera axis to pitch axis
    A13 = Rot_y(theta)                          azimuth (yaw), one per camera
    A14 = Trans(0, 0, AZ_OFFSET)                yaw axis to nodal point: -> CamPos (L, R)

CamPos's Z is the camera's optic axis, Y down, X right (the imaging model of section 4). The
constants of section 13 (millimetres there) are metres here. Positive ``phi`` tilts the optic
axis towards FLANGE -Y (up); positive ``theta`` turns it towards FLANGE +X (right).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.modules.geometry.aim_solver import AimSolveError, aim_pixel
from umbra.modules.geometry.transforms import compose, rot_x, rot_y, translation

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class HeadGeometry:
    """Head offsets (metres) of section 13.1; defaults are the guide's ``*consts.h`` values."""

    neck_offset: float = -0.1492  #: pitch axis to tool axis (NECK_OFFSET, -149.2 mm)
    left_offset: float = -0.0127  #: tool Z axis to left camera yaw axis (LEFT_OFFSET)
    right_offset: float = 0.1524  #: tool Z axis to right camera yaw axis (RIGHT_OFFSET)
    alt_offset: float = -0.0651  #: camera axis to pitch (altitude) axis (ALT_OFFSET)
    az_offset: float = 0.0349  #: nodal point to yaw (azimuth) axis (AZ_OFFSET)

    def eye_offset(self, side: str) -> float:
        """X offset of the yaw axis of camera ``side`` (``"left"`` or ``"right"``), metres."""
        if side == "left":
            return self.left_offset
        if side == "right":
            return self.right_offset
        raise ValueError(f"camera side must be 'left' or 'right', got {side!r}")


ROCHESTER_HEAD = HeadGeometry()


def T_flange_camaxis(side: str, head: HeadGeometry = ROCHESTER_HEAD) -> FloatArray:
    """``A9 A10``: the CamAxis frame of one camera in FLANGE (the last point rigid to FLANGE)."""
    return translation(0.0, head.neck_offset, 0.0) @ translation(head.eye_offset(side), 0.0, 0.0)


def T_flange_campos(
    altitude: float, azimuth: float, side: str, head: HeadGeometry = ROCHESTER_HEAD
) -> FloatArray:
    """CamPos of camera ``side`` in FLANGE (section 6) for altitude ``phi`` and azimuth ``theta``.

    Args:
        altitude: head altitude (pitch) ``phi``, radians.
        azimuth: that camera's azimuth (yaw) ``theta``, radians.
        side: ``"left"`` or ``"right"``.
    """
    return compose(
        T_flange_camaxis(side, head),
        rot_x(altitude),
        translation(0.0, head.alt_offset, 0.0),
        rot_y(azimuth),
        translation(0.0, 0.0, head.az_offset),
    )


def head_angles_from_campos(T_flange_campos: ArrayLike) -> tuple[float, float]:
    """``(phi, theta)`` radians that produced a CamPos (section 8).

    The rotation of ``E = A9 ... A14`` is ``Rot_x(phi) Rot_y(theta)`` (the other links are pure
    translations), so ``phi = atan2(E21, E11)`` and ``theta = atan2(E02, E00)``. Only the
    rotation is read.
    """
    E = np.asarray(T_flange_campos, dtype=float)
    phi = float(np.arctan2(E[2, 1], E[1, 1]))
    theta = float(np.arctan2(E[0, 2], E[0, 0]))
    return phi, theta


class AimError(ValueError):
    """The point cannot be centred in the camera (too close to the altitude axis)."""


def aim_camera_at_point(
    point_flange: ArrayLike, side: str, head: HeadGeometry = ROCHESTER_HEAD
) -> tuple[float, float]:
    """Altitude and azimuth (radians) that put ``point_flange`` on camera ``side``'s optic axis.

    Section 10, with the point taken relative to the camera's CamAxis origin (on the altitude
    axis). After ``Rot_x(phi)`` the optic axis lies in the plane ``y' = ALT_OFFSET`` of the
    rotated frame, so ``y cos(phi) + z sin(phi) = ALT_OFFSET``; with ``h = hypot(y, z)`` this is
    the guide's ``b = asin(d/h)``, ``phi = atan2(-y, z) - b`` for ``d = -ALT_OFFSET`` (the guide
    uses the magnitude of the offset). Then ``theta = atan2(x, z cos(phi) - y sin(phi))``.
    The asin branch is the one for points in front of the head (small angles), as in the guide.

    Args:
        point_flange: the point (metres) in FLANGE coordinates.
        side: ``"left"`` or ``"right"``.

    Returns:
        ``(phi, theta)`` radians.

    Raises:
        AimError: when the point is closer to the altitude axis than ``|ALT_OFFSET|``.
    """
    p = np.asarray(point_flange, dtype=float).reshape(-1)
    if p.shape != (3,):
        raise AimError(f"point_flange must be 3 numbers, got {point_flange!s}")
    x, y, z = p - T_flange_camaxis(side, head)[:3, 3]
    h = float(np.hypot(y, z))
    d = -head.alt_offset
    if h <= abs(d):
        raise AimError(
            f"point is {h:.4f} m from the altitude axis, must be farther than {abs(d):.4f} m"
        )
    b = float(np.arcsin(d / h))
    phi = float(np.arctan2(-y, z)) - b
    theta = float(np.arctan2(x, z * np.cos(phi) - y * np.sin(phi)))
    return phi, theta


def aim_camera_model_at_point(
    point_flange: ArrayLike,
    side: str,
    project_campos: Callable[[FloatArray], FloatArray],
    pixel: ArrayLike,
    head: HeadGeometry = ROCHESTER_HEAD,
) -> tuple[float, float]:
    """Altitude and azimuth (radians) that show ``point_flange`` at ``pixel`` in a real camera.

    The section-10 solution puts the point on CamPos's Z axis; a calibrated camera sits in CamPos
    with its own rotation and offset (``project_campos``: pixels of a point given in CamPos, the
    whole camera model, distortion included). Starting from section 10, Newton's method on the
    projected pixel error (:func:`umbra.modules.geometry.aim_solver.aim_pixel`) corrects both
    angles.

    Raises:
        AimError: the point is too close to the altitude axis, or cannot be brought to ``pixel``.
    """
    phi, theta = aim_camera_at_point(point_flange, side, head)
    try:
        return aim_pixel(
            lambda a, b: T_flange_campos(a, b, side, head),
            project_campos,
            point_flange,
            (phi, theta),
            pixel,
        )
    except AimSolveError as exc:
        raise AimError(str(exc)) from None
