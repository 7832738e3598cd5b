"""vsServo: snake contour in, 4-DOF camera velocity out, through the stages of a grab."""

from __future__ import annotations

import dataclasses
from typing import Literal

import numpy as np

from umbra.connectors import Input, Module, Output, Parameters, from_param, param
from umbra.connectors.commands import GrabCommand, GripperCommand
from umbra.connectors.limits import MAX_TOOL_ANGULAR_RAD_S, MAX_TOOL_SPEED_M_S
from umbra.connectors.messages import CameraModel, Contour, Twist
from umbra.connectors.params import NonNegative
from umbra.connectors.states import GuardState, ServoReason, ServoState
from umbra.connectors.status_figures import error_figure
from umbra.connectors.tracking import TrackStatus
from umbra.modules.calib.camera_model import Intrinsics
from umbra.modules.calib.distortion import undistort_points
from umbra.modules.servo.features import (
    FeatureError,
    MomentFeatures,
    checked_intrinsics,
    features_from_normalized_contour,
)
from umbra.modules.servo.goal import goal_from_pixels, goal_from_standoff
from umbra.modules.servo.law import ServoGains
from umbra.modules.servo.stages import (
    Observation,
    ServoOutput,
    ServoStages,
    StageSettings,
)

ERROR_NAMES = ("error_x", "error_y", "error_z", "error_roll")


