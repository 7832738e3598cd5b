"""The station's logic without a browser: the state line, reasons in plain words (from their
codes) said once, the run's life cycle, the jog pad's names and the refusal counts."""

from __future__ import annotations

import numpy as np

from tests.operator.helpers import Page, image
from tests.operator.test_console_module import _harness, _operator, _pump, _state
from umbra.connectors.messages import Pose, Poses
from umbra.connectors.states import (
    GuardReason,
    GuardStage,
    GuardState,
    Outcome,
    ServoReason,
    ServoStage,
    ServoState,
    Verdict,
)
from umbra.connectors.tracking import SnakeCheck
from umbra.modules.operator.jog_labels import jog_labels
from umbra.modules.operator.message_board import MessageBoard
from umbra.modules.operator.scene_view import scene_view
from umbra.modules.operator.state_line import (
    ENDED,
    RUNNING,
    STARTING,
    commands_available,
    phase_of,
    state_line,
)

#: the reason the issue found shown five times, as vsSnake gives it, and its checks' codes
SNAKE_REASON = (
    "snake failure: no colour edge under 100% of the contour (featureless image); "
    "area changed -63% in one frame; centroid jumped 41 px in one frame"
)
SNAKE_CHECKS = (SnakeCheck.NO_EDGE, SnakeCheck.AREA_CHANGE, SnakeCheck.CENTROID_JUMP)
SNAKE_WORDS = (
    "the tracker lost the patch's edge; the patch's size jumped; the patch jumped in the image"
)


def test_a_failed_snake_reads_in_plain_words_from_its_codes_each_once() -> None:
    failed = _servo("assist", reason=SNAKE_REASON, checks=SNAKE_CHECKS)
    assert failed.words() == SNAKE_WORDS
    # two checks that say the same thing are said once; the exact text plays no part
    shape = (SnakeCheck.ASPECT_CHANGE, SnakeCheck.ASPECT_DRIFT, SnakeCheck.AREA_CHANGE)
    assert _servo("assist", reason="(reworded)", checks=shape).words() == (
        "the patch's shape changed; the patch's size jumped"
    )
    late = _servo("assist", reason="contour is 0.612 s old", code=ServoReason.CONTOUR_LATE)
    assert late.words() == "the tracker's outline came too late"


def test_a_repeated_message_is_one_line_with_its_count_and_the_exact_text_a_click_away() -> None:
    board = MessageBoard(size=3)
    for k in range(5):
        lead = "the grab stopped and asks for you"
        board.post_reason(lead, SNAKE_WORDS, SNAKE_REASON, t=1.0 + k)
    lines = board.for_page()
    assert len(lines) == 1
    assert lines[0]["count"] == 5 and lines[0]["t"] == 5.0 and lines[0]["id"] == 5
    assert lines[0]["text"].startswith("the grab stopped and asks for you: the tracker lost")
    assert lines[0]["detail"] == SNAKE_REASON
    board.post("refused click: take control first", 6.0, to="abc", level="error")
    board.post("refused click: take control first", 6.5, to="def", level="error")  # another page
    board.post("viewer 2 is watching", 7.0)
    board.post("viewer 3 is watching", 8.0)  # the oldest of 4 distinct lines goes (size 3)
    texts = [(m["text"], m["to"]) for m in board.for_page()]
    assert texts == [
        ("viewer 3 is watching", "*"),
        ("viewer 2 is watching", "*"),
        ("refused click: take control first", "def"),
    ]
    # a repeat moves its line to the top again
    board.post("refused click: take control first", 9.0, to="def", level="error")
    assert board.for_page()[0]["count"] == 2 and board.for_page()[0]["t"] == 9.0


def _servo(
    stage: str,
    message: str = "",
    reason: str = "",
    code: ServoReason | None = None,
    checks: tuple[SnakeCheck, ...] = (),
) -> ServoState:
    """A vsServo state; a failed snake's code when checks are given."""
    if code is None:
        code = ServoReason.SNAKE_FAILED if checks else ServoReason.NONE
    return ServoState(
        stage=ServoStage(stage),
        message=message,
        reason=reason,
        assist=stage == "assist",
        code=code,
        checks=checks,
    )


def _guard(code: GuardReason, reason: str = "") -> GuardState:
    stage = GuardStage.PASSING if code == GuardReason.PASSING else GuardStage.ZERO
    return GuardState(stage=stage, code=code, reason=reason)


PASSING = _guard(GuardReason.PASSING)


