"""Every macro ends with a verdict: SketchWorld says grasped or missed with the numbers, from the
true tool pose, when the gripper closes (grasps) or the player reports the path done."""

from __future__ import annotations

import numpy as np
import pytest

from umbra.connectors.messages import JointState
from umbra.connectors.path_messages import ToolPath, VcrState
from umbra.connectors.states import Outcome
from umbra.modules.arm.arm_params import ArmParams
from umbra.modules.geometry.transforms import rot_z
from umbra.modules.sketch.tool_poses import DOWN, tool_pose
from umbra.modules.world.ik import solve_ik
from umbra.modules.world.scene_objects import SketchScene
from umbra.modules.world.sketch_judge import SketchJudge
from umbra.modules.world.sketch_verdict import macro_verdict
from umbra.modules.world.sketch_world import SketchWorld
from umbra.runtime.harness import ModuleHarness

DT = 0.01
READY_DEG = [0.0, 45.6, -182.7, 0.0, -42.9, 0.0]
T_FLANGE_TOOL = np.eye(4)
T_FLANGE_TOOL[2, 3] = 0.14


def _closed_at(offset_m: np.ndarray, angle_deg: float = 0.0) -> SketchJudge:
    """A judge of the nominal scene whose gripper closed at the pipe's centre + ``offset_m``."""
    scene = SketchScene.nominal()
    pipe = scene.pipe
    across = rot_z(np.radians(angle_deg))[:3, :3] @ pipe.axis
    T = tool_pose(pipe.center + offset_m, DOWN, across)
    judge = SketchJudge(scene)
    judge.update(T, 1.0)
    judge.update(T, 0.0)
    return judge


def test_a_grasp_within_tolerance_reads_grasped_with_its_numbers() -> None:
    judge = _closed_at(np.array([0.0, 0.0, 0.002]), angle_deg=1.5)
    outcome, text, figures = macro_verdict("grab_pipe", judge.verdicts)
    assert outcome == "succeeded"
    assert text == "grasped: 2.0 mm off the pipe axis, 1.5 deg off it"
    assert figures["grasp_distance_mm"] == pytest.approx(2.0, abs=1e-6)
    assert figures["success"] == 1.0


def test_a_grasp_11_mm_off_reads_missed_with_the_tolerance() -> None:
    judge = _closed_at(np.array([0.0, 0.0, 0.011]))
    outcome, text, figures = macro_verdict("grab_pipe", judge.verdicts)
    assert outcome == "missed"
    assert text.startswith("missed: gripper closed 11.0 mm off the pipe axis, 0.0 deg off it")
    assert "(tolerance 5 mm, 3 deg)" in text and figures["success"] == 0.0


def test_a_close_far_from_the_pipe_says_how_far() -> None:
    judge = _closed_at(np.array([0.0, 0.0, 0.2]))
    outcome, text, _ = macro_verdict("grab_pipe", judge.verdicts)
    assert (outcome, text) == ("missed", "missed: gripper closed 200 mm off the pipe axis")
    assert macro_verdict("grab_pipe", SketchJudge(SketchScene.nominal()).verdicts)[1] == (
        "missed: the gripper never closed"
    )


def test_a_grab_that_caught_the_doors_handle_agrees_with_the_judge() -> None:
    """Grab Pipe closing on the door's handle: the judge says the grab failed (its target is
    the pipe); the verdict says missed too, with what the gripper caught and how far off."""
    scene = SketchScene.nominal()
    door = scene.door
    T = tool_pose(door.handle_center + np.array([0.0, 0.0, 0.003]), DOWN, door.handle_axis)
    judge = SketchJudge(scene)
    judge.update(T, 1.0)
    judge.update(T, 0.0)
    v = judge.verdicts
    assert v.handle_held and not np.isfinite(v.grasp_distance_m)  # the handle, not the pipe
    for macro in ("grab_pipe", "approach_side"):
        assert v.success(macro) is False
        outcome, text, figures = macro_verdict(macro, v)
        assert outcome == "missed" and figures["success"] == 0.0
        assert text.startswith("missed: the gripper caught the door's handle, ")
        assert "not the pipe" in text
        assert figures["handle_distance_mm"] == pytest.approx(v.handle_distance_m * 1e3)
        assert 0.0 <= figures["handle_distance_mm"] <= 10.0


