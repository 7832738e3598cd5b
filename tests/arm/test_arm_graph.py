"""The servo-side modules in real graphs: checked contracts and a run on the sim clock."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from umbra.modules.arm.dh import puma560
from umbra.modules.arm.reg_vel import RegVel
from umbra.modules.arm.rotate_kin import RotateKin
from umbra.modules.arm.wolverine_jnts import WolverineJnts
from umbra.modules.arm.wolverine_kin import WolverineKin
from umbra.modules.generic.constant import TwistSource
from umbra.modules.geometry.transforms import invert_transform, transform_from_xyz_rpy_deg
from umbra.runtime.errors import CheckFailed
from umbra.runtime.graph.check import check_text
from umbra.runtime.registry import Registry
from umbra.runtime.scheduler import Scheduler, SchedulerOptions

T_TOOL_CAMERA = transform_from_xyz_rpy_deg([0.0, 0.06, 0.04], [0.0, 0.0, 90.0])

SERVO_SIDE = """graph: servo_side
frames:
  tool->camera: {xyz: [0.0, 0.06, 0.04], rpy_deg: [0, 0, 90]}
modules:
  vision: {type: TwistSource, rate: 100, params: {twist: [0.02, 0, 0, 0, 0, 0.1]}}
  reg: {type: REG_VEL, rate: 100}
  rot: {type: ROTATE_KIN}
  kin: {type: WOLVERINE_KIN}
  jnts:
    type: WOLVERINE_JNTS
    rate: 100
    params: {initial_q_deg: [10, 50, -170, 5, 40, 15], lag_tau: 0.0, accel_max: 100.0}
connections:
  - vision.twist -> reg.command
  - reg.twist -> rot.camera_twist
  - rot.tool_twist -> kin.tool_twist
  - kin.joint_rates -> jnts.rates
  - jnts.joint_state ~> kin.joint_state
"""


def registry() -> Registry:
    reg = Registry()
    for cls in (TwistSource, RegVel, RotateKin, WolverineKin, WolverineJnts):
        reg.add(cls)
    return reg


def test_the_servo_side_graph_moves_the_camera_as_commanded(tmp_path: Path):
    plan = check_text(SERVO_SIDE, "servo.yaml", registry())
    scheduler = Scheduler(plan, SchedulerOptions(duration=1.0, output_dir=tmp_path))
    start_q = np.radians([10, 50, -170, 5, 40, 15])
    result = scheduler.run()
    assert result.exit_code == 0, result.reason
    q = scheduler.modules["jnts"].outputs["true_joint_state"].last.position
    table = puma560()
    T_start = table.fk(start_q) @ T_TOOL_CAMERA
    T_end = table.fk(q) @ T_TOOL_CAMERA
    moved = invert_transform(T_start) @ T_end
    # ~1 s at 0.02 m/s along camera x while turning at 0.1 rad/s about camera z, less the
    # ticks of latency along the chain: the camera moved along its own x axis and turned about z.
    angle = np.arctan2(moved[1, 0], moved[0, 0])
    assert angle == pytest.approx(0.1 * 0.97, abs=0.01)
    distance = np.linalg.norm(moved[:3, 3])
    assert distance == pytest.approx(0.02 * 0.97, abs=0.001)
    assert abs(moved[2, 3]) < 1e-4  # no motion along the optical axis


def test_vision_straight_into_the_driver_is_a_graph_error():
    text = SERVO_SIDE.replace(
        "  - vision.twist -> reg.command\n  - reg.twist -> rot.camera_twist\n",
        "  - vision.twist -> rot.camera_twist\n",
    )
    text = text.replace("  reg: {type: REG_VEL, rate: 100}\n", "")
    with pytest.raises(CheckFailed) as info:
        check_text(text, "servo.yaml", registry())
    assert "must be fed through a safety guard" in str(info.value)
    assert "vision -> rot -> kin -> jnts.rates" in str(info.value)


def test_frame_and_joint_mismatches_are_graph_errors(tmp_path: Path):
    text = SERVO_SIDE.replace(
        "rate: 100, params: {twist:", "rate: 100, params: {frame: tool, twist:"
    )
    with pytest.raises(CheckFailed) as info:
        check_text(text, "servo.yaml", registry())
    assert "frame mismatch: `vision.twist` is a Twist in `tool`" in str(info.value)
    dh = tmp_path / "arm.yaml"
    dh.write_text("joints:\n  - {name: a, a: 0.5}\n  - {name: b, a: 0.3}\n")
    two_joints = f"  kin: {{type: WOLVERINE_KIN, params: {{dh_file: {dh}}}}}"
    text = SERVO_SIDE.replace("  kin: {type: WOLVERINE_KIN}", two_joints)
    with pytest.raises(CheckFailed, match="joint mismatch"):
        check_text(text, "servo.yaml", registry())