def test_the_state_line_says_stage_control_what_the_robot_does_and_why_it_is_stopped() -> None:
    waiting = _servo("acquire", "waiting: snake has no contour", code=ServoReason.NOT_SEEDED)
    guard_zero = _guard(GuardReason.NO_COMMAND_YET, "no command received yet")
    line = state_line(RUNNING, waiting, guard_zero, None, "", jogging=False)
    assert line.stage == "acquire" and line.control.startswith("nobody")
    assert "click the patch" in line.doing and "starts by itself" in line.doing
    assert line.stopped == "no command yet"
    approach = state_line(RUNNING, _servo("approach"), PASSING, None, "ann", False)
    assert (approach.doing, approach.stopped, approach.control) == (
        "moving toward the patch",
        "",
        "ann",
    )
    old = _guard(GuardReason.STALE_DATA, "command made from sensor data 1.30 s old (limit 0.25 s)")
    held = state_line(RUNNING, _servo("approach"), old, None, "ann", False)
    assert held.stopped == "the camera data behind the command is too old"
    assert held.stopped_detail == "command made from sensor data 1.30 s old (limit 0.25 s)"
    snake = _servo("assist", reason=SNAKE_REASON, checks=SNAKE_CHECKS)
    assist = state_line(RUNNING, snake, guard_zero, None, "ann", False)
    assert assist.doing == "stopped: the grab asks for you"
    assert assist.stopped == SNAKE_WORDS
    assert assist.stopped_detail == SNAKE_REASON
    paused = _servo("paused", reason="paused by the operator", code=ServoReason.PAUSED)
    held_paused = state_line(RUNNING, paused, guard_zero, None, "ann", False)
    assert held_paused.stopped == "paused by the operator"
    done = state_line(RUNNING, _servo("done"), guard_zero, None, "ann", False)
    assert done.stopped == done.stopped_detail == "grab complete; the arm holds"
    jog = state_line(RUNNING, _servo("paused"), PASSING, None, "ann", True)
    assert jog.doing.startswith("jogging by hand") and jog.stopped == ""
    judged = Verdict(
        stage="missed",
        message="missed: tool point 11.02 mm from the grasp point",
        outcome=Outcome.MISSED,
    )
    ended = state_line(ENDED, _servo("done"), guard_zero, judged, "ann", False)
    assert ended.phase == ENDED and ended.doing == "the run has ended"
    assert ended.verdict.startswith("missed: tool point 11.02 mm") and ended.outcome == "missed"
    running = Verdict(stage="running", message="no grasp yet")
    assert state_line(RUNNING, _servo("approach"), PASSING, running, "ann", False).verdict == ""


def test_the_life_cycle_starts_runs_and_ends_and_commands_follow_the_stage() -> None:
    assert phase_of(images_seen=False, stopping=False) == STARTING
    assert phase_of(images_seen=True, stopping=False) == RUNNING
    assert phase_of(images_seen=True, stopping=True) == ENDED
    assert commands_available(RUNNING, "acquire") == {
        "start": False,  # nothing to start: the seed starts the approach
        "pause": True,
        "resume": False,
        "abort": True,
        "stop": False,  # no judge connected to end the run
    }
    assert commands_available(RUNNING, "paused", can_stop=True) == {
        "start": True,
        "pause": False,
        "resume": True,
        "abort": True,
        "stop": True,
    }
    assert commands_available(RUNNING, "done")["start"] is True
    assert not any(commands_available(ENDED, "approach", can_stop=True).values())
    assert not any(commands_available(STARTING, "-").values())


def test_the_jog_pad_names_directions_as_seen_in_the_live_image() -> None:
    T_tool_camera = np.eye(4)
    T_tool_camera[:3, 3] = [0.0, 0.0, -0.12]  # the pick-up's palm camera: axes as the tool's
    tool = {(j["axis"], j["sign"]): j for j in jog_labels("tool", T_tool_camera)}
    assert len(tool) == 8
    assert tool[(2, -1)]["label"] == "away (lift)" and tool[(2, -1)]["axis_name"] == "tool z-"
    assert tool[(2, 1)]["label"] == "toward (down)"
    assert tool[(0, 1)]["label"] == "→ right" and tool[(1, -1)]["label"] == "↑ up the image"
    # a camera turned half a turn about the tool's x axis: tool z+ now lifts, tool y+ is up
    flipped = T_tool_camera.copy()
    flipped[:3, :3] = np.diag([1.0, -1.0, -1.0])
    turned = {(j["axis"], j["sign"]): j["label"] for j in jog_labels("tool", flipped)}
    assert turned[(2, 1)] == "away (lift)" and turned[(1, 1)] == "↑ up the image"
    assert turned[(3, 1)] == "↺ turn anticlockwise"
    camera = {(j["axis"], j["sign"]): j["label"] for j in jog_labels("camera", None)}
    assert camera[(2, 1)] == "toward (down)" and camera[(3, 1)] == "↻ turn clockwise"
    assert jog_labels("tool", None) == []  # no tool->camera frame: no tool-frame pad


