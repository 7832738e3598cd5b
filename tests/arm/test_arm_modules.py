"""REG_VEL, ROTATE_KIN, WOLVERINE_KIN and WOLVERINE_JNTS through the module harness."""

from __future__ import annotations

import numpy as np
import pytest

from umbra.connectors.commands import GripperAction, GripperCommand
from umbra.connectors.errors import UserError
from umbra.connectors.messages import JointRates, JointState, Twist
from umbra.connectors.states import GuardReason, GuardStage, ServoReason, ServoState
from umbra.modules.arm.dh import puma560
from umbra.modules.arm.jacobian import jacobian
from umbra.modules.arm.reg_vel import RegVel
from umbra.modules.arm.rotate_kin import RotateKin
from umbra.modules.arm.wolverine_jnts import WolverineJnts
from umbra.modules.arm.wolverine_kin import WolverineKin
from umbra.modules.geometry.transforms import transform_from_xyz_rpy_deg, twist_tool_from_camera
from umbra.runtime.harness import ModuleHarness

PUMA = puma560()
Q_NOMINAL = np.radians([0, 45, -180, 0, 45, 0])
T_TOOL_CAMERA = transform_from_xyz_rpy_deg([0.0, 0.06, 0.04], [0.0, 0.0, 90.0])


def camera_twist(vector, frame="camera"):
    return Twist(vector=np.asarray(vector, dtype=float), frame=frame)


# -- REG_VEL ---------------------------------------------------------------------------------


def test_reg_vel_passes_fresh_commands_and_zeroes_stale_ones():
    with ModuleHarness(RegVel, {"timeout": 0.05, "max_linear": 0.1}) as h:
        sent = h.step(0.01)
        assert not np.any(h.output("twist").vector)
        assert h.output("status").reason == "no command received yet"
        assert h.output("status").code == GuardReason.NO_COMMAND_YET
        h.push("command", camera_twist([0.01, 0, 0, 0, 0, 0.1]))
        h.step(0.01)
        np.testing.assert_allclose(h.output("twist").vector, [0.01, 0, 0, 0, 0, 0.1])
        assert h.output("twist").frame == "camera"
        assert h.output("status").stage == GuardStage.PASSING
        assert h.output("status").code == GuardReason.PASSING
        for _ in range(4):
            h.step(0.01)
        assert np.any(h.output("twist").vector)  # 0.05 s old: still within the timeout
        sent = h.step(0.01)
        assert not np.any(h.output("twist").vector)
        assert "no new command for 0.060 s (link watchdog 0.050 s)" in sent["status"][0].reason
        assert sent["status"][0].code == GuardReason.WATCHDOG
        assert sent["status"][0].stage == GuardStage.ZERO


def test_reg_vel_zeroes_when_the_producer_is_gone_or_halts():
    with ModuleHarness(RegVel) as h:
        h.push("command", camera_twist([0.01, 0, 0, 0, 0, 0]))
        h.step(0.01)
        assert np.any(h.output("twist").vector)
        h.module.registers["command"].link_alive = False
        h.step(0.01)
        assert not np.any(h.output("twist").vector)
        assert h.output("status").reason == "command producer is gone"
        assert h.output("status").code == GuardReason.PRODUCER_GONE
        h.module.registers["command"].link_alive = True
        halt = ServoState(
            stage="assist", assist=True, reason="snake failure: size", code=ServoReason.SNAKE_FAILED
        )
        h.push("halt", halt)
        h.push("command", camera_twist([0.01, 0, 0, 0, 0, 0]))
        h.step(0.01)
        assert not np.any(h.output("twist").vector)
        assert h.output("status").reason == "halted by assist: snake failure: size"
        assert h.output("status").code == GuardReason.HALTED


