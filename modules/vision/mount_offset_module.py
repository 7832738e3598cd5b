"""MountOffset: the simulation's wrongly mounted camera (a pose passed on with a fixed offset)."""

from __future__ import annotations

import numpy as np

from umbra.connectors import Input, Module, Output, Parameters, param
from umbra.connectors.messages import Pose
from umbra.modules.geometry.mount_offset import offset_mount, offset_transform


class MountOffset(Module["MountOffset.Params"]):
    """Moves a pose by a fixed offset in its own (child) axes: ``T_parent_true = T_parent_pose .
    T_offset``. Placed between the plant's camera pose and a simulated camera (DigiCam), it
    renders the images a camera bolted on a few degrees and centimetres off would see, while
    the rest of the graph still believes the nominal mount: the camera-pose tool's test case.
    """

    TYPE = "MountOffset"

    class Params(Parameters):
        xyz_m: list[float] = param(
            [0.0, 0.0, 0.0],
            "offset translation in the child frame",
            unit="m",
            min_length=3,
            max_length=3,
        )
        rpy_deg: list[float] = param(
            [0.0, 0.0, 0.0],
            "offset roll, pitch, yaw (fixed axes x, y, z) in the child frame",
            unit="deg",
            min_length=3,
            max_length=3,
        )

    pose = Input(Pose, trigger=True, feedback=True, doc="the believed pose T_parent_child")
    offset_pose = Output(Pose, doc="the true pose: the believed one times the offset")

    def start(self) -> None:
        p = self.params
        self._T_offset = offset_transform(p.xyz_m, p.rpy_deg)

    def step(self, now: float) -> None:
        sample = self.pose.get(now)
        if sample is None or not self.pose.fresh:
            return
        matrix = offset_mount(np.asarray(sample.matrix, dtype=float), self._T_offset)
        self.offset_pose.send(
            Pose(matrix=matrix, parent=sample.parent, child=sample.child, stamp=sample.stamp)
        )
