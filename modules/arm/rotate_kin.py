"""ROTATE_KIN: a camera-frame twist becomes the tool-frame twist that moves the camera so."""

from __future__ import annotations

import numpy as np
from pydantic import model_validator

from umbra.connectors import (
    Input,
    Module,
    Output,
    Parameters,
    ParamProblem,
    UserError,
    from_param,
    param,
)
from umbra.connectors.messages import Twist
from umbra.modules.geometry.transforms import (
    is_rigid,
    transform_from_xyz_rpy_deg,
    twist_tool_from_camera,
)


class RotateKin(Module["RotateKin.Params"]):
    """Transforms a twist from the camera frame into the tool frame (full rigid transform).

    ``w_tool = R w_cam`` and ``v_tool = R v_cam + w_tool x (p_tool - p_cam)``: when the camera
    is offset from the tool point, turning the camera about its own axis needs a tool
    translation too (the lever-arm term), not only a rotation of the vector. The camera mount
    ``T_tool_camera`` comes from the graph's static frames (``tool->camera``) unless
    ``mount_xyz`` / ``mount_rpy_deg`` are given.
    """

    TYPE = "ROTATE_KIN"

    class Params(Parameters):
        camera_frame: str = param("camera", "frame of the incoming twist")
        tool_frame: str = param("tool", "frame of the outgoing twist")
        mount_xyz: list[float] | None = param(
            None,
            "camera origin in the tool frame (default: graph frames)",
            unit="m",
            min_length=3,
            max_length=3,
        )
        mount_rpy_deg: list[float] | None = param(
            None,
            "camera roll, pitch, yaw in the tool frame (default: graph frames)",
            unit="deg",
            min_length=3,
            max_length=3,
        )

        @model_validator(mode="after")
        def _mount_whole(self) -> RotateKin.Params:
            if (self.mount_xyz is None) != (self.mount_rpy_deg is None):
                raise ParamProblem(
                    "mount_xyz" if self.mount_xyz is None else "mount_rpy_deg",
                    "is needed too: give both mount_xyz and mount_rpy_deg, or neither",
                )
            return self

        def required_frames(self) -> list[tuple[str, str]]:
            """T_tool_camera from the graph's frames unless the mount is given here."""
            return [(self.tool_frame, self.camera_frame)] if self.mount_xyz is None else []

    camera_twist = Input(Twist, frame=from_param("camera_frame"), trigger=True, doc="camera twist")
    tool_twist = Output(Twist, frame=from_param("tool_frame"), doc="tool twist")

    def start(self) -> None:
        p = self.params
        if p.mount_xyz is not None and p.mount_rpy_deg is not None:  # both or neither: Params
            self.T_tool_camera = transform_from_xyz_rpy_deg(p.mount_xyz, p.mount_rpy_deg)
        else:
            try:
                self.T_tool_camera = self.context.frames.lookup(p.tool_frame, p.camera_frame)
            except KeyError:
                raise UserError(
                    f"ROTATE_KIN `{self.name}`: no static frame `{p.tool_frame}->"
                    f"{p.camera_frame}` in the graph; add it under `frames:` or set mount_xyz "
                    "and mount_rpy_deg"
                ) from None
        if not is_rigid(self.T_tool_camera, 1e-6):
            raise UserError(f"ROTATE_KIN `{self.name}`: the camera mount is not a rigid transform")
        self._rejected = 0

    def step(self, now: float) -> None:
        sample = self.camera_twist.get(now)
        if sample is None or not self.camera_twist.fresh:
            return
        if sample.frame != self.params.camera_frame:
            # A wrong frame at run time is a bug upstream; never move on it.
            self._rejected += 1
            vector = np.zeros(6)
        else:
            vector = twist_tool_from_camera(self.T_tool_camera, sample.vector)
        self.tool_twist.send(Twist(vector=vector, frame=self.params.tool_frame, stamp=sample.stamp))

    def summary(self) -> dict[str, int]:
        return {"rejected_frames": self._rejected}
