"""Kinematics of a pan-tilt unit (PTU) carrying a camera, and aiming it at a 3-D point.

The unit is modelled with the Rochester head's chain (``umbra.modules.geometry.rochester_head``):
its base frame ``ptu`` is the guide's FLANGE (Z forward out of the unit at zero angles, Y down,
X right); tilt is the altitude ``phi`` (``Rot_x``, positive tilts the axis up), pan is the
azimuth ``theta`` (``Rot_y`` on the tilt stage, positive turns right); ``tilt_offset`` is the
guide's ALT_OFFSET and ``nodal_offset`` its AZ_OFFSET. The camera's mount frame is the guide's
CamPos. Aiming is the guide's section-10 solution (:func:`aim_camera_at_point`) for the mount's
axis; given the camera model at the current zoom (intrinsics, distortion, and the camera's pose in
its mount, which the zoom file tabulates per zoom) it is corrected by Newton's method until the
point shows at the principal point (:func:`aim_camera_model_at_point`). Metres, radians.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.modules.calib.camera_model import PinholeCamera
from umbra.modules.geometry.rochester_head import (
    AimError,
    HeadGeometry,
    T_flange_campos,
    aim_camera_at_point,
    aim_camera_model_at_point,
)

FloatArray = NDArray[np.float64]


class PtuLimitError(ValueError):
    """An aim or command outside the unit's travel."""


@dataclass(frozen=True)
class PtuGeometry:
    """Offsets (m), travel (rad) and speed limits (rad/s, rad/s²) of a pan-tilt unit.

    Defaults are of the order of a FLIR PTU-D46: pan ±159°, tilt -47°..+31°, 1 rad/s.
    """

    tilt_offset: float = -0.04
    nodal_offset: float = 0.03
    pan_limits: tuple[float, float] = (-2.775, 2.775)
    tilt_limits: tuple[float, float] = (-0.82, 0.54)
    max_rate: float = 1.0
    max_accel: float = 4.0

    @property
    def head(self) -> HeadGeometry:
        """The Rochester head geometry of this unit (one camera on the tool axis)."""
        return HeadGeometry(
            neck_offset=0.0,
            left_offset=0.0,
            right_offset=0.0,
            alt_offset=self.tilt_offset,
            az_offset=self.nodal_offset,
        )

    def T_ptu_mount(self, pan: float, tilt: float) -> FloatArray:
        """The camera mount (CamPos) in the unit's base frame at ``pan``, ``tilt`` (rad)."""
        return T_flange_campos(tilt, pan, "left", self.head)

    def check(self, pan: float, tilt: float) -> None:
        """Raise PtuLimitError when the angles are outside the travel."""
        for name, value, (low, high) in (
            ("pan", pan, self.pan_limits),
            ("tilt", tilt, self.tilt_limits),
        ):
            if not (np.isfinite(value) and low <= value <= high):
                raise PtuLimitError(
                    f"{name} {np.degrees(value):.1f} deg is outside the unit's travel "
                    f"{np.degrees(low):.1f} .. {np.degrees(high):.1f} deg"
                )

    def aim(
        self,
        point_ptu: ArrayLike,
        camera: PinholeCamera | None = None,
        pixel: ArrayLike | None = None,
    ) -> tuple[float, float]:
        """``(pan, tilt)`` (rad) that aim at ``point_ptu`` (m, unit's base frame).

        Without ``camera``: the point on the mount's nominal axis. With ``camera`` (the model at
        the current zoom, its extrinsics taking mount-frame points into the camera frame): the
        point shows at ``pixel`` (default the principal point) through the whole model.
        Raises PtuLimitError when out of travel, too close, or the camera cannot see it.
        """
        try:
            if camera is None:
                tilt, pan = aim_camera_at_point(point_ptu, "left", self.head)
            else:
                centre = camera.intrinsics.as_array()[3:5] if pixel is None else pixel
                tilt, pan = aim_camera_model_at_point(
                    point_ptu, "left", _projector(camera), centre, self.head
                )
        except AimError as exc:
            raise PtuLimitError(str(exc)) from None
        self.check(pan, tilt)
        return pan, tilt


def _projector(camera: PinholeCamera):
    """Pixels of a mount-frame point through ``camera``; ValueError behind the camera."""

    def project(point_mount: FloatArray) -> FloatArray:
        if camera.to_camera_frame(point_mount)[2] <= 0:
            raise ValueError("behind the camera")
        return camera.project(point_mount)

    return project


def aim_in_base(
    geometry: PtuGeometry,
    T_base_ptu: ArrayLike,
    point_base: ArrayLike,
    camera: PinholeCamera | None = None,
    pixel: ArrayLike | None = None,
) -> tuple[float, float]:
    """``(pan, tilt)`` aiming a unit mounted at ``T_base_ptu`` at ``point_base`` (m, base);
    ``camera`` and ``pixel`` as in :meth:`PtuGeometry.aim`."""
    T = np.asarray(T_base_ptu, dtype=float)
    p = np.linalg.inv(T) @ np.append(np.asarray(point_base, dtype=float), 1.0)
    return geometry.aim(p[:3], camera, pixel)
