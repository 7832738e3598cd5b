"""An attended run (``umbra run --attended``): the simulated operator stays off, the world's
verdict is published (and re-sent) but the run goes on until the person stops it."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from umbra.connectors.messages import Contour, JointState
from umbra.connectors.module import ModuleContext
from umbra.modules.arm.arm_params import ArmParams
from umbra.modules.world.operator_sim import OperatorSim
from umbra.modules.world.world import SimWorld
from umbra.runtime.harness import ModuleHarness

DT = 0.05
#: the shipped pick-up's start: camera 35 cm above the table
Q0 = np.radians([14.482, 45.603, -182.743, 0.0, -42.86, -165.518])
NAMES = ArmParams().joint_names


def _frames() -> dict[str, np.ndarray]:
    """The shipped pick-up's static frames."""
    frames = {key: np.eye(4) for key in ("base->table", "flange->tool", "tool->camera")}
    frames["base->table"][2, 3] = 0.25
    frames["flange->tool"][2, 3] = 0.14
    frames["tool->camera"][2, 3] = -0.12
    return frames


FRAMES = _frames()


def _patch() -> Contour:
    return Contour(
        vertices=np.array([[300.0, 220.0], [340.0, 220.0], [340.0, 260.0], [300.0, 260.0]]),
        centroid=np.array([320.0, 240.0]),
        area=1600.0,
        orientation=0.0,
        axes=np.array([40.0, 40.0]),
    )


def test_operator_sim_never_seeds_in_an_attended_run() -> None:
    with ModuleHarness(OperatorSim, {"click_delay_s": 0.1}, attended=True) as h:
        for _ in range(100):  # 5 s with the patch in view, 50 times the delay
            h.push("truth", _patch())
            h.step(dt=DT)
        assert h.outputs("seed") == []
        summary = h.module.summary()
    assert summary["clicked_after_s"] is None and summary["attended"] is True
    # the same module unattended clicks within its delay: the attended run is what held it
    with ModuleHarness(OperatorSim, {"click_delay_s": 0.1}) as h:
        for _ in range(10):
            h.push("truth", _patch())
            h.step(dt=DT)
        assert len(h.outputs("seed")) == 1


def _close_gripper(h: ModuleHarness) -> None:
    """The arm at Q0 (the tool far above the patch) opens, then closes its gripper."""
    for gripper in (1.0, 0.5, 0.0):
        h.push("joint_state", JointState(names=NAMES, position=Q0, gripper=gripper))
        h.step(dt=DT)


def test_world_publishes_its_verdict_and_leaves_the_attended_run_going() -> None:
    with ModuleHarness(SimWorld, frames=FRAMES, attended=True) as h:
        h.step(dt=DT)
        assert h.output("status").stage == "running"  # the life cycle: running first
        _close_gripper(h)
        verdict = h.output("status")
        assert verdict.stage == "missed"
        assert verdict.message.startswith("missed: tool point ")
        assert verdict.values["position_error_mm"] > 50.0  # the tool is ~20 cm above the patch
        assert h.stop_request is None  # published, not ended
        for _ in range(int(3.0 / DT)):  # 3 s on: re-sent every second, never replaced
            h.push("joint_state", JointState(names=NAMES, position=Q0, gripper=0.0))
            h.step(dt=DT)
        resent = [s for s in h.outputs("status") if s.stage == "missed"]
        assert 3 <= len(resent) <= 4
        assert {s.message for s in resent} == {verdict.message}
        assert h.stop_request is None
        assert h.module.summary()["verdict"] == verdict.message


def test_world_ends_an_unattended_run_with_its_verdict() -> None:
    with ModuleHarness(SimWorld, frames=FRAMES) as h:
        _close_gripper(h)
        verdict = h.output("status")
        assert verdict.stage == "missed"
        assert h.stop_request == (verdict.message, 1)


def test_world_waits_past_its_timeout_in_an_attended_run() -> None:
    params = {"timeout_s": 0.5}
    with ModuleHarness(SimWorld, params, frames=FRAMES, attended=True) as h:
        for _ in range(30):  # 1.5 s, three times the timeout, gripper open
            h.push("joint_state", JointState(names=NAMES, position=Q0, gripper=1.0))
            h.step(dt=DT)
        assert h.stop_request is None and h.output("status").stage == "running"
    with ModuleHarness(SimWorld, params, frames=FRAMES) as h:
        for _ in range(30):
            h.push("joint_state", JointState(names=NAMES, position=Q0, gripper=1.0))
            h.step(dt=DT)
        assert h.stop_request is not None and "no grasp within 0.5 s" in h.stop_request[0]


def test_a_verdict_ends_the_run_only_when_nobody_attends_it(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """``ModuleContext.end_run``, the one rule every judge ends a run by (the world's grasp, the
    sketch world's macros): unattended it asks the run to stop with the exit status; attended it
    asks nothing and says so once, however often a judge comes back to it."""
    asked: list[tuple[str, int]] = []
    log = logging.getLogger("umbra.test_attended")
    alone = ModuleContext(request_stop=lambda why, code: asked.append((why, code)), log=log)
    assert alone.end_run("grasped: 1.2 mm", 0) is True
    assert asked == [("grasped: 1.2 mm", 0)]
    person = ModuleContext(
        request_stop=lambda why, code: asked.append((why, code)), log=log, attended=True
    )
    with caplog.at_level(logging.INFO, logger=log.name):
        assert person.end_run("timeout: not succeeded: open_door", 1) is False
        assert person.end_run("timeout: not succeeded: open_door", 1) is False
    assert asked == [("grasped: 1.2 mm", 0)]
    said = [r.getMessage() for r in caplog.records if "attended run" in r.getMessage()]
    assert said == [
        "attended run: timeout: not succeeded: open_door; the run goes on until its operator "
        "stops it (Ctrl-C)"
    ]
