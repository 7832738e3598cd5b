"""The whole grab chain in closed loop: vsServo -> REG_VEL -> ROTATE_KIN -> WOLVERINE_KIN ->
WOLVERINE_JNTS (sim, with an unknown joint calibration error), the camera rendered from the
arm's *true* joint angles. The servo reaches the patch although the arm's own kinematics are off
by centimetres: what an open-loop grab would miss by."""

from __future__ import annotations

import numpy as np

from tests.servo.servo_scene import SCENE_PARAMS, camera_above, patch_corners, project
from umbra.connectors.messages import Contour
from umbra.modules.arm.dh import puma560
from umbra.modules.arm.reg_vel import RegVel
from umbra.modules.arm.rotate_kin import RotateKin
from umbra.modules.arm.wolverine_jnts import WolverineJnts
from umbra.modules.arm.wolverine_kin import WolverineKin
from umbra.modules.geometry.transforms import invert_transform, transform_from_xyz_rpy_deg
from umbra.modules.servo.vsservo import VsServo
from umbra.runtime.harness import ModuleHarness

PUMA = puma560()
Q0_DEG = [10.0, 50.0, -170.0, 5.0, 40.0, 15.0]
T_TOOL_CAMERA = transform_from_xyz_rpy_deg([0.0, 0.06, 0.04], [0.0, 0.0, 90.0])
CALIBRATION_ERROR_DEG = [0.8, -0.6, 0.7, 0.0, 0.5, 0.0]
DT = 0.02
STANDOFF, GRAB = 0.2, 0.04


def camera_pose(q: np.ndarray) -> np.ndarray:
    return PUMA.fk(q) @ T_TOOL_CAMERA


def test_closed_loop_grab_reaches_the_patch_despite_calibration_error():
    # Put the patch 0.35 m in front of the starting camera, off-centre and turned by 25 deg.
    q0 = np.radians(Q0_DEG)
    T_base_patch = camera_pose(q0 + np.radians(CALIBRATION_ERROR_DEG)) @ invert_transform(
        camera_above(0.04, -0.03, 0.35, 25.0)
    )
    servo = ModuleHarness(
        VsServo,
        {
            **SCENE_PARAMS,
            "standoff": STANDOFF,
            "grab_distance": GRAB,
            "grab_speed": 0.02,
            "max_linear": 0.04,
        },
    )
    register = ModuleHarness(RegVel, {"timeout": 0.1, "max_linear": 0.05, "max_angular": 0.4})
    rotate = ModuleHarness(RotateKin, frames={"tool->camera": T_TOOL_CAMERA})
    kin = ModuleHarness(WolverineKin)
    joints = ModuleHarness(
        WolverineJnts, {"initial_q_deg": Q0_DEG, "calibration_error_deg": CALIBRATION_ERROR_DEG}
    )
    harnesses = (servo, register, rotate, kin, joints)
    for h in harnesses:
        h.start()
    joints.step(0.0)
    stage = "acquire"
    for _ in range(2500):
        q_true = joints.output("true_joint_state").position
        T_patch_camera = invert_transform(T_base_patch) @ camera_pose(q_true)
        pixels = project(T_patch_camera, patch_corners())
        servo.push(
            "contour",
            Contour(vertices=pixels, centroid=pixels.mean(0), area=0.0, orientation=0.0, axes=[]),
        )
        sent = servo.step(DT)
        stage = sent["status"][0].stage
        register.push("command", sent["twist"][0])
        if "gripper" in sent:
            register.push("gripper_in", sent["gripper"][0])
        sent = register.step(DT)
        rotate.push("camera_twist", sent["twist"][0])
        if "gripper" in sent:
            joints.push("gripper_in", sent["gripper"][0])
        kin.push("tool_twist", rotate.step(DT)["tool_twist"][0])
        kin.push("joint_state", joints.output("joint_state"))
        joints.push("rates", kin.step(DT)["joint_rates"][0])
        joints.step(DT)
        if stage == "done":
            break
    for h in harnesses:
        h.stop()
    assert stage == "done"
    state = joints.output("joint_state")
    assert state.gripper == 0.0  # closed
    # The true camera ends centred over the patch, at the standoff less the final advance,
    # its image x axis along the patch's long side (or opposite: the axis has no direction).
    q_true = joints.output("true_joint_state").position
    T_patch_camera = invert_transform(T_base_patch) @ camera_pose(q_true)
    np.testing.assert_allclose(T_patch_camera[:3, 3], [0.0, 0.0, STANDOFF - GRAB], atol=4e-3)
    assert abs(T_patch_camera[1, 0]) < np.sin(np.radians(2.0))
    # Where the controller believes the camera is differs by centimetres: an open-loop grab
    # planned on the arm's own kinematics would miss by that much.
    believed = camera_pose(state.position)[:3, 3]
    assert np.linalg.norm(believed - camera_pose(q_true)[:3, 3]) > 0.01