def test_reg_vel_clamps_and_rejects_a_wrong_frame():
    with ModuleHarness(RegVel, {"max_linear": 0.05, "max_angular": 0.2}) as h:
        h.push("command", camera_twist([0.3, 0.4, 0, 0, 0, 1.0]))
        h.step(0.01)
        np.testing.assert_allclose(h.output("twist").vector, [0.03, 0.04, 0, 0, 0, 0.2])
        h.push("command", camera_twist([0.01, 0, 0, 0, 0, 0], frame="tool"))
        h.step(0.01)
        assert not np.any(h.output("twist").vector)
        assert "expected `camera`" in h.output("status").reason
        assert h.output("status").code == GuardReason.WRONG_FRAME


def test_reg_vel_passes_gripper_commands_only_while_passing():
    with ModuleHarness(RegVel) as h:
        h.push("gripper_in", GripperCommand(action=GripperAction.CLOSE))
        assert "gripper" not in h.step(0.01)  # no command yet: not passing
        h.push("command", camera_twist(np.zeros(6)))
        h.push("gripper_in", GripperCommand(action=GripperAction.CLOSE))
        assert h.step(0.01)["gripper"][0].action == GripperAction.CLOSE


# -- ROTATE_KIN ------------------------------------------------------------------------------


def test_rotate_kin_uses_the_graph_frames_with_the_lever_arm():
    with ModuleHarness(RotateKin, frames={"tool->camera": T_TOOL_CAMERA}) as h:
        xi = np.array([0.01, -0.02, 0.03, 0.1, -0.2, 0.3])
        h.push("camera_twist", camera_twist(xi))
        out = h.step(0.01)["tool_twist"][0]
        assert out.frame == "tool"
        np.testing.assert_allclose(out.vector, twist_tool_from_camera(T_TOOL_CAMERA, xi))
        # Roll about the camera axis alone moves the tool point (camera offset 6 cm, 4 cm).
        h.push("camera_twist", camera_twist([0, 0, 0, 0, 0, 1.0]))
        out = h.step(0.01)["tool_twist"][0]
        assert np.linalg.norm(out.vector[:3]) == pytest.approx(0.06)
        assert h.step(0.01) == {}  # nothing new: nothing sent


def test_rotate_kin_mount_params_and_missing_frames():
    params = {"mount_xyz": [0.0, 0.06, 0.04], "mount_rpy_deg": [0.0, 0.0, 90.0]}
    with ModuleHarness(RotateKin, params) as h:
        np.testing.assert_allclose(h.module.T_tool_camera, T_TOOL_CAMERA, atol=1e-15)
    with pytest.raises(UserError, match="no static frame `tool->camera`"):
        ModuleHarness(RotateKin).start()
    with pytest.raises(UserError, match="give both"):
        ModuleHarness(RotateKin, {"mount_xyz": [0, 0, 0]}).start()


# -- WOLVERINE_KIN ---------------------------------------------------------------------------


def joint_state(q, names=PUMA.names):
    return JointState(names=names, position=np.asarray(q, dtype=float))


def test_wolverine_kin_resolves_the_tool_twist_at_the_joint_state():
    tool = {"tool_xyz": [0.0, 0.0, 0.1], "tool_rpy_deg": [0.0, 0.0, 0.0]}
    with ModuleHarness(WolverineKin, tool) as h:
        h.push("joint_state", joint_state(Q_NOMINAL))
        xi_tool = np.array([0.02, -0.01, 0.03, 0.0, 0.1, -0.05])
        h.push("tool_twist", Twist(vector=xi_tool, frame="tool"))
        sent = h.step(0.01)
        rates = sent["joint_rates"][0]
        assert rates.names == PUMA.names and not rates.near_singularity
        pose = sent["tool_pose"][0]
        T_tool = transform_from_xyz_rpy_deg([0, 0, 0.1], [0, 0, 0])
        np.testing.assert_allclose(pose.matrix, PUMA.fk(Q_NOMINAL, T_tool), atol=1e-12)
        assert (pose.parent, pose.child) == ("base", "tool")
        # J(q) rates reproduce the twist, in base coordinates at the tool point.
        R = pose.matrix[:3, :3]
        achieved = jacobian(PUMA, Q_NOMINAL, T_tool) @ rates.rates
        np.testing.assert_allclose(achieved, np.r_[R @ xi_tool[:3], R @ xi_tool[3:]], atol=1e-10)
        assert sent["status"][0].values["manipulability"] > 0


