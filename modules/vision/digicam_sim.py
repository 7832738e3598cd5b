"""DigiCam's simulated wrist camera: the scene rendered from the poses the world sends (the
camera's, the patch's, and the arm's, drawn over the rest), the scheduled faults, and the
ground truth (a mixin of :class:`~umbra.modules.vision.digicam.DigiCam`)."""

from __future__ import annotations

import dataclasses
from collections import deque
from collections.abc import Callable
from typing import Any

import msgspec
import numpy as np

from umbra.connectors import UserError
from umbra.connectors.messages import Contour, Image, Pose
from umbra.modules.vision.arm_view import arm_in, arm_occluders
from umbra.modules.vision.contour_message import contour_message
from umbra.modules.vision.features import polygon_features
from umbra.modules.vision.lighting import Lighting
from umbra.modules.vision.scene import Scene, camera_looking_down, pose
from umbra.modules.vision.sim_camera import CameraSpec, SceneFault, SimulatedCamera

#: ``lag`` fault: the speed [1] at which a lagging camera's frames follow the scene.
LAG_PLAYBACK = 0.2


class SimCameraSide:
    """The ``source: sim`` half of DigiCam; its state lives on the module."""

    params: Any
    name: str
    context: Any
    log: Any
    camera_pose: Any
    camera_model: Any
    patch_pose: Any
    arm_poses: Any
    image: Any
    truth: Any
    _sim: SimulatedCamera | None
    _fault: SceneFault | None
    _first_step_at: float | None
    _fault_started_at: float | None
    _frozen: np.ndarray | None
    _poses: deque[tuple[float, np.ndarray, np.ndarray]]
    _last: Image | None
    _sent: int
    _send: Callable[..., None]  #: DigiCam's: send a new frame

    def _check_sim_params(self) -> None:
        p = self.params
        problems = []
        if len(p.patch_xyz_m) != 3:
            problems.append(f"patch_xyz_m needs 3 values, got {len(p.patch_xyz_m)}")
        if len(p.patch_size_m) != 2 or min(p.patch_size_m) <= 0:
            problems.append(f"patch_size_m needs 2 positive values, got {p.patch_size_m}")
        if len(p.patch_rgb) != 3 or not all(0 <= c <= 255 for c in p.patch_rgb):
            problems.append(f"patch_rgb needs 3 values in 0..255, got {p.patch_rgb}")
        if len(p.cast_rgb) != 3 or min(p.cast_rgb) < 0:
            problems.append(f"cast_rgb needs 3 non-negative values, got {p.cast_rgb}")
        if len(p.fault_rgb) != 3 or not all(0 <= c <= 255 for c in p.fault_rgb):
            problems.append(f"fault_rgb needs 3 values in 0..255, got {p.fault_rgb}")
        if len(p.dist) not in (4, 5):
            problems.append(f"dist needs 4 or 5 coefficients, got {len(p.dist)}")
        if problems:
            raise UserError(f"{self.name}: " + "; ".join(problems))

    def _camera_spec(self) -> CameraSpec:
        p = self.params
        model = self.camera_model.value
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
            raise UserError(f"{self.name}: bad camera model: {exc}") from None

    def _patch_pose(self) -> np.ndarray:
        sample = self.patch_pose.value
        if sample is None:
            p = self.params
            return pose(p.patch_xyz_m, float(np.deg2rad(p.patch_yaw_deg)))
        return self._in_world(sample, "patch_pose")

    def _in_world(self, sample: Pose, port: str) -> np.ndarray:
        return self._T_world(sample.parent, port) @ sample.matrix

    def _T_world(self, parent: str, port: str) -> np.ndarray:
        """T_world_parent of the frame ``parent`` an input's poses are in (static frames)."""
        world = self.params.world_frame
        if parent == world:
            return np.eye(4)
        try:
            return self.context.frames.lookup(world, parent)
        except KeyError:
            raise UserError(
                f"{self.name}: input `{port}` is a pose in `{parent}`, and no static "
                f"frames lead from `{world}` to it (declare `{world}->{parent}`)"
            ) from None

    def _camera_pose(self, T_world_patch: np.ndarray) -> np.ndarray:
        sample = self.camera_pose.value
        if sample is None:
            return camera_looking_down(T_world_patch[:3, 3], self.params.camera_height_m)
        T_world_child = self._in_world(sample, "camera_pose")
        camera = self.params.camera_frame
        if sample.child == camera:
            return T_world_child
        model = self.camera_model.value
        if model is not None and model.mount == sample.child:
            return T_world_child @ np.asarray(model.T_mount_camera, dtype=float)
        try:
            return T_world_child @ self.context.frames.lookup(sample.child, camera)
        except KeyError:
            raise UserError(
                f"{self.name}: input `camera_pose` gives `{sample.child}`, and neither the "
                f"camera model's mount nor static frames lead to `{camera}` "
                f"(declare `{sample.child}->{camera}`)"
            ) from None

    def _step_sim(self, now: float) -> None:
        p = self.params
        fault = self._fault
        assert self._sim is not None and fault is not None
        waiting = [
            reg.name for reg in (self.camera_pose, self.patch_pose, self.camera_model)
            if reg.connected and reg.value is None
        ]  # fmt: skip
        if waiting:  # wired poses not here yet: no frame from a pose nobody measured
            if not self._told_waiting:
                self._told_waiting = True
                self.log.info("%s: waiting for %s before the first frame", self.name, waiting)
            return
        if self._first_step_at is None:
            self._first_step_at = now
        faulted = fault.begun(now - self._first_step_at)
        if faulted and p.fault_duration_s and self._fault_started_at is not None:
            faulted = now - self._fault_started_at < p.fault_duration_s  # the fault is over
        if faulted and self._fault_started_at is None:
            self._fault_started_at = now
            self.log.warning("%s: injected fault %r begins at %.3f s", self.name, p.fault, now)
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
            patch_rgb=tuple(int(c) for c in p.patch_rgb),  # type: ignore[arg-type]
            patch_present=p.patch_present,
            background=p.background,
        )
        if faulted and p.fault == "freeze" and self._frozen is not None:
            self._send_frozen(scene, T_world_camera, now)
            return
        if faulted:
            scene = fault.apply(scene, now - self._fault_started_at)  # type: ignore[operator]
        scene = self._with_arm(scene, T_world_camera)
        lighting = Lighting(
            gain=p.gain,
            cast_rgb=tuple(float(c) for c in p.cast_rgb),  # type: ignore[arg-type]
            noise_sigma=p.noise_sigma,
            blur_length_px=p.blur_length_px,
            blur_angle_rad=float(np.deg2rad(p.blur_angle_deg)),
        )
        frame = self._sim.render(
            self._camera_spec(), scene, T_world_camera, lighting, self.context.rng
        )
        self._send(frame.image, now, stamp=captured, origin=self._poses_origin(captured, now))
        self._frozen = frame.image
        self.truth.send(self._truth(frame.patch_polygon, frame.patch_visible_fraction, now))

    def _with_arm(self, scene: Scene, T_world_camera: np.ndarray) -> Scene:
        """The scene with the arm's faces in front (``arm_poses``: its true frames), if wired."""
        arm = self.arm_poses.value
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
        for reg in (self.camera_pose, self.patch_pose, self.arm_poses):
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
        poses, lag = self._poses, self.params.fault_lag_s
        poses.append((now, T_world_camera, T_world_patch))
        while len(poses) > 1 and poses[1][0] <= now - lag - 1.0:
            poses.popleft()
        begun = self._fault_started_at
        if not faulted or begun is None:
            return now, T_world_camera, T_world_patch
        shown = max(begun + LAG_PLAYBACK * (now - begun), now - lag)
        for entry in reversed(poses):  # the newest step captured at or before `shown`
            if entry[0] <= shown:
                return entry
        return poses[0]

    def _send_frozen(self, scene: Scene, T_world_camera: np.ndarray, now: float) -> None:
        """A frozen grabber: the held pixels again, newly stamped; the truth follows the world."""
        assert self._sim is not None and self._frozen is not None
        stale = self.params.fault_frozen_stale
        self._last = Image(
            pixels=self._frozen, frame=self.params.camera_frame, stale=stale, stamp=now
        )
        self.image.send(self._last)
        self._sent += 1
        polygon, inside = self._sim.patch_outline(self._camera_spec(), scene, T_world_camera)
        truth = self._truth(polygon, inside, now)
        if len(polygon) >= 3:
            reason = f"camera frozen; {100 * inside:.0f}% of the true outline inside the image"
            truth = msgspec.structs.replace(truth, reason=reason)
        self.truth.send(truth)

    @staticmethod
    def _truth(polygon: np.ndarray, visible: float, now: float) -> Contour:
        if len(polygon) < 3:
            return contour_message(np.zeros((0, 2)), None, "idle", "no patch in view", now)
        status = "tracking" if visible > 0 else "idle"
        reason = f"{100 * visible:.0f}% of the patch visible"
        return contour_message(polygon, polygon_features(polygon), status, reason, now)
