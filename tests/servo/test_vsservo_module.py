"""vsServo through the module harness: contours in, camera twist, status and gripper out."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from tests.servo.servo_scene import (
    INTRINSICS,
    SCENE_PARAMS,
    camera_above,
    move,
    patch_corners,
    project,
)
from umbra.connectors.commands import GrabAction, GrabCommand, GripperAction
from umbra.connectors.errors import UserError
from umbra.connectors.messages import CameraModel, Contour
from umbra.connectors.states import ServoReason, ServoStage
from umbra.connectors.tracking import SnakeCheck, TrackStatus
from umbra.modules.servo.vsservo import VsServo
from umbra.runtime.harness import ModuleHarness

PARAMS = {
    **SCENE_PARAMS,
    "standoff": 0.2,
    "acquire_frames": 3,
    "settle_frames": 3,
    "grab_distance": 0.04,
    "grab_speed": 0.02,
    "gripper_close_time": 0.2,
}


def contour_of(
    pixels: np.ndarray,
    status: TrackStatus = TrackStatus.TRACKING,
    reason: str = "",
    checks: tuple[SnakeCheck, ...] = (),
) -> Contour:
    return Contour(
        vertices=pixels,
        centroid=pixels.mean(axis=0) if len(pixels) else np.zeros(2),
        area=0.0,
        orientation=0.0,
        axes=np.zeros(2),
        status=status,
        reason=reason,
        checks=checks,
    )


def servo_run(h: ModuleHarness, T: np.ndarray, ticks: int, dt: float = 0.02):
    stages = []
    for _ in range(ticks):
        h.push("contour", contour_of(project(T, patch_corners())))
        sent = h.step(dt)
        twist = sent["twist"][0]
        assert twist.frame == "camera"
        T = move(T, twist.vector, dt)
        stages.append(sent["status"][0].stage)
        if stages[-1] in ("done", "assist"):
            break
    return T, stages


def test_module_runs_a_grab_to_done():
    with ModuleHarness(VsServo, PARAMS) as h:
        T, stages = servo_run(h, camera_above(0.03, -0.02, 0.35, 20.0), 2000)
        assert stages[-1] == "done"
        order = [s for i, s in enumerate(stages) if i == 0 or stages[i - 1] != s]
        assert order == ["acquire", "approach", "final_grab", "done"]
        actions = [g.action for g in h.outputs("gripper")]
        assert actions == [GripperAction.OPEN, GripperAction.CLOSE]
        np.testing.assert_allclose(T[:3, 3], [0.0, 0.0, 0.2 - 0.04], atol=3e-3)
        assert h.module.summary()["stage"] == "done"


def test_failed_snake_stops_and_resume_restarts():
    with ModuleHarness(VsServo, PARAMS) as h:
        T, stages = servo_run(h, camera_above(0.05, 0.0, 0.35, 0.0), 10)
        assert stages[-1] == "approach"
        failed = contour_of(
            project(T, patch_corners()),
            TrackStatus.FAILED,
            "aspect ratio",
            (SnakeCheck.ASPECT_CHANGE,),
        )
        h.push("contour", failed)
        sent = h.step(0.02)
        assert not np.any(sent["twist"][0].vector)
        status = sent["status"][0]
        assert status.stage == "assist" and status.assist
        assert status.reason == "snake failure: aspect ratio"
        assert status.code == ServoReason.SNAKE_FAILED
        assert status.checks == (SnakeCheck.ASPECT_CHANGE,)
        assert status.words() == "the patch's shape changed"
        h.push("operator", GrabCommand(action=GrabAction.RESUME))
        h.push("contour", contour_of(project(T, patch_corners())))
        assert h.step(0.02)["status"][0].stage == "acquire"
        h.push("operator", GrabCommand(action=GrabAction.ABORT))
        assert h.step(0.02)["status"][0].stage == ServoStage.ABORTED


def test_idle_snake_keeps_acquisition_waiting():
    with ModuleHarness(VsServo, PARAMS) as h:
        h.push("contour", contour_of(np.zeros((0, 2)), status="idle"))
        status = h.step(0.02)["status"][0]
        assert status.stage == "acquire" and status.message == "waiting: snake has no contour"
        assert status.code == ServoReason.NOT_SEEDED


def test_camera_model_input_undistorts_the_contour():
    dist = np.array([-0.25, 0.08, 0.001, -0.0005, 0.0])
    K = np.array([[INTRINSICS.fx, 0, INTRINSICS.u0], [0, INTRINSICS.fy, INTRINSICS.v0], [0, 0, 1]])
    model = CameraModel(
        fx=INTRINSICS.fx, fy=INTRINSICS.fy, u0=INTRINSICS.u0, v0=INTRINSICS.v0, dist=dist
    )
    T = camera_above(0.04, 0.03, 0.3, 10.0)
    T_camera_world = np.linalg.inv(T)
    rvec, _ = cv2.Rodrigues(T_camera_world[:3, :3])
    distorted, _ = cv2.projectPoints(patch_corners(), rvec, T_camera_world[:3, 3], K, dist)
    with ModuleHarness(VsServo, {**PARAMS, "acquire_frames": 1}) as h:
        h.push("camera", model)
        for _ in range(2):
            h.push("contour", contour_of(distorted[:, 0]))
            h.step(0.02)
        with_model = h.output("status").values
    with ModuleHarness(VsServo, {**PARAMS, "acquire_frames": 1}) as h:
        for _ in range(2):
            h.push("contour", contour_of(project(T, patch_corners())))
            h.step(0.02)
        ideal = h.output("status").values
    for name in ("error_x", "error_y", "error_z", "error_roll"):
        assert with_model[name] == pytest.approx(ideal[name], abs=1e-6)


def test_goal_in_pixels_and_bad_gains():
    params = {**PARAMS, "goal_mode": "pixels", "goal_area_px": 9150.0, "goal_u": 300.0}
    with ModuleHarness(VsServo, params) as h:
        goal = h.module.stages.goal
        # 9150 px^2 of a 0.004 m^2 patch at fx fy = 366000 px^2: depth 0.4 m.
        assert goal.a_n == pytest.approx(0.4)
        assert goal.x_n == pytest.approx(0.4 * (300.0 - INTRINSICS.u0) / INTRINSICS.fx)
    with pytest.raises(UserError, match=r"(?s)gains.*at least 4 items"):
        ModuleHarness(VsServo, {**PARAMS, "gains": [1.0]}).start()