def test_wolverine_kin_sends_zero_without_a_usable_joint_state():
    with ModuleHarness(WolverineKin, {"max_state_age": 0.05}) as h:
        h.push("tool_twist", Twist(vector=np.ones(6) * 0.01, frame="tool"))
        sent = h.step(0.01)
        assert not np.any(sent["joint_rates"][0].rates)
        assert sent["status"][0].reason == "no joint state yet"
        h.push("joint_state", joint_state(Q_NOMINAL, names=("a", "b", "c", "d", "e", "f")))
        h.push("tool_twist", Twist(vector=np.ones(6) * 0.01, frame="tool"))
        assert "differ from" in h.step(0.01)["status"][0].reason
        h.push("joint_state", joint_state([0.1, np.nan, 0, 0, 0, 0]))
        h.push("tool_twist", Twist(vector=np.ones(6) * 0.01, frame="tool"))
        sent = h.step(0.01)
        assert "unknown angles" in sent["status"][0].reason
        assert not np.any(sent["joint_rates"][0].rates)
        h.push("joint_state", joint_state(Q_NOMINAL))
        h.step(0.1)
        h.push("tool_twist", Twist(vector=np.ones(6) * 0.01, frame="tool"))
        sent = h.step(0.0)
        assert not np.any(sent["joint_rates"][0].rates)
        assert "0.100 s old" in sent["status"][0].reason


def test_wolverine_kin_flags_the_wrist_singularity_and_stays_bounded():
    q = Q_NOMINAL.copy()
    q[4] = 0.0
    with ModuleHarness(WolverineKin) as h:
        h.push("joint_state", joint_state(q))
        h.push("tool_twist", Twist(vector=np.r_[0, 0, 0, 0.1, 0, 0], frame="tool"))
        sent = h.step(0.01)
        rates = sent["joint_rates"][0]
        assert rates.near_singularity
        assert np.all(np.abs(rates.rates) <= PUMA.qd_max)
        assert "near singularity" in sent["status"][0].message


def test_wolverine_kin_reports_a_bad_dh_file_as_a_parameter_error(tmp_path):
    path = tmp_path / "arm.yaml"
    path.write_text("joints:\n  - {name: j1, alpha_deg: lots}\n")
    with pytest.raises(UserError, match=r"arm.yaml:2: error: joints\[0\].alpha_deg"):
        ModuleHarness(WolverineKin, {"dh_file": str(path)})
    path.write_text("joints:\n  - {name: a, a: 0.5}\n  - {name: b, a: 0.3}\n")
    with ModuleHarness(WolverineKin, {"dh_file": str(path)}) as h:
        assert h.module.params.joint_names == ("a", "b")


# -- WOLVERINE_JNTS --------------------------------------------------------------------------


def rates_msg(rates, names=PUMA.names):
    return JointRates(names=names, rates=np.asarray(rates, dtype=float))


