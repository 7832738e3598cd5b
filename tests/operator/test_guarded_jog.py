"""The jog reaches the arm only through REG_VEL; vsServo's pause / start / abort."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from umbra.connectors.messages import Twist
from umbra.connectors.states import GuardReason, ServoReason, ServoStage, ServoState
from umbra.modules.arm.reg_vel import RegVel
from umbra.modules.servo.features import MomentFeatures
from umbra.modules.servo.stages import ABORTED, ACQUIRE, PAUSED, ServoStages
from umbra.runtime.graph.check import load_graph
from umbra.runtime.harness import ModuleHarness

PARAMS = {"timeout": 0.1, "max_linear": 0.05, "max_angular": 0.3}


def _twist(*v: float) -> Twist:
    return Twist(vector=np.array(v, dtype=float), frame="camera")


def test_a_held_jog_replaces_the_command_and_stops_when_its_keepalives_stop() -> None:
    with ModuleHarness(RegVel, PARAMS) as h:
        h.push("command", _twist(0.01, 0, 0, 0, 0, 0))
        halt = ServoState(
            stage=ServoStage.ASSIST,
            assist=True,
            reason="snake failure",
            code=ServoReason.SNAKE_FAILED,
        )
        h.push("halt", halt)
        h.step(dt=0.01)
        assert not np.any(h.output("twist").vector)  # halted by the servo
        h.push("jog", _twist(0, 0, 0.2, 0, 0, 0))  # too fast: clamped
        h.step(dt=0.01)
        np.testing.assert_allclose(h.output("twist").vector, [0, 0, 0.05, 0, 0, 0])
        assert h.output("status").passing and h.output("status").jog
        for _ in range(9):  # no keep-alive for 0.1 s and more: zero, and why
            h.step(dt=0.012)
        assert not np.any(h.output("twist").vector)
        assert h.output("status").reason.startswith("jog: no new command for 0.1")
        assert h.output("status").code == GuardReason.WATCHDOG and h.output("status").jog
        h.push("jog", _twist(0, 0, 0, 0, 0, 0))  # release: back to the (halted) command
        h.step(dt=0.01)
        assert h.output("status").reason.startswith("halted by assist")
        assert h.output("status").code == GuardReason.HALTED and not h.output("status").jog
        assert 8 <= h.module.summary()["jog_ticks"] <= 9  # 0.1 s of jog at 100 Hz


def test_a_non_finite_jog_is_zero_with_the_reason() -> None:
    with ModuleHarness(RegVel, PARAMS) as h:
        h.push("command", _twist(0.01, 0, 0, 0, 0, 0))
        h.push("jog", _twist(np.nan, 0, 0, 0, 0, 0))
        h.step(dt=0.01)
        assert not np.any(h.output("twist").vector)
        assert "jog: command rejected: expected 6 finite numbers" in h.output("status").reason


def test_the_graphs_jog_path_passes_the_guard() -> None:
    plan = load_graph(str(Path(__file__).resolve().parents[2] / "graphs" / "tool_pickup.yaml"))
    conns = {(c.src.module, c.src.port, c.dst.module, c.dst.port) for c in plan.connections}
    assert ("console", "jog", "register", "jog") in conns
    assert ("console", "seed", "snake", "seed") in conns
    assert ("operator", "seed", "console", "sim_seed") in conns


def _stages() -> ServoStages:
    goal = MomentFeatures(x_n=0.0, y_n=0.0, a_n=1.0, alpha=0.0)
    return ServoStages(goal)


def test_pause_holds_resume_and_start_restart_abort_opens_the_gripper() -> None:
    s = _stages()
    s.step(0.0, None)  # the initial "open" goes out
    s.operator("pause")
    out = s.step(0.1, None)
    assert (out.stage, out.assist, out.message) == (PAUSED, False, "paused by the operator")
    assert not np.any(out.camera_twist)
    s.operator("resume")
    assert s.stage == ACQUIRE
    s.operator("abort")
    out = s.step(0.2, None)
    assert out.stage == ABORTED and out.gripper == "open"
    s.operator("start")
    assert s.stage == ACQUIRE
