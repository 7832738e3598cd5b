"""VCR_PLAYER as a module: a lost console, a stale command and a guard stop halt it on the path."""

from __future__ import annotations

import numpy as np
import pytest

from connectors.messages import JointState, Status
from connectors.sketch_messages import SketchPrimitive, VcrCommand
from modules.arm.dh import puma560
from modules.geometry.transforms import translation
from modules.sketch.macros import macro_keys
from modules.sketch.path_check import PathLimits, plan_path
from modules.sketch.session import Q_READY
from modules.trajectory.vcr_module import VcrPlayer
from modules.world.scene_objects import SketchScene
from runtime.harness import ModuleHarness

TABLE = puma560()
DT = 0.01


@pytest.fixture(scope="module")
def path():
    T_ft = translation(0, 0, 0.14)
    line = SketchPrimitive(primitive_id="L", kind="line", points=SketchScene.nominal().pipe.ends)
    keys = macro_keys("grab_pipe", line, TABLE.fk(Q_READY, T_ft), 1.0)
    return plan_path(keys, TABLE, T_ft, Q_READY, 1.0, PathLimits(), path_id="p1")


class _Arm:
    """The arm follows the player's desired joints exactly (what matters here is the player)."""

    def __init__(self, h: ModuleHarness) -> None:
        self.h = h
        self.q = Q_READY.copy()

    def tick(self, n: int = 1) -> None:
        for _ in range(n):
            self.h.push("joint_state", JointState(names=TABLE.names, position=self.q.copy()))
            self.h.step(DT)
            player = self.h.module.player
            if player is not None:
                self.q = player.joint_path.q(player.vcr.state.s)


def _command(h, action, **kw):
    h.push("command", VcrCommand(action=action, path_id="p1", stamp=h.now, **kw))


def test_plays_and_a_guard_stop_freezes_it_on_the_path(path):
    with ModuleHarness(VcrPlayer, {}) as h:
        arm = _Arm(h)
        h.push("path", path)
        arm.tick()
        _command(h, "play")
        arm.tick(150)
        state = h.output("state")
        assert state.mode == "playing" and state.s > 0.05
        twist = h.output("twist")
        assert twist.frame == "tool" and np.linalg.norm(twist.vector[:3]) > 0.005
        h.push("guard", Status(stage="zero", reason="command is 0.210 s old"))
        arm.tick()
        state = h.output("state")
        assert state.mode == "halted" and state.reason.startswith("guard stop: command is 0.210")
        s_halt = state.s
        h.push("guard", Status(stage="passing"))
        arm.tick(50)
        assert h.output("state").s == s_halt  # stays halted until the operator plays again
        _command(h, "play")
        arm.tick(20)
        assert h.output("state").mode == "playing" and h.output("state").s > s_halt


def test_lost_console_halts_smoothly_and_stale_commands_are_refused(path):
    with ModuleHarness(VcrPlayer, {"max_command_age": 0.5}) as h:
        arm = _Arm(h)
        h.push("path", path)
        arm.tick()
        _command(h, "play")
        arm.tick(150)
        h.module.command.link_alive = False  # the console's process is gone
        arm.tick(40)
        state = h.output("state")
        assert state.mode == "halted" and state.reason == "console lost" and state.s_dot == 0.0
        h.module.command.link_alive = True
        h.push("command", VcrCommand(action="play", path_id="p1", stamp=h.now - 2.0))
        arm.tick(20)
        state = h.output("state")
        assert state.mode == "halted"
        assert state.reason == "console lost"  # the halt's reason stays; the refusal is counted
        assert h.module.summary()["refused_commands"] == 1


def test_refused_path_and_commands_for_another_path(path):
    import msgspec

    bad = msgspec.structs.replace(path, ok=False, reason="reach: sample 3")
    with ModuleHarness(VcrPlayer, {}) as h:
        arm = _Arm(h)
        h.push("path", bad)
        arm.tick()
        assert h.output("state").mode == "idle"
        assert "failed its checks: reach: sample 3" in h.output("state").reason
        assert np.all(h.output("twist").vector == 0)
        h.push("path", path)
        arm.tick()
        h.push("command", VcrCommand(action="play", path_id="other", stamp=h.now))
        arm.tick(5)
        assert "command for path 'other', loaded is 'p1'" in h.output("state").reason


def test_paths_the_servo_side_cannot_trust_are_refused(path):
    import msgspec

    from modules.trajectory.player import PathPlayer
    from modules.trajectory.vcr import VcrError

    T_ft = translation(0, 0, 0.14)
    bad_joints = np.array(path.joints)
    bad_joints[3, 1] = np.nan
    cases = {
        "non-finite parameters or joints": msgspec.structs.replace(path, joints=bad_joints),
        "joints outside the arm's limits": msgspec.structs.replace(path, joints=path.joints + 10),
        "over the limits": msgspec.structs.replace(
            path, checks={**path.checks, "rate": path.checks["rate"] * 10}
        ),
        "expected 2..20000 waypoints": msgspec.structs.replace(
            path, s=np.zeros(30_000), joints=np.zeros((30_000, 6))
        ),
    }
    for message, bad in cases.items():
        with pytest.raises(VcrError, match=message):
            PathPlayer(bad, TABLE, T_ft)
