"""The Active Sketch camera rig: two zoom cameras on pan-tilt units beside the arm.

Each camera's pose in ``base`` is ``T_base_ptu (static) @ T_ptu_mount(pan, tilt) (PTU
kinematics) @ T_mount_camera(zoom) (the zoom calibration file's extrinsics)``, and its
intrinsics are the zoom calibration's at the current zoom (the report's file by default), as
CamCalib interpolates them. Metres, radians; zoom 0 (wide) .. 1 (tele).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.connectors.messages import CameraModel
from umbra.modules.calib.camcalib import REPORT_FILE
from umbra.modules.calib.camera_message import camera_message, pinhole_from_message
from umbra.modules.calib.zoom_io import load_zoom_table
from umbra.modules.calib.zoom_table import ZoomTable
from umbra.modules.geometry.transforms import transform_from_xyz_rpy_deg
from umbra.modules.ptu.ptu_model import PtuGeometry, aim_in_base

FloatArray = NDArray[np.float64]

#: the shipped graph's unit bases (frames base->ptu_left / base->ptu_right): 1.4 m up on a mast
#: 0.5 m behind the arm's base, 0.5 m apart, looking along +x and 30 deg down (Z forward, Y down)
PTU_LEFT_XYZ_RPY = ([-0.5, 0.25, 1.4], [-120.0, 0.0, -90.0])
PTU_RIGHT_XYZ_RPY = ([-0.5, -0.25, 1.4], [-120.0, 0.0, -90.0])


def load_report_zoom_table() -> ZoomTable:
    """The report's zoom calibration (modules/calib/data/zoom_cam.xml)."""
    return load_zoom_table(REPORT_FILE, None)


@dataclass
class RigCamera:
    """One camera on its PTU: base pose, PTU geometry and the zoom calibration."""

    name: str
    T_base_ptu: FloatArray
    zoom_table: ZoomTable
    geometry: PtuGeometry = field(default_factory=PtuGeometry)
    width: int = 640
    height: int = 480

    def model(self, zoom: float) -> CameraModel:
        """The camera model at ``zoom`` (intrinsics; ``T_mount_camera`` in the PTU's mount)."""
        low, high = float(self.zoom_table.zooms[0]), float(self.zoom_table.zooms[-1])
        z = min(max(zoom, low), high)
        return camera_message(
            self.zoom_table.sample(z).camera(),
            zoom=z,
            width=self.width,
            height=self.height,
            mount=f"{self.name}_mount",
            frame=self.name,
        )

    def aim(self, point_base: ArrayLike, zoom: float) -> tuple[float, float]:
        """``(pan, tilt)`` (rad) that show ``point_base`` (m, base) at the principal point of the
        camera at ``zoom``, through its whole model (its pose in the mount at that zoom,
        intrinsics, distortion); raises PtuLimitError (a ValueError) out of travel."""
        camera = pinhole_from_message(self.model(zoom))
        return aim_in_base(self.geometry, self.T_base_ptu, point_base, camera)

    def T_base_camera(self, pan: float, tilt: float, model: CameraModel) -> FloatArray:
        """The camera's pose in base at the PTU angles (rad) for ``model``."""
        return self.T_base_ptu @ self.geometry.T_ptu_mount(pan, tilt) @ model.T_mount_camera


def default_rig(width: int = 640, height: int = 480) -> tuple[RigCamera, RigCamera]:
    """Cameras a (left) and b (right) of the shipped graph."""
    table = load_report_zoom_table()
    return (
        RigCamera(
            "cam_left",
            transform_from_xyz_rpy_deg(*PTU_LEFT_XYZ_RPY),
            table,
            width=width,
            height=height,
        ),
        RigCamera(
            "cam_right",
            transform_from_xyz_rpy_deg(*PTU_RIGHT_XYZ_RPY),
            table,
            width=width,
            height=height,
        ),
    )
