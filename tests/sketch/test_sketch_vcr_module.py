"""VCR_PLAYER as a module: a lost console, a stale command and a guard stop halt it on the path."""

from __future__ import annotations

import numpy as np
import pytest

from umbra.connectors.messages import JointState
from umbra.connectors.path_messages import VcrCommand
from umbra.connectors.sketch_messages import Macro, SketchPrimitive
from umbra.connectors.states import GuardReason, GuardStage, GuardState
from umbra.modules.arm.dh import puma560
from umbra.modules.geometry.transforms import translation
from umbra.modules.sketch.macros import macro_keys
from umbra.modules.sketch.path_check import PathLimits, plan_path
from umbra.modules.sketch.session import Q_READY
from umbra.modules.trajectory.vcr_module import VcrPlayer
from umbra.modules.world.scene_objects import SketchScene
from umbra.runtime.harness import ModuleHarness

TABLE = puma560()
DT = 0.01


@pytest.fixture(scope="module")
def path():
    T_ft = translation(0, 0, 0.14)
    line = SketchPrimitive(primitive_id="L", kind="line", points=SketchScene.nominal().pipe.ends)
    keys = macro_keys(Macro.GRAB_PIPE, line, TABLE.fk(Q_READY, T_ft), 1.0)
    return plan_path(keys, TABLE, T_ft, Q_READY, 1.0, PathLimits(), path_id="p1")


class _Arm:
    """The arm follows the player's desired joints exactly (what matters here is the player)."""

    def __init__(self, h: ModuleHarness) -> None:
        self.h = h
        self.q = Q_READY.copy()
        self.offset = np.zeros(6)  # where the arm is, off the path (rad)

    def tick(self, n: int = 1) -> None:
        for _ in range(n):
            self.h.push("joint_state", JointState(names=TABLE.names, position=self.q.copy()))
            self.h.step(DT)
            player = self.h.module.player
            if player is not None:
                self.q = player.joint_path.q(player.vcr.state.s) + self.offset


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
        late = GuardState(
            stage=GuardStage.ZERO, code=GuardReason.WATCHDOG, reason="command is 0.210 s old"
        )
        h.push("guard", late)
        arm.tick()
        state = h.output("state")
        assert state.mode == "halted" and state.reason.startswith("guard stop: command is 0.210")
        s_halt = state.s
        h.push("guard", GuardState(stage=GuardStage.PASSING, code=GuardReason.PASSING))
        arm.tick(50)
        assert h.output("state").s == s_halt  # stays halted until the operator plays again
        _command(h, "play")
        arm.tick(20)
        assert h.output("state").mode == "playing" and h.output("state").s > s_halt


def test_lost_console_halts_smoothly_and_stale_commands_are_refused(path):
    with ModuleHarness(VcrPlayer, {"max_command_age": 0.5}) as h:
        arm = _Arm(h)
        h.push("path", path)
        h.module.command.set_link_alive(True)  # the runtime sees the console's process
        arm.tick()
        _command(h, "play")
        arm.tick(150)
        h.module.command.set_link_alive(False)  # the console's process is gone
        arm.tick(40)
        state = h.output("state")
        assert state.mode == "halted" and state.reason == "console lost" and state.s_dot == 0.0
        h.module.command.set_link_alive(True)
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

    from umbra.modules.trajectory.player import PathPlayer
    from umbra.modules.trajectory.vcr import VcrError

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


def test_a_stale_command_or_stale_joints_halt_a_moving_player_on_the_path(path):
    with ModuleHarness(VcrPlayer, {"max_command_age": 0.5}) as h:
        arm = _Arm(h)
        h.push("path", path)
        arm.tick()
        _command(h, "play")
        arm.tick(150)
        assert h.output("state").mode == "playing"
        h.push("command", VcrCommand(action="speed", speed=0.5, path_id="p1", stamp=h.now - 0.8))
        arm.tick(40)
        state = h.output("state")
        assert state.mode == "halted" and state.s_dot == 0.0
        assert state.reason.startswith("stale command 'speed'") and "expected at most 0.500" in (
            state.reason
        )
        assert state.speed == 1.0  # the stale command itself was not obeyed
        assert np.all(h.output("twist").vector == 0.0)  # halted: no motion commanded
        _command(h, "play")
        arm.tick(100)
        assert h.output("state").mode == "playing"
        # the arm's joint state stops arriving: the player freezes at once
        for _ in range(30):
            h.step(DT)
        state = h.output("state")
        assert state.mode == "halted" and state.reason.startswith("joint state is stale")
        # meanwhile the arm coasted on along the path (here 0.1 path units: some joint is more
        # than max_start_error off where the path froze): play takes the path up where it is
        player = h.module.player
        coasted = player.joint_path.q(state.s + 0.1)
        assert np.max(np.abs(coasted - player.joint_path.q(state.s))) > 0.05
        arm.q = coasted
        h.push("joint_state", JointState(names=TABLE.names, position=coasted))
        _command(h, "play")
        h.step(DT)
        state_after = h.output("state")
        assert state_after.mode == "playing" and abs(state_after.s - (state.s + 0.1)) < 0.01


def test_a_new_path_is_refused_while_playing_and_a_start_off_the_path_is_refused(path):
    import msgspec

    other = msgspec.structs.replace(path, path_id="p2")
    with ModuleHarness(VcrPlayer, {}) as h:
        arm = _Arm(h)
        h.push("path", path)
        arm.tick()
        _command(h, "play")
        arm.tick(100)
        h.push("path", other)
        arm.tick()
        state = h.output("state")
        assert state.path_id == "p1" and state.mode == "playing"
        assert "path p2 refused: p1 is playing; pause it first" in state.reason
        _command(h, "pause")
        arm.tick(60)
        assert h.output("state").mode == "paused"
        # the arm is moved away while paused (e.g. jogged): the player does not pull it back,
        # and refuses to play on from where the path is no longer
        arm.offset = np.radians([0, 0, 0, 0, 6.0, 0])
        arm.tick(5)
        assert np.all(h.output("twist").vector == 0.0)
        _command(h, "play")
        arm.tick(5)
        state = h.output("state")
        assert state.mode == "paused"
        assert "play refused: the arm is 6.0 deg off path p1" in state.reason


def test_a_console_not_yet_known_alive_does_not_halt_the_path(path):
    """At start a command may arrive before its producer's liveliness token: the console is not
    yet known, not lost (``Register.link_gone``), and the path plays on."""
    with ModuleHarness(VcrPlayer, {"max_command_age": 0.5}) as h:
        arm = _Arm(h)
        h.push("path", path)
        h.module.command.set_link_alive(False)  # in another process, its token not yet seen
        arm.tick()
        _command(h, "play")
        arm.tick(40)
        state = h.output("state")
        assert state.mode == "playing" and state.s > 0.0
