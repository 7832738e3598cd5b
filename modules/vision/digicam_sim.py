"""DigiCam's simulated wrist camera: the scene rendered from the poses the world sends (the
camera's, the patch's, and the arm's, drawn over the rest), the scheduled faults, and the
ground truth (a part that :class:`~umbra.modules.vision.digicam.DigiCam` owns)."""

from __future__ import annotations

import dataclasses
from collections import deque
from typing import TYPE_CHECKING

import msgspec
import numpy as np

from umbra.connectors import UserError
from umbra.connectors.messages import CameraModel, Contour, Image, Pose
from umbra.connectors.tracking import TrackStatus
from umbra.modules.vision.arm_view import arm_in, arm_occluders
from umbra.modules.vision.contour_message import contour_message
from umbra.modules.vision.features import polygon_features
from umbra.modules.vision.lighting import Lighting
from umbra.modules.vision.scene import Scene, camera_looking_down, pose
from umbra.modules.vision.sim_camera import CameraSpec, SceneFault, SimulatedCamera

if TYPE_CHECKING:
    from umbra.modules.vision.digicam import DigiCam

#: ``lag`` fault: the speed [1] at which a lagging camera's frames follow the scene.
LAG_PLAYBACK = 0.2


class SimCameraSide:
    """The ``source: sim`` half of a :class:`~umbra.modules.vision.digicam.DigiCam`: reads the
    camera's inputs and parameters and sends on its outputs; keeps the renderer, the scheduled
    fault and when it began, the frozen frame and the recent poses (``lag``)."""

    def __init__(self, camera: DigiCam) -> None:
        self._c = camera
        p = camera.params
        self.sim = SimulatedCamera()
        self._fault = SceneFault(
            kind=p.fault,
            at_s=p.fault_at_s,
            speed_mps=p.fault_speed_mps,
            side=p.fault_side,
            rgb=(int(p.fault_rgb[0]), int(p.fault_rgb[1]), int(p.fault_rgb[2])),
        )
        #: the model made of the parameters, once (they are not tunable)
        self._params_model = CameraModel(
            fx=p.fx, fy=p.fy, skew=p.skew, u0=p.u0, v0=p.v0,
            dist=np.array([*p.dist, 0.0][:5], dtype=float),
            width=p.width or 640, height=p.height or 480,
            mount=p.camera_frame, frame=p.camera_frame,
        )  # fmt: skip
        self._first_step_at: float | None = None
        self.fault_started_at: float | None = None  #: when the fault began [s] (None: not yet)
        self._frozen: np.ndarray | None = None
        #: (t, T_world_camera, T_world_patch) of recent steps, for the ``lag`` fault
        self._poses: deque[tuple[float, np.ndarray, np.ndarray]] = deque()
        self._told_waiting = False

    def _camera_spec(self) -> CameraSpec:
        p = self._c.params
        model = self._c.camera_model.value
        try:
            if model is not None:
                return CameraSpec.from_values(
                    model.fx, model.fy, model.skew, model.u0, model.v0,
                    model.width, model.height, model.dist,
                )  # fmt: skip
            return CameraSpec.from_values(
                p.fx, p.fy, p.skew, p.u0, p.v0, p.width or 640, p.height or 480, p.dist
            )
        except ValueError as exc:
            raise UserError(f"{self._c.name}: bad camera model: {exc}") from None

    def _rendered_with(self, captured: float) -> CameraModel:
        """The camera model of a frame captured at ``captured`` [s]: the camera_model input's,
        else one made of the parameters (its mount: the camera itself, as its pose in the tool is
        the graph's static frames' or the pose input's, not this model's)."""
        model: CameraModel | None = self._c.camera_model.value
        return msgspec.structs.replace(
            model if model is not None else self._params_model, stamp=captured, origin=captured
        )

    def _patch_pose(self) -> np.ndarray:
        sample = self._c.patch_pose.value
        if sample is None:
            p = self._c.params
            return pose(p.patch_xyz_m, float(np.deg2rad(p.patch_yaw_deg)))
        return self._in_world(sample, "patch_pose")

    def _in_world(self, sample: Pose, port: str) -> np.ndarray:
        return self._T_world(sample.parent, port) @ np.asarray(sample.matrix, dtype=float)

    def _T_world(self, parent: str, port: str) -> np.ndarray:
        """T_world_parent of the frame ``parent`` an input's poses are in (static frames)."""
        world = self._c.params.world_frame
        if parent == world:
            return np.eye(4)
        try:
            return self._c.context.frames.lookup(world, parent)
        except KeyError:
            raise UserError(
                f"{self._c.name}: input `{port}` is a pose in `{parent}`, and no static "
                f"frames lead from `{world}` to it (declare `{world}->{parent}`)"
            ) from None

    def _camera_pose(self, T_world_patch: np.ndarray) -> np.ndarray:
        sample: Pose | None = self._c.camera_pose.value
        if sample is None:
            return camera_looking_down(T_world_patch[:3, 3], self._c.params.camera_height_m)
        T_world_child = self._in_world(sample, "camera_pose")
        camera = self._c.params.camera_frame
        if sample.child == camera:
            return T_world_child
        model: CameraModel | None = self._c.camera_model.value
        if model is not None and model.mount == sample.child:
            return T_world_child @ np.asarray(model.T_mount_camera, dtype=float)
        try:
            return T_world_child @ self._c.context.frames.lookup(sample.child, camera)
        except KeyError:
            raise UserError(
                f"{self._c.name}: input `camera_pose` gives `{sample.child}`, and neither the "
                f"camera model's mount nor static frames lead to `{camera}` "
                f"(declare `{sample.child}->{camera}`)"
            ) from None

    def step(self, now: float) -> None:
        """Render and send the frame of ``now`` [s] (and its truth and camera model)."""
        p = self._c.params
        fault = self._fault
        waiting = [
            reg.name for reg in (self._c.camera_pose, self._c.patch_pose, self._c.camera_model)
            if reg.connected and reg.value is None
        ]  # fmt: skip
        if waiting:  # wired poses not here yet: no frame from a pose nobody measured
            if not self._told_waiting:
                self._told_waiting = True
                self._c.log.info("%s: waiting for %s before the first frame", self._c.name, waiting)
            return
        if self._first_step_at is None:
            self._first_step_at = now
        faulted = fault.begun(now - self._first_step_at)
        if faulted and p.fault_duration_s and self.fault_started_at is not None:
            faulted = now - self.fault_started_at < p.fault_duration_s  # the fault is over
        if faulted and self.fault_started_at is None:
            self.fault_started_at = now
            self._c.log.warning(
                "%s: injected fault %r begins at %.3f s", self._c.name, p.fault, now
            )
        T_world_patch = self._patch_pose()
        T_world_camera = self._camera_pose(T_world_patch)
        captured = now
        if p.fault == "lag":
            captured, T_world_camera, T_world_patch = self._lagged(
                now, T_world_camera, T_world_patch, faulted
            )
        scene = Scene(
            T_world_patch=T_world_patch,
            patch_size_m=(float(p.patch_size_m[0]), float(p.patch_size_m[1])),
            patch_rgb=(int(p.patch_rgb[0]), int(p.patch_rgb[1]), int(p.patch_rgb[2])),
            patch_present=p.patch_present,
            background=p.background,
        )
        if faulted and p.fault == "freeze" and self._frozen is not None:
            self._send_frozen(scene, T_world_camera, now)
            return
        if faulted:
            scene = fault.apply(scene, now - self.fault_started_at)  # type: ignore[operator]
        scene = self._with_arm(scene, T_world_camera)
        lighting = Lighting(
            gain=p.gain,
            cast_rgb=(float(p.cast_rgb[0]), float(p.cast_rgb[1]), float(p.cast_rgb[2])),
            noise_sigma=p.noise_sigma,
            blur_length_px=p.blur_length_px,
            blur_angle_rad=float(np.deg2rad(p.blur_angle_deg)),
        )
        frame = self.sim.render(
            self._camera_spec(), scene, T_world_camera, lighting, self._c.context.rng
        )
        self._c._send(frame.image, now, stamp=captured, origin=self._poses_origin(captured, now))
        if self._c.camera_info.connected:  # wired, or mapped to ROS 2's camera_info
            self._c.camera_info.send(self._rendered_with(captured))
        self._frozen = frame.image
        self._c.truth.send(self._truth(frame.patch_polygon, frame.patch_visible_fraction, now))

    def _with_arm(self, scene: Scene, T_world_camera: np.ndarray) -> Scene:
        """The scene with the arm's faces in front (``arm_poses``: its true frames), if wired."""
        arm = self._c.arm_poses.value
        if arm is None:
            return scene
        faces = arm_occluders(arm_in(arm, self._T_world(arm.frame, "arm_poses")), T_world_camera)
        return dataclasses.replace(scene, occluders=(*scene.occluders, *faces))

    def _poses_origin(self, captured: float, now: float) -> float:
        """The origin [s] of a sim frame: the oldest of the poses it was rendered from (a world
        whose poses come late over a congested link makes old frames), at most its capture (a
        ``lag`` frame, rendered from poses of its capture time, is as old as that)."""
        if captured < now:
            return captured
        oldest = captured
        for reg in (self._c.camera_pose, self._c.patch_pose, self._c.arm_poses):
            sample = reg.value
            if sample is not None and sample.origin < oldest:
                oldest = sample.origin
        return oldest

    def _lagged(
        self, now: float, T_world_camera: np.ndarray, T_world_patch: np.ndarray, faulted: bool
    ) -> tuple[float, np.ndarray, np.ndarray]:
        """The capture time [s] and poses a ``lag`` frame shows at ``now``: while the fault is
        on, the scene plays at ``LAG_PLAYBACK`` of real speed (a starved loop working through
        queued frames) until it is ``fault_lag_s`` behind, then stays that far behind."""
        poses, lag = self._poses, self._c.params.fault_lag_s
        poses.append((now, T_world_camera, T_world_patch))
        while len(poses) > 1 and poses[1][0] <= now - lag - 1.0:
            poses.popleft()
        begun = self.fault_started_at
        if not faulted or begun is None:
            return now, T_world_camera, T_world_patch
        shown = max(begun + LAG_PLAYBACK * (now - begun), now - lag)
        for entry in reversed(poses):  # the newest step captured at or before `shown`
            if entry[0] <= shown:
                return entry
        return poses[0]

    def _send_frozen(self, scene: Scene, T_world_camera: np.ndarray, now: float) -> None:
        """A frozen grabber: the held pixels again, newly stamped; the truth follows the world."""
        assert self._frozen is not None
        stale = self._c.params.fault_frozen_stale
        self._c._last = Image(
            pixels=self._frozen, frame=self._c.params.camera_frame, stale=stale, stamp=now
        )
        self._c.image.send(self._c._last)
        self._c._sent += 1
        polygon, inside = self.sim.patch_outline(self._camera_spec(), scene, T_world_camera)
        truth = self._truth(polygon, inside, now)
        if len(polygon) >= 3:
            reason = f"camera frozen; {100 * inside:.0f}% of the true outline inside the image"
            truth = msgspec.structs.replace(truth, reason=reason)
        self._c.truth.send(truth)

    @staticmethod
    def _truth(polygon: np.ndarray, visible: float, now: float) -> Contour:
        if len(polygon) < 3:
            empty = np.zeros((0, 2))
            return contour_message(empty, None, TrackStatus.IDLE, "no patch in view", now)
        status = TrackStatus.TRACKING if visible > 0 else TrackStatus.IDLE
        reason = f"{100 * visible:.0f}% of the patch visible"
        return contour_message(polygon, polygon_features(polygon), status, reason, now)
