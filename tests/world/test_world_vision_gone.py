"""The world's verdict "the vision process is gone": only for a producer seen alive that then
vanished, never for one whose liveliness token has not come yet (a process slow to start under
load sends its first samples before its token is known)."""

from __future__ import annotations

import numpy as np

from umbra.connectors.messages import JointState
from umbra.connectors.states import Outcome, ServoReason, ServoStage, ServoState
from umbra.modules.world.world import SimWorld
from umbra.runtime.harness import ModuleHarness

FRAMES = {
    "base->table": np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0.25], [0, 0, 0, 1.0]]),
    "flange->tool": np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0.14], [0, 0, 0, 1.0]]),
    "tool->camera": np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, -0.12], [0, 0, 0, 1.0]]),
}
NAMES = tuple(f"j{i}" for i in range(1, 7))
Q = np.deg2rad([14.482, 45.603, -182.743, 0.0, -42.86, -165.518])


def _tick(world: ModuleHarness, alive: bool) -> None:
    world.push("joint_state", JointState(names=NAMES, position=Q, gripper=1.0))
    waiting = ServoState(
        stage=ServoStage.ACQUIRE, message="waiting for a seed", code=ServoReason.NOT_SEEDED
    )
    world.push("servo_status", waiting)
    world.module.registers["servo_status"].set_link_alive(alive)
    world.step(0.01)


def test_a_producer_not_yet_known_alive_is_not_gone() -> None:
    with ModuleHarness(SimWorld, {"end_after_stop_s": 0.1}, frames=FRAMES) as world:
        for _ in range(100):  # 1 s without its token, samples coming
            _tick(world, alive=False)
        assert world.stop_request is None
        assert world.module.result["outcome"] == Outcome.PENDING


def test_a_producer_seen_alive_that_vanishes_stops_the_run() -> None:
    with ModuleHarness(SimWorld, {"end_after_stop_s": 0.1}, frames=FRAMES) as world:
        for _ in range(10):
            _tick(world, alive=True)
        for _ in range(30):
            _tick(world, alive=False)
        assert "the vision process is gone" in str(world.module.result["verdict"])
