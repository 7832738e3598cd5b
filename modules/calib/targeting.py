"""Targeting: a 3-D point from the same feature picked in two calibrated cameras.

Visual targeting of the Sandia report (and the stereo methods of the Rochester guide, sections
11-12), generalized to two independent cameras, each with its own camera model (for example two
zoom cameras on pan-tilt units, each model from its own CamCalib).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from umbra.connectors import Input, Module, Output, Parameters, param
from umbra.connectors.messages import CameraModel, Pose, Scalar, Status, Vector
from umbra.modules.calib.camera_message import pinhole_from_message
from umbra.modules.calib.camera_model import PinholeCamera
from umbra.modules.geometry.rays import RayGeometryError, Triangulation, triangulate_pixels


def triangulate_measured(
    cameras: Sequence[PinholeCamera], pixels: Sequence[ArrayLike], method: str = "midpoint"
) -> tuple[Triangulation, list[float]]:
    """Triangulate one measured (distorted) pixel ``[u, v]`` per camera.

    Returns the triangulation (point and gap, metres, the cameras' reference frame) and the
    point's depth along each camera's optic axis (metres; not positive: behind that camera).
    Raises ``RayGeometryError`` when a pixel cannot be undistorted or the rays fix no point.
    """
    ideal = [c.ideal_pixels(uv) for c, uv in zip(cameras, pixels, strict=True)]
    if not np.all(np.isfinite(ideal)):
        raise RayGeometryError("a pixel lies outside its camera's distortion model")
    result = triangulate_pixels([c.camera_matrix() for c in cameras], ideal, method)
    depths = [float(c.to_camera_frame(result.point)[2]) for c in cameras]
    return result, depths


class Targeting(Module["Targeting.Params"]):
    """Triangulates a pixel pair: point (metres, ``reference_frame``) and ray gap (metres).

    Each camera model's extrinsics are relative to its ``mount``; the mount's pose in
    ``reference_frame`` comes from ``mount_pose_a``/``mount_pose_b`` when connected (a moving
    pan-tilt head), otherwise from the graph's static frames. Pixels are measured (distorted)
    pixels ``[u, v]``; they are undistorted with each camera's model. The point is published on
    every new pixel pair; ``status`` says ``ok``, ``mismatch`` (gap above ``max_gap``: the pixels
    are probably not the same feature) or ``error`` (parallel rays, point behind a camera).
    """

    TYPE = "Targeting"

    class Params(Parameters):
        reference_frame: str = param("base", "frame of the output point")
        method: Literal["midpoint", "linear"] = param(
            "midpoint", "Duda-Hart midpoint of the rays, or the pseudo-inverse of the equations"
        )
        max_gap: float = param(0.01, "largest ray gap reported as ok", unit="m", gt=0)

    camera_a = Input(CameraModel, doc="model of camera a (e.g. from CamCalib)")
    camera_b = Input(CameraModel, doc="model of camera b")
    pixel_a = Input(Vector, trigger=True, doc="[u, v] of the feature in camera a's image (px)")
    pixel_b = Input(Vector, trigger=True, doc="[u, v] of the feature in camera b's image (px)")
    mount_pose_a = Input(
        Pose, required=False, feedback=True, doc="pose of camera a's mount in reference_frame"
    )
    mount_pose_b = Input(
        Pose, required=False, feedback=True, doc="pose of camera b's mount in reference_frame"
    )
    point = Output(Vector, doc="[x, y, z] of the target in reference_frame (m)")
    gap = Output(Scalar, doc="distance between the two rays at closest approach (m)")
    status = Output(Status, doc="ok / mismatch / error, with the reason")

    def start(self) -> None:
        self._solved = 0
        self._failed = 0

    def step(self, now: float) -> None:
        if not (self.pixel_a.fresh or self.pixel_b.fresh):
            return
        samples = [
            self.camera_a.get(now),
            self.camera_b.get(now),
            self.pixel_a.get(now),
            self.pixel_b.get(now),
        ]
        if any(s is None for s in samples):
            return
        model_a, model_b, pixel_a, pixel_b = samples
        try:
            cameras = [
                self._camera(model_a, self.mount_pose_a.get(now)),
                self._camera(model_b, self.mount_pose_b.get(now)),
            ]
            pixels = [np.asarray(p.values, dtype=float).reshape(2) for p in (pixel_a, pixel_b)]
            result, depths = triangulate_measured(cameras, pixels, self.params.method)
            if min(depths) <= 0:
                raise RayGeometryError("the rays meet behind a camera")
        except (RayGeometryError, KeyError, ValueError) as error:
            self._failed += 1
            reason = str(error.args[0]) if isinstance(error, KeyError) else str(error)
            self.status.send(Status(stage="error", message=reason, reason=reason))
            return
        self._solved += 1
        stamp = max(pixel_a.stamp, pixel_b.stamp)
        gap = float(result.gap)
        self.point.send(Vector(values=np.asarray(result.point, dtype=float), stamp=stamp))
        self.gap.send(Scalar(value=gap, stamp=stamp))
        ok = gap <= self.params.max_gap
        self.status.send(
            Status(
                stage="ok" if ok else "mismatch",
                message=f"gap {gap * 1000:.1f} mm"
                + ("" if ok else f" > {self.params.max_gap * 1000:.1f} mm"),
                values={"gap_m": gap, "depth_a_m": depths[0], "depth_b_m": depths[1]},
            )
        )

    def _camera(self, model: CameraModel, mount_pose: Pose | None) -> PinholeCamera:
        reference = self.params.reference_frame
        if mount_pose is not None:
            if mount_pose.parent != reference or mount_pose.child != model.mount:
                raise KeyError(
                    f"mount pose is {mount_pose.parent}->{mount_pose.child}, expected "
                    f"{reference}->{model.mount}"
                )
            return pinhole_from_message(model, mount_pose.matrix)
        if model.mount == reference:
            return pinhole_from_message(model)
        return pinhole_from_message(model, self.context.frames.lookup(reference, model.mount))

    def summary(self) -> dict[str, Any]:
        return {"targets_solved": self._solved, "targets_failed": self._failed}