def test_the_refused_count_on_the_page_leaves_out_the_holders_own_refusals() -> None:
    with _harness() as h:
        operator = _operator(h)
        viewer = Page(h.module.url)
        try:
            _pump(h, lambda: viewer.session in h.module.arbiter.sessions)
            seq = h.module.image.value.seq
            operator.send("click", u=900.0, v=20.0, frame=seq)  # outside: the holder's own
            viewer.send("click", u=340.0, v=230.0, frame=seq)  # a page without control
            viewer.send("action", action="abort")
            _pump(h, lambda: h.module.counts["refused"] == 3)
            assert h.module.counts["refused_others"] == 2
            state = _state(h, viewer, lambda s: s["refused"] == 2)
            assert state["phase"] == RUNNING and state["panels"]["video"]
            assert h.module.summary()["refused_others"] == 2
        finally:
            operator.close()
            viewer.close()


def test_a_stopping_console_tells_its_pages_the_run_ended_with_the_verdict() -> None:
    verdict = "grasped: tool point 0.61 mm from the grasp point, roll error 0.05 deg"
    h = _harness()
    h.__enter__()
    page = Page(h.module.url)
    try:
        _pump(h, lambda: page.session in h.module.arbiter.sessions)
        grasped = Verdict(
            stage="grasped", message=verdict, values={"time_s": 14.2}, outcome=Outcome.SUCCEEDED
        )
        h.push("world", grasped)
        _state(h, page, lambda s: s["line"]["verdict"] == verdict)
    finally:
        h.__exit__(None, None, None)  # stops the module: its pages get the last state
    last = None
    try:
        while True:
            last = page.recv_text("state", timeout=1.0)
    except Exception:  # the socket closed with the server: every state was read
        pass
    page.close()
    assert last is not None and last["phase"] == ENDED
    assert last["line"]["verdict"] == verdict and last["world"]["values"]["time_s"] == 14.2
    assert not any(last["commands"].values())


def test_the_3d_panel_draws_in_the_arms_base_frame() -> None:
    links = Poses(
        matrices=np.stack([np.eye(4), np.eye(4)]),
        children=("link1", "flange"),
        frame="base",
    )
    T_table_camera = np.eye(4)
    T_table_camera[:3, 3] = [0.4, 0.1, 0.3]
    T_base_table = np.eye(4)
    T_base_table[2, 3] = 0.25
    camera = Pose(matrix=T_table_camera, parent="table", child="camera")
    patch = Pose(matrix=np.eye(4), parent="table", child="patch")
    scene = scene_view(links, camera, patch, T_base_table, None, 77.3, 16 / 9, (0.06, 0.04))
    assert [link["name"] for link in scene["links"]] == ["link1", "flange"]
    T = np.array(scene["camera"]["T"]).reshape(4, 4)
    assert np.allclose(T[:3, 3], [0.4, 0.1, 0.55])  # the table is 0.25 m above the base
    assert abs(scene["camera"]["tan_half_fov_x"] - np.tan(np.radians(77.3 / 2))) < 1e-4
    assert scene["patch"] is None  # no static frame from the base to the patch's parent given
    assert (
        scene_view(None, camera, patch, T_base_table, T_base_table, 77.3, 1.0, (0.06, 0.04)) is None
    )


def test_the_plot_gets_its_whole_history_now_and_then_and_new_rows_in_between() -> None:
    with _harness(serve=False) as h:

        def servo_steps(n: int) -> None:
            for k in range(n):
                values = {"error_x": 0.01 * k, "error_y": 0.0, "error_z": -0.002, "error_roll": 0.1}
                h.push("servo", ServoState(stage=ServoStage.APPROACH, values=values))
                h.push("image", image())
                h.step(dt=0.1)

        servo_steps(5)
        first = h.module.view.error_rows(h.module._last_now)
        assert first["errors_full"] and len(first["errors"]) == 5
        assert first["errors"][1][1:] == [10.0, 0.0, -2.0, round(0.1 * 180 / np.pi, 3)]  # mm, deg
        assert h.module.view.error_rows(h.module._last_now) == {"errors": [], "errors_full": False}
        servo_steps(3)
        more = h.module.view.error_rows(h.module._last_now)
        assert not more["errors_full"] and len(more["errors"]) == 3
        assert more["errors"][0][0] > first["errors"][-1][0]
        servo_steps(20)  # 2 s later: the whole history again
        again = h.module.view.error_rows(h.module._last_now)
        assert again["errors_full"] and len(again["errors"]) == 28
