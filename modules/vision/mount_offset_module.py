"""MountOffset: the simulation's wrongly mounted camera (a pose passed on with a fixed offset)."""

from __future__ import annotations

import numpy as np

from umbra.connectors import Input, Module, Output, Parameters, UserError, param
from umbra.connectors.messages import Pose
from umbra.modules.geometry.mount_offset import offset_mount, offset_transform


class MountOffset(Module):
    """Moves a pose by a fixed offset in its own (child) axes: ``T_parent_true = T_parent_pose .
    T_offset``. Placed between the plant's camera pose and a simulated camera (DigiCam), it
    renders the images a camera bolted on a few degrees and centimetres off would see, while
    the rest of the graph still believes the nominal mount: the camera-pose tool's test case.
    """

    TYPE = "MountOffset"

    class Params(Parameters):
        xyz_m: list[float] = param(
            [0.0, 0.0, 0.0], "offset translation in the child frame", unit="m"
        )
        rpy_deg: list[float] = param(
            [0.0, 0.0, 0.0],
            "offset roll, pitch, yaw (fixed axes x, y, z) in the child frame",
            unit="deg",
        )

    pose = Input(Pose, trigger=True, feedback=True, doc="the believed pose T_parent_child")
    offset_pose = Output(Pose, doc="the true pose: the believed one times the offset")

    def start(self) -> None:
        p = self.params
        if len(p.xyz_m) != 3 or len(p.rpy_deg) != 3:
            raise UserError(
                f"{self.name}: xyz_m and rpy_deg need 3 values each, got {len(p.xyz_m)} and "
                f"{len(p.rpy_deg)}"
            )
        try:
            self._T_offset = offset_transform(p.xyz_m, p.rpy_deg)
        except ValueError as error:
            raise UserError(f"{self.name}: {error}") from None

    def step(self, now: float) -> None:
        sample = self.pose.get(now)
        if sample is None or not self.pose.fresh:
            return
        matrix = offset_mount(np.asarray(sample.matrix, dtype=float), self._T_offset)
        self.offset_pose.send(
            Pose(matrix=matrix, parent=sample.parent, child=sample.child, stamp=sample.stamp)
        )