class VsServo(Module["VsServo.Params"]):
    """Visual servo on a rectangular colored patch of known size (image-moment features).

    From each contour: normalized area (depth: the patch size is known), centroid (x, y) and
    principal-axis angle (roll) give a 4-DOF error; ``v = -lambda L^-1 e`` gives the camera
    twist (x right, y down, z along the optical axis), clamped in speed. Stages: acquire (snake
    healthy for ``acquire_frames``), approach (until every error is within tolerance for
    ``settle_frames``), final grab (advance ``grab_distance`` along the optical axis at
    ``grab_speed``, close the gripper), done. Any snake failure stops at once (zero twist) and
    asks for the operator; ``resume`` (or ``start``) on the operator input restarts acquisition,
    ``pause`` holds (zero twist) until a resume, ``abort`` aborts and opens the gripper. The
    goal is a standoff in metres (patch centred on ``goal_u``, ``goal_v``, default the
    principal point) or, with ``goal_area_px``, a target image of the patch in pixels.
    Intrinsics come from the ``camera`` input when connected (undistorting the contour), else
    from ``fx``, ``fy``, ``u0``, ``v0``.
    """

    TYPE = "vsServo"

    class Params(Parameters):
        patch_width: float = param(0.08, "patch long side", unit="m", gt=0)
        patch_height: float = param(0.05, "patch short side", unit="m", gt=0)
        fx: float = param(
            600.0, "focal length x (unused when `camera` is connected)", unit="px", gt=0
        )
        fy: float = param(
            600.0, "focal length y (unused when `camera` is connected)", unit="px", gt=0
        )
        u0: float = param(320.0, "principal point u (unused when `camera` is connected)", unit="px")
        v0: float = param(240.0, "principal point v (unused when `camera` is connected)", unit="px")
        goal_mode: Literal["standoff", "pixels"] = param("standoff", "how the goal is given")
        standoff: float = param(0.2, "goal depth of the patch (goal_mode standoff)", unit="m", gt=0)
        goal_area_px: float = param(
            20000.0, "goal patch area in the image (goal_mode pixels)", unit="px^2", gt=0
        )
        goal_u: float | None = param(
            None, "goal patch centre u (default principal point)", unit="px"
        )
        goal_v: float | None = param(
            None, "goal patch centre v (default principal point)", unit="px"
        )
        goal_roll_deg: float = param(0.0, "goal principal-axis angle from +u", unit="deg")
        gains: list[NonNegative] = param(
            [0.8, 0.8, 0.6, 0.8],
            "gains x, y, z, roll",
            unit="1/s",
            min_length=4,
            max_length=4,
            tunable=True,
        )
        max_linear: float = param(
            0.05, "linear speed clamp", unit="m/s", gt=0, le=MAX_TOOL_SPEED_M_S, safety=True
        )
        max_angular: float = param(
            0.3,
            "angular speed clamp",
            unit="rad/s",
            gt=0,
            le=MAX_TOOL_ANGULAR_RAD_S,
            safety=True,
        )
        acquire_frames: int = param(5, "healthy frames before the approach", ge=1)
        settle_frames: int = param(5, "in-tolerance frames that end the approach", ge=1)
        tolerance_xy: float = param(0.002, "x, y tolerance", unit="m", gt=0)
        tolerance_z: float = param(0.003, "depth tolerance", unit="m", gt=0)
        tolerance_roll_deg: float = param(1.0, "roll tolerance", unit="deg", gt=0)
        grab_distance: float = param(0.05, "final open-loop advance", unit="m", ge=0)
        grab_speed: float = param(0.02, "speed of the final advance", unit="m/s", gt=0, safety=True)
        gripper_close_time: float = param(0.5, "wait after closing the gripper", unit="s", ge=0)
        max_contour_age: float = param(
            0.5, "older contours count as lost", unit="s", gt=0, safety=True
        )
        camera_frame: str = param("camera", "frame of the output twist")
        progress_period_s: float = param(
            1.0, "log stage and errors this often (0: only stage changes)", unit="s", ge=0
        )

    contour = Input(Contour, trigger=True, doc="tracked patch from vsSnake")
    operator = Input(GrabCommand, required=False, doc="operator: start / pause / resume / abort")
    camera = Input(CameraModel, required=False, feedback=True, doc="calibrated camera (zoom)")
    guard = Input(
        GuardState,
        required=False,
        feedback=True,
        doc="the safety guard's status (REG_VEL): the final grab counts only the advance it passed",
    )
    twist = Output(
        Twist,
        frame=from_param("camera_frame"),
        origin_from=("contour",),  # as old as the image the snake found the patch in
        doc="camera velocity command",
    )
    status = Output(
        ServoState,
        origin_from=("contour",),  # as old as the image its errors come from
        doc="stage, why (a code, the snake's failed checks, the exact text), errors, "
        "operator-assistance requests",
    )
    gripper = Output(GripperCommand, events=True, doc="gripper command: open / close")

    def start(self) -> None:
        p = self.params
        self.patch_area = p.patch_width * p.patch_height
        self._stage_entered: dict[str, float] = {}
        self._stage_times: dict[str, float] = {}
        self._current: tuple[str, float] | None = None
        self._last_progress = -np.inf
        self._last_reason = ""
        self._t0: float | None = None
        self._camera_seq = -1
        self._intrinsics = Intrinsics(p.fx, p.fy, 0.0, p.u0, p.v0)
        self._distortion: np.ndarray | None = None
        gains = ServoGains(tuple(p.gains), p.max_linear, p.max_angular)  # type: ignore[arg-type]
        settings = StageSettings(
            acquire_frames=p.acquire_frames,
            settle_frames=p.settle_frames,
            tolerance=(
                p.tolerance_xy,
                p.tolerance_xy,
                p.tolerance_z,
                np.radians(p.tolerance_roll_deg),
            ),
            grab_distance=p.grab_distance,
            grab_speed=p.grab_speed,
            gripper_close_time=p.gripper_close_time,
            max_contour_age=p.max_contour_age,
        )
        self.stages = ServoStages(self._goal(), gains, settings)
        self._last_key: tuple[str, str, str] | None = None
        self._assists = 0

    def retune(self, old: Parameters) -> None:
        """The gains changed: the stages go on with the new ones (the clamps are safety
        parameters, never changed live)."""
        p = self.params
        self.stages.gains = ServoGains(tuple(p.gains), p.max_linear, p.max_angular)  # type: ignore[arg-type]

    def _goal(self) -> MomentFeatures:
        p = self.params
        K = self._intrinsics
        centre = (
            (K.u0 if p.goal_u is None else p.goal_u),
            (K.v0 if p.goal_v is None else p.goal_v),
        )
        roll = float(np.radians(p.goal_roll_deg))
        if p.goal_mode == "pixels":
            return goal_from_pixels(p.goal_area_px, centre, roll, K, self.patch_area)
        return goal_from_standoff(p.standoff, K, centre, roll)

    def _update_camera(self, now: float) -> None:
        model = self.camera.get(now)
        if model is None or model.seq == self._camera_seq:
            return
        self._camera_seq = model.seq
        self._intrinsics = checked_intrinsics(Intrinsics.of_model(model))
        dist = np.asarray(model.dist, dtype=float)
        self._distortion = dist if np.any(dist) else None
        self._K = model.K
        self.stages.goal = self._goal()

    def _normalized(self, vertices: np.ndarray) -> np.ndarray:
        if self._distortion is None:
            return self._intrinsics.normalized_from_pixels(vertices)
        # the whole model, skew included (cv2.undistortPoints drops K's skew)
        points = np.asarray(vertices, dtype=np.float64).reshape(-1, 2)
        return undistort_points(points, self._K, self._distortion, normalized=True)

    def _observe(self, now: float) -> Observation | None:
        contour = self.contour.get(now)
        if contour is None:
            return None
        received = now - self.contour.age(now)
        if contour.status == TrackStatus.FAILED:
            return Observation(
                None, healthy=False, stamp=received, reason=contour.reason, checks=contour.checks
            )
        if contour.status != TrackStatus.TRACKING:
            return Observation(None, healthy=True, stamp=received)
        try:
            normalized = self._normalized(np.asarray(contour.vertices, dtype=float))
            features = features_from_normalized_contour(normalized, self.patch_area)
        except FeatureError as exc:
            return Observation(
                None, healthy=False, stamp=received, reason=str(exc), code=ServoReason.NO_FEATURES
            )
        return Observation(features, healthy=True, stamp=received)

    def step(self, now: float) -> None:
        self._update_camera(now)
        command = self.operator.get(now)
        if command is not None and self.operator.fresh:
            self.stages.operator(command.action)
        observation = self._observe(now)
        guard = self.guard.value
        if observation is not None and guard is not None:
            observation = dataclasses.replace(
                observation,
                commands_pass=guard.passing,
                guard_travel_z=float(guard.travel_m[2]),
            )
        out = self.stages.step(now, observation)
        self.twist.send(Twist(vector=out.camera_twist, frame=self.params.camera_frame))
        if out.gripper is not None:
            self.gripper.send(GripperCommand(action=out.gripper))
        self._report(out, now)

    def _track_stage(self, now: float, out: ServoOutput, values: dict[str, float]) -> None:
        """Time spent per stage, and progress lines for the person watching the run."""
        if self._current is None or self._current[0] != out.stage:
            if self._current is not None:
                stage, since = self._current
                self._stage_times[stage] = self._stage_times.get(stage, 0.0) + now - since
            self._current = (out.stage, now)
            if out.assist:
                self._last_reason = out.reason
                self.log.warning("stage %s: %s (%s)", out.stage, out.message, out.reason)
            else:
                self.log.info("stage %s: %s", out.stage, out.message)
        if self._t0 is None:
            self._t0 = now
        period = self.params.progress_period_s
        if period and now - self._last_progress >= period:
            self._last_progress = now
            errors = ", ".join(error_figure(k, v) for k, v in values.items())
            self.log.info(
                "t=%.1f s stage %s%s",
                now - self._t0,
                out.stage,
                f" errors {errors}" if errors else "",
            )

    def _report(self, out: ServoOutput, now: float = 0.0) -> None:
        values = {
            name: float(value)
            for name, value in zip(ERROR_NAMES, out.error, strict=True)
            if np.isfinite(value)
        }
        self._track_stage(now, out, values)
        key = (out.stage, out.message, out.reason)
        if key != self._last_key and out.assist:
            self._assists += 1
        self._last_key = key
        self.status.send(
            ServoState(
                stage=out.stage,
                message=out.message,
                assist=out.assist,
                reason=out.reason,
                values=values,
                code=out.code,
                checks=out.checks,
            )
        )

    def summary(self) -> dict[str, object]:
        times = dict(self._stage_times)
        if self._current is not None:
            stage = self._current[0]
            times[stage] = times.get(stage, 0.0)  # the final stage's time is open-ended
        return {
            "stage": str(self.stages.stage),
            "assist_requests": self._assists,
            "assist_reason": self._last_reason,
            "stage_times_s": {str(k): round(v, 3) for k, v in times.items()},
        }
