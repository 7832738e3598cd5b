"""The operator's *Stop* on SketchWorld (the judge of Active Sketch): a ``stop`` on its
``operator`` input ends the run, attended or not, as a normal stop with the verdict "stopped by
the operator" (World's rule, :mod:`umbra.modules.world.operator_stop`); the console's
``stop_run`` reaches it in graphs/active_sketch_page.yaml."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tests.operator.test_console_module import _harness, _operator, _pump, _state
from tests.sketch.test_sketch_verdict import DT, _path, _q_at
from umbra.connectors.commands import StopRun
from umbra.connectors.messages import JointState
from umbra.modules.arm.arm_params import ArmParams
from umbra.modules.sketch.tool_poses import DOWN, tool_pose
from umbra.modules.world.sketch_world import SketchWorld
from umbra.runtime.graph.check import load_graph
from umbra.runtime.harness import ModuleHarness

GRAPH = Path(__file__).resolve().parents[2] / "graphs" / "active_sketch_page.yaml"
NAMES = ArmParams().joint_names


def _grab_pipe(h: ModuleHarness, height_mm: float) -> None:
    """Play grab_pipe and close the true gripper ``height_mm`` above the pipe's axis, then run
    0.3 s (three reports at the objects' 10 Hz)."""
    pipe = h.module.judge.scene.pipe
    q = _q_at(tool_pose(pipe.center + np.array([0.0, 0.0, height_mm / 1e3]), DOWN, pipe.axis))
    h.push("path", _path("grab_pipe", "p1"))
    for i in range(30):
        h.push("joint_state", JointState(names=NAMES, position=q, gripper=1.0 if i < 2 else 0.0))
        h.step(dt=DT)


def test_an_attended_stop_ends_the_run_with_the_macros_that_succeeded() -> None:
    with ModuleHarness(SketchWorld, {"end_after": ["grab_pipe"]}, attended=True) as h:
        _grab_pipe(h, 2.0)
        # end_after is met, but an attended run goes on until its operator stops it
        assert h.module.summary()["succeeded"] == ["grab_pipe"]
        assert h.stop_request is None and h.module.summary()["stopped"] == ""
        h.step(dt=DT)
        assert h.stop_request is None
        h.push("operator", StopRun(by="ann"))
        h.step(dt=DT)
        verdict = "stopped by the operator; succeeded: grab_pipe"
        assert h.stop_request == (verdict, 0)
        assert h.module.summary()["stopped"] == verdict
        h.push("operator", StopRun(by="ann"))  # a second Stop changes nothing
        h.step(dt=DT)
        assert h.module.summary()["stopped"] == verdict


def test_a_stop_before_any_success_is_a_normal_stop_that_says_so() -> None:
    with ModuleHarness(SketchWorld) as h:
        _grab_pipe(h, 11.0)  # missed: 11 mm off the axis
        assert h.module.summary()["succeeded"] == [] and h.stop_request is None
        h.push("operator", StopRun())
        h.step(dt=DT)
        verdict = "stopped by the operator; no macro succeeded"
        assert h.stop_request == (verdict, 0)  # a normal stop: the misses are in macro_verdicts
        summary = h.module.summary()
        assert summary["stopped"] == verdict
        assert [v["outcome"] for v in summary["macro_verdicts"]] == ["missed"]


def test_the_consoles_stop_reaches_sketch_world_and_ends_the_run() -> None:
    """A page holding control presses *Stop run*: the console sends ``stop``, SketchWorld
    (attended: it never ends the run by itself) ends it (real websocket, real modules)."""
    with _harness() as console, ModuleHarness(SketchWorld, attended=True) as world:
        page = _operator(console)
        try:
            state = _state(console, page, lambda s: s["phase"] == "running")
            assert state["commands"]["stop"] is True
            page.send("action", action="stop")
            _pump(console, lambda: len(console.outputs("stop_run")) == 1)
            assert isinstance(console.outputs("stop_run")[0], StopRun)
            world.step(dt=DT)
            assert world.stop_request is None
            world.push("operator", console.outputs("stop_run")[-1])
            world.step(dt=DT)
            assert world.stop_request == ("stopped by the operator; no macro succeeded", 0)
        finally:
            page.close()


def test_active_sketch_page_wires_the_consoles_stop_to_the_world() -> None:
    plan = load_graph(str(GRAPH))
    assert plan.modules["console"].cls.TYPE == "OperatorConsole"
    assert plan.modules["world"].cls.TYPE == "SketchWorld"
    wired = {str(c) for c in plan.connections}
    assert "console.stop_run ~> world.operator" in wired