def test_wolverine_jnts_sim_integrates_commanded_rates():
    params = {"initial_q_deg": np.degrees(Q_NOMINAL).tolist(), "lag_tau": 0.0, "accel_max": 1e3}
    with ModuleHarness(WolverineJnts, params) as h:
        sent = h.step(0.01)
        np.testing.assert_allclose(sent["joint_state"][0].position, Q_NOMINAL)
        assert sent["status"][0].reason == "no joint rates yet"
        rates = np.array([0.1, -0.1, 0.05, 0.2, -0.2, 0.3])
        for _ in range(50):
            h.push("rates", rates_msg(rates))
            h.step(0.01)
        h.step(0.0)  # read back the state at the same instant
        # Each step reads the state (integrating the held command) before taking the new one:
        # a command acts from the next tick on, so 50 ticks move the joints for 49 x 10 ms.
        expected = Q_NOMINAL + rates * 0.49
        # (less the trapezoid on the first 2 ms sub-step, where the rate steps up).
        np.testing.assert_allclose(h.output("joint_state").position, expected, atol=5e-4)
        assert h.output("joint_state").names == PUMA.names


def test_wolverine_jnts_zeroes_stale_or_foreign_rates_and_moves_the_gripper():
    params = {"initial_q_deg": np.degrees(Q_NOMINAL).tolist(), "max_command_age": 0.05}
    with ModuleHarness(WolverineJnts, params) as h:
        h.push("rates", rates_msg(np.full(6, 0.1)))
        h.step(0.01)
        h.step(0.1)
        assert "old" in h.output("status").reason
        q_held = h.output("joint_state").position
        for _ in range(10):
            h.step(0.01)
        # Commands stopped: the joints decelerate and stop (accel limit), not run away.
        assert np.max(np.abs(h.output("joint_state").position - q_held)) < 0.02
        assert np.max(np.abs(h.output("joint_state").velocity)) < 1e-3  # lag decays to rest
        h.push("rates", rates_msg(np.full(6, 0.1), names=tuple("abcdef")))
        h.step(0.01)
        assert "arm has" in h.output("status").reason
        h.push("gripper_in", GripperCommand(action=GripperAction.CLOSE))
        h.run(60, 0.01)
        assert h.output("joint_state").gripper == 0.0


def test_wolverine_jnts_calibration_error_shows_only_in_the_true_state():
    params = {
        "initial_q_deg": np.degrees(Q_NOMINAL).tolist(),
        "calibration_error_deg": [0.5, -0.5, 0.3, 0, 0, 0],
    }
    with ModuleHarness(WolverineJnts, params) as h:
        sent = h.step(0.01)
        reported = sent["joint_state"][0].position
        true = sent["true_joint_state"][0].position
        np.testing.assert_allclose(true - reported, np.radians([0.5, -0.5, 0.3, 0, 0, 0]))
        true_state, state = sent["true_joint_state"][0], sent["joint_state"][0]
        assert true_state.names == state.names == PUMA.names
        assert true_state.gripper == state.gripper == 1.0
        np.testing.assert_array_equal(true_state.velocity, state.velocity)


def test_wolverine_jnts_backend_errors_are_user_errors():
    with pytest.raises(UserError, match="outside the joint limits"):
        ModuleHarness(WolverineJnts, {"initial_q_deg": [0, 0, 180, 0, 0, 0]}).start()
    with pytest.raises(UserError, match=r"calibration_error_deg`? needs 6"):
        ModuleHarness(WolverineJnts, {"calibration_error_deg": [1.0]}).start()


def test_reg_vel_reports_the_travel_it_let_through() -> None:
    """REG_VEL's odometer: the linear travel [m] of the twists it passed, in its frame (what a
    dead-reckoning grab measures its advance on), nothing while it holds the arm."""
    with ModuleHarness(RegVel, {"timeout": 0.1, "max_origin_age": 0.25}) as h:
        for _ in range(50):  # 0.5 s at 10 mm/s along z
            h.push("command", Twist(vector=np.array([0, 0, 0.01, 0, 0, 0.0]), frame="camera"))
            h.step(0.01)
        for _ in range(30):  # no new command: held at zero by the watchdog after 0.1 s
            h.step(0.01)
        travel = h.output("status").travel_m
        assert travel[2] == pytest.approx(0.005 + 0.001, abs=2e-4)  # + the 0.1 s hold
        assert travel[0] == 0.0 and travel[1] == 0.0
