"""The state line says what a click on the patch does now, and a failed tracker in words, in
the one vocabulary (the stages' and the tracker checks' words), whatever the exact texts."""

from __future__ import annotations

import msgspec
import pytest

from tests.operator.helpers import rectangle_contour
from umbra.connectors.messages import Contour
from umbra.connectors.states import (
    GuardReason,
    GuardStage,
    GuardState,
    ServoReason,
    ServoStage,
    ServoState,
)
from umbra.connectors.tracking import SnakeCheck
from umbra.modules.operator.state_line import (
    CLICK_ENDED,
    CLICK_NO_GRAB,
    CLICK_STARTING,
    ENDED,
    RUNNING,
    STARTING,
    click_does,
    state_line,
)

HELD = GuardState(stage=GuardStage.ZERO, code=GuardReason.HALTED, reason="halted by paused")


def _servo(stage: ServoStage, code: ServoReason = ServoReason.NONE, **kw: object) -> ServoState:
    return ServoState(stage=stage, message=f"exact text of {stage}", code=code, **kw)


def _failed(*checks: SnakeCheck) -> Contour:
    """A failed contour with the checks ``checks``, its exact reason full of figures."""
    contour = rectangle_contour("failed", "exact reason: area changed -63.2% in one frame")
    return msgspec.structs.replace(contour, checks=checks)


def test_a_click_after_a_jog_says_the_arm_waits_for_resume_not_that_the_approach_starts() -> None:
    waiting = _servo(ServoStage.ACQUIRE, ServoReason.NOT_SEEDED)
    before = state_line(RUNNING, waiting, None, None, "ann", jogging=False)
    assert "starts by itself" in before.click
    # the jog is held: the console pauses the grab (vsServo may not have said so yet)
    during = state_line(RUNNING, waiting, None, None, "ann", jogging=True)
    assert "Resume" in during.click and "starts by itself" not in during.click
    # after the jog vsServo is paused: a click seeds, the arm waits for Resume
    after = state_line(RUNNING, _servo(ServoStage.PAUSED), HELD, None, "ann", jogging=False)
    assert after.click == "seeds the tracker; the arm holds until you press Resume"
    assert "starts by itself" not in after.click + after.doing


@pytest.mark.parametrize(
    ("stage", "moves", "then"),
    [
        (ServoStage.ACQUIRE, True, "starts by itself"),
        (ServoStage.APPROACH, True, "goes on"),
        (ServoStage.FINAL_GRAB, True, "goes on"),
        (ServoStage.PAUSED, False, "Resume"),
        (ServoStage.ASSIST, False, "Resume"),
        (ServoStage.DONE, False, "Start"),
        (ServoStage.ABORTED, False, "Start"),
    ],
)
def test_every_stage_says_what_a_click_does(stage: ServoStage, moves: bool, then: str) -> None:
    words = click_does(RUNNING, _servo(stage), jogging=False)
    assert "tracker" in words and then in words
    assert ("holds" not in words) == moves, words


def test_a_click_before_the_first_picture_after_the_run_and_without_a_grab() -> None:
    assert click_does(STARTING, None, False) == CLICK_STARTING
    assert click_does(ENDED, _servo(ServoStage.APPROACH), False) == CLICK_ENDED
    assert click_does(RUNNING, None, False) == CLICK_NO_GRAB
    line = state_line(ENDED, _servo(ServoStage.DONE), None, None, "", jogging=False)
    assert line.click == CLICK_ENDED and line.click_without_control.startswith("nothing")


def test_a_tracker_failure_while_paused_is_said_in_the_checks_words() -> None:
    contour = _failed(SnakeCheck.NO_EDGE, SnakeCheck.AREA_CHANGE)
    paused = state_line(
        RUNNING, _servo(ServoStage.PAUSED), HELD, None, "ann", jogging=False, contour=contour
    )
    assert paused.tracker == (
        "the tracker failed: the tracker lost the patch's edge; the patch's size jumped; "
        "click the patch to re-seed it"
    )
    assert "63.2" not in paused.tracker  # the exact text stays in the log, not the line
    # tracking: nothing to say
    fine = state_line(
        RUNNING,
        _servo(ServoStage.PAUSED),
        HELD,
        None,
        "ann",
        jogging=False,
        contour=rectangle_contour(),
    )
    assert fine.tracker == ""
    # without named checks: the code's words alone
    bare = state_line(
        RUNNING, _servo(ServoStage.DONE), HELD, None, "ann", jogging=False, contour=_failed()
    )
    assert bare.tracker == f"{ServoReason.SNAKE_FAILED.words}; click the patch to re-seed it"


def test_a_failure_the_line_already_says_as_the_arms_stop_is_not_said_twice() -> None:
    checks = (SnakeCheck.NO_EDGE,)
    assist = _servo(ServoStage.ASSIST, ServoReason.SNAKE_FAILED, checks=checks, assist=True)
    line = state_line(RUNNING, assist, HELD, None, "ann", jogging=False, contour=_failed(*checks))
    assert line.stopped == SnakeCheck.NO_EDGE.words and line.tracker == ""
