"""SketchCam: a simulated zoom camera on a PTU that sees the Active Sketch scene."""

from __future__ import annotations

import numpy as np

from umbra.connectors import Input, Module, Output, Parameters, param
from umbra.connectors.messages import CameraModel, Image, Pose, Poses
from umbra.connectors.scene_messages import SceneObjects
from umbra.modules.vision.arm_view import arm_in, with_arm
from umbra.modules.vision.lighting import Sensor
from umbra.modules.vision.sketch_render import render_scene


class SketchCam(Module["SketchCam.Params"]):
    """Renders the scene's objects through the current camera model (CamCalib: intrinsics at
    the zoom, ``T_mount_camera``) from the PTU's mount pose (``T_world_mount``).

    Frames out carry the model's camera name; stamps are the render time. Nothing is sent until
    a model, a mount pose and the objects have all arrived. Give it a ``rate``.
    """

    TYPE = "SketchCam"

    class Params(Parameters):
        noise_sigma: float = param(2.0, "pixel noise", unit="grey levels", ge=0, le=50)

    camera_model = Input(CameraModel, feedback=True, doc="model at the current zoom (CamCalib)")
    mount_pose = Input(Pose, feedback=True, doc="T_world_mount of the PTU (PTU.mount_pose)")
    objects = Input(SceneObjects, feedback=True, doc="the scene's solids (SketchWorld)")
    arm_poses = Input(
        Poses,
        required=False,
        feedback=True,
        doc="the arm's TRUE frames in the objects' frame (SketchWorld.arm_poses): drawn too",
    )
    image = Output(Image, measured=True, doc="BGR frames")

    def start(self) -> None:
        self._frames = 0
        self._sensor: Sensor | None = None

    def step(self, now: float) -> None:
        model = self.camera_model.get(now)
        mount = self.mount_pose.get(now)
        objects = self.objects.get(now)
        if model is None or mount is None or objects is None:
            return
        T_base_camera = mount.matrix @ model.T_mount_camera
        arm = self.arm_poses.get(now)
        if arm is not None and arm.frame == objects.frame:
            objects = with_arm(objects, arm_in(arm, np.eye(4)))
        shape = (model.height, model.width, 3)
        if self._sensor is None or self._sensor.shape != shape:
            self._sensor = Sensor(shape)
        pixels = render_scene(
            objects,
            model.K,
            T_base_camera,
            model.width,
            model.height,
            model.dist,
            self.context.rng,
            self.params.noise_sigma,
            self._sensor,
        )
        self._frames += 1
        self.image.send(Image(pixels=pixels, frame=model.frame))

    def summary(self) -> dict[str, int]:
        return {"frames": self._frames}
