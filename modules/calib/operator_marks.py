"""SimMarks: the simulated operator of visual targeting, who marks a known point in two images.

In the report's visual targeting (section 3.1) the operator selects a common feature in the
images of two calibrated cameras. In a simulation the feature is a known 3-D point: this module
projects it through each camera's current model (zoom-dependent, from CamCalib) and the pose of
the camera's mount (the graph's static frames), adds the operator's click jitter, and sends the
two pixels the way the Targeting module takes them. It also publishes what the simulation knows
and the estimate should match: the true point, and the mounts' poses for simulated cameras
(DigiCam's ``camera_pose``), so that the rendered images show the feature where it is marked.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from umbra.connectors import Input, Module, Output, Parameters, UserError, param
from umbra.connectors.messages import CameraModel, Pose, Vector
from umbra.modules.calib.camera_message import pinhole_from_message


class SimMarks(Module["SimMarks.Params"]):
    """Simulated operator clicks: the pixels of a known point in two cameras (targeting input).

    On every new camera model (and at the module's rate, if it has one) the point ``point_m``
    (metres, ``reference_frame``) is projected through both cameras, distortion included, and
    each pixel gets Gaussian click noise (``click_noise_px`` per axis, from the graph's seeded
    generator). The pair is sent only when the point is in front of both cameras and inside both
    images: an operator cannot click what is out of view (counted as ``out_of_view``). Each
    camera's mount pose in ``reference_frame`` comes from the graph's static frames
    (``reference_frame->mount``), as Targeting reads it; it is also sent as ``pose_a``/``pose_b``
    for simulated cameras.
    """

    TYPE = "SimMarks"

    class Params(Parameters):
        point_m: list[float] = param(
            [0.0, 0.0, 0.03],
            "the known point [x, y, z] in reference_frame",
            unit="m",
            min_length=3,
            max_length=3,
        )
        reference_frame: str = param("base", "frame of the point and of the mount poses")
        click_noise_px: float = param(
            0.0, "standard deviation of each click coordinate", unit="px", ge=0
        )

    camera_a = Input(CameraModel, trigger=True, doc="model of camera a (e.g. from CamCalib)")
    camera_b = Input(CameraModel, trigger=True, doc="model of camera b")
    pixel_a = Output(
        Vector, measured=True, doc="[u, v] of the point in camera a's image, as clicked (px)"
    )
    pixel_b = Output(
        Vector, measured=True, doc="[u, v] of the point in camera b's image, as clicked (px)"
    )
    truth = Output(Vector, measured=True, doc="the true point [x, y, z] in reference_frame (m)")
    pose_a = Output(
        Pose, measured=True, doc="pose of camera a's mount in reference_frame (static frames)"
    )
    pose_b = Output(
        Pose, measured=True, doc="pose of camera b's mount in reference_frame (static frames)"
    )

    def start(self) -> None:
        self._point = np.asarray(self.params.point_m, dtype=float)
        self._marks = 0
        self._out_of_view = 0
        self._reported_out = False

    def step(self, now: float) -> None:
        models = (self.camera_a.get(now), self.camera_b.get(now))
        if models[0] is None or models[1] is None:
            return
        T_ref_mounts = [self._mount_pose(m) for m in models]
        pixels = [self._projection(m, T) for m, T in zip(models, T_ref_mounts, strict=True)]
        reference = self.params.reference_frame
        for out, model, T in zip((self.pose_a, self.pose_b), models, T_ref_mounts, strict=True):
            out.send(Pose(matrix=T, parent=reference, child=model.mount, stamp=now))
        self.truth.send(Vector(values=self._point, stamp=now))
        seen = [uv for uv in pixels if uv is not None]
        if len(seen) < len(pixels):
            self._out_of_view += 1
            if not self._reported_out:
                self._reported_out = True
                self.log.warning("%s: the point is out of view of a camera; no marks", self.name)
            return
        sigma = self.params.click_noise_px
        for out, uv in zip((self.pixel_a, self.pixel_b), seen, strict=True):
            if sigma > 0:
                uv = uv + self.context.rng.normal(0.0, sigma, 2)
            out.send(Vector(values=uv, stamp=now))
        self._marks += 1

    def _mount_pose(self, model: CameraModel) -> np.ndarray:
        """T_ref_mount of a camera model's mount, from the static frames."""
        reference = self.params.reference_frame
        if model.mount == reference:
            return np.eye(4)
        try:
            return self.context.frames.lookup(reference, model.mount)
        except KeyError:
            raise UserError(
                f"{self.name}: camera `{model.frame}` is mounted on `{model.mount}`, and no "
                f"static frames lead from `{reference}` to it (declare `{reference}->"
                f"{model.mount}` under `frames:`)"
            ) from None

    def _projection(self, model: CameraModel, T_ref_mount: np.ndarray) -> np.ndarray | None:
        """Pixel [u, v] of the point, or None when it is behind the camera or off the image."""
        camera = pinhole_from_message(model, T_ref_mount)
        if camera.to_camera_frame(self._point)[2] <= 0:
            return None
        uv = camera.project(self._point)
        if not (0 <= uv[0] < model.width and 0 <= uv[1] < model.height):
            return None
        return uv

    def summary(self) -> dict[str, Any]:
        return {"marks": self._marks, "out_of_view": self._out_of_view}