def test_other_macros_are_worded_with_their_figures() -> None:
    judge = SketchJudge(SketchScene.nominal())
    outcome, text, _ = macro_verdict("surface_scan", judge.verdicts)
    assert (outcome, text) == ("missed", "missed: covered 0 % of the surface (goal 95 %)")
    outcome, text, _ = macro_verdict("move_around_axis", judge.verdicts)
    assert outcome == "missed" and text.startswith("missed: door opened to 0.0 deg of 80")
    assert macro_verdict("ready", judge.verdicts)[0] == "done"


def _q_at(T_base_tool: np.ndarray) -> np.ndarray:
    table = ArmParams().table
    return solve_ik(table, T_base_tool, np.radians(READY_DEG), T_FLANGE_TOOL)


def _path(macro: str, path_id: str) -> ToolPath:
    return ToolPath(
        path_id=path_id,
        macro=macro,
        names=ArmParams().joint_names,
        s=np.array([0.0, 1.0]),
        joints=np.zeros((2, 6)),
    )


@pytest.mark.parametrize(
    ("height_mm", "verdict"), [(2.0, "grasped: 2.0"), (11.0, "missed: gripper closed 11.0")]
)
def test_sketch_world_publishes_the_verdict_when_the_true_gripper_closes(
    height_mm: float, verdict: str
) -> None:
    names = ArmParams().joint_names
    with ModuleHarness(SketchWorld) as h:
        pipe = h.module.judge.scene.pipe
        T = tool_pose(pipe.center + np.array([0.0, 0.0, height_mm / 1e3]), DOWN, pipe.axis)
        q = _q_at(T)
        h.push("path", _path("grab_pipe", "p1"))
        for gripper in (1.0, 1.0, 0.0, 0.0):
            h.push("joint_state", JointState(names=names, position=q, gripper=gripper))
            h.step(dt=DT)
        verdicts = h.outputs("verdict")
        assert len(verdicts) == 1  # once per macro, not once per tick
        assert verdicts[0].stage == "grab_pipe"
        assert verdicts[0].message.startswith(verdict), verdicts[0].message
        summary = h.module.summary()["macro_verdicts"]
        assert [v["verdict"] for v in summary] == [verdicts[0].message]


def test_sketch_world_judges_a_macro_when_the_player_reports_its_path_done() -> None:
    names = ArmParams().joint_names
    q = np.radians(READY_DEG)
    with ModuleHarness(SketchWorld) as h:
        h.push("path", _path("surface_scan", "p7"))
        for _ in range(3):
            h.push("joint_state", JointState(names=names, position=q, gripper=1.0))
            h.push("vcr_state", VcrState(path_id="p7", mode="playing", progress=0.5))
            h.step(dt=DT)
        assert h.outputs("verdict") == []  # still playing: no verdict yet
        h.push("vcr_state", VcrState(path_id="p7", mode="done", progress=1.0))
        h.step(dt=DT)
        h.push("vcr_state", VcrState(path_id="p7", mode="done", progress=1.0))
        h.step(dt=DT)
        (verdict,) = h.outputs("verdict")
        assert verdict.stage == "surface_scan"
        assert verdict.message == "missed: covered 0 % of the surface (goal 95 %)"


def test_a_macro_the_world_does_not_judge_ends_done_when_played_to_its_end() -> None:
    """``ready`` played to its end: one verdict, outcome DONE (not a success, not a miss)."""
    names = ArmParams().joint_names
    q = np.radians(READY_DEG)
    with ModuleHarness(SketchWorld) as h:
        h.push("path", _path("ready", "p3"))
        h.push("joint_state", JointState(names=names, position=q, gripper=1.0))
        h.push("vcr_state", VcrState(path_id="p3", mode="done", progress=1.0))
        h.step(dt=DT)
        (verdict,) = h.outputs("verdict")
        assert verdict.stage == "ready" and verdict.outcome == Outcome.DONE
        (entry,) = h.module.summary()["macro_verdicts"]
        assert entry["outcome"] == "done"
