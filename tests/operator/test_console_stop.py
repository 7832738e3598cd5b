"""The operator's *Stop*: a page's typed action through the console's ``stop_run`` to the world,
which ends the run as a normal stop with the verdict "stopped by the operator" (real websocket,
real console and world modules in the harness)."""

from __future__ import annotations

import pytest

from tests.operator.helpers import Page
from tests.operator.test_console_module import _harness, _operator, _pump, _state
from tests.world.test_attended import DT, FRAMES, NAMES, Q0, _close_gripper
from umbra.connectors.commands import StopRun
from umbra.connectors.messages import JointState, Text
from umbra.modules.world.world import SimWorld
from umbra.runtime.harness import ModuleHarness


def _stops(h: ModuleHarness) -> list[str]:
    return [type(s).__name__ for s in h.outputs("stop_run")]


def test_only_the_holder_stops_the_run_and_the_world_ends_it_stopped_by_the_operator() -> None:
    with _harness() as console, ModuleHarness(SimWorld, frames=FRAMES, attended=True) as world:
        viewer = Page(console.module.url)
        operator = _operator(console)
        try:
            _pump(console, lambda: viewer.session in console.module.arbiter.sessions)
            state = _state(console, operator, lambda s: s["phase"] == "running")
            assert state["commands"]["stop"] is True  # a judge listens (the harness's sink)
            viewer.send("action", action="stop")  # a page without control: refused
            _pump(console, lambda: console.module.counts["refused_others"] == 1)
            assert _stops(console) == []
            operator.send("action", action="stop")
            _pump(console, lambda: _stops(console) == ["StopRun"])
            assert console.outputs("stop_run")[-1].by == operator.name
            # the world, attended (it never ends a run by itself), ends it now
            world.step(dt=DT)
            assert world.stop_request is None and world.output("status").stage == "running"
            world.push("operator", console.outputs("stop_run")[-1])
            world.step(dt=DT)
            assert world.stop_request == ("stopped by the operator before a grasp", 0)
            status = world.output("status")
            assert (status.stage, status.message) == (
                "stopped",
                "stopped by the operator before a grasp",
            )
            assert world.module.summary()["verdict"] == status.message
            # the page shows the verdict, then the run's end with it
            console.push("world", status)
            state = _state(console, operator, lambda s: s["line"]["verdict"] != "")
            assert state["line"]["verdict"] == "stopped by the operator before a grasp"
            console.__exit__(None, None, None)
            ended = _last_state(operator)
            assert ended["phase"] == "ended" and not any(ended["commands"].values())
            assert ended["line"]["verdict"] == "stopped by the operator before a grasp"
        finally:
            viewer.close()
            operator.close()


def _last_state(page: Page) -> dict:
    """The last state the page got before its socket closed."""
    last: dict = {}
    while True:
        try:
            last = page.recv_text("state", timeout=2.0)
        except Exception:  # closed, or nothing more
            return last


def test_a_stop_after_the_grasp_was_judged_keeps_its_verdict_and_exit_status() -> None:
    with ModuleHarness(SimWorld, frames=FRAMES, attended=True) as world:
        _close_gripper(world)  # the tool is far above the patch: missed
        judged = world.output("status")
        assert judged.stage == "missed" and world.stop_request is None
        time_s = world.module.summary()["time_s"]
        for _ in range(10):
            world.push("joint_state", JointState(names=NAMES, position=Q0, gripper=0.0))
            world.step(dt=DT)
        world.push("operator", StopRun(by="ann"))
        world.step(dt=DT)
        verdict = f"{judged.message}; stopped by the operator"
        assert world.stop_request == (verdict, 1)  # a miss stays a miss
        assert world.output("status").stage == "missed"
        summary = world.module.summary()
        assert summary["verdict"] == verdict and summary["time_s"] == time_s  # the grasp's time
        world.push("operator", StopRun(by="ann"))  # a second Stop changes nothing
        world.step(dt=DT)
        assert world.module.summary()["verdict"] == verdict


def test_the_worlds_operator_input_takes_a_stop_and_nothing_else() -> None:
    with ModuleHarness(SimWorld, frames=FRAMES) as world:
        with pytest.raises(TypeError, match="takes StopRun, found Text"):
            world.push("operator", Text(text="stop"))  # a word is not a Stop
        world.step(dt=DT)
        assert world.stop_request is None and world.output("status").stage == "running"
