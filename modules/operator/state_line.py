"""The station's one state line and the run's life cycle, from the graph's statuses. Pure.

The line answers five questions at a glance: which stage the task is in, who holds control,
what the robot is doing, when it stands still why, and what a click on the patch in the live
image does now (``click``). A failed tracker is said in its checks' words (``tracker``) whatever
the stage, so a failure while paused is not only a red outline. The life cycle is ``starting`` (no
camera image yet), ``running``, ``ended`` (the process is stopping: the page says so, with the
verdict, instead of trying to reconnect to a run that is gone).

A seed starts the approach: vsServo waits in ``acquire`` for a healthy snake and moves as soon
as the snake holds the patch for a few frames. *Start* begins a new grab from a stopped stage
(done, aborted, paused, assist); in ``acquire`` there is nothing to start but the seed. A jog
pauses the grab, so after a jog a click seeds the tracker and the arm holds until *Resume*.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

from umbra.connectors.messages import Contour
from umbra.connectors.reasons import words_of
from umbra.connectors.states import (
    GuardState,
    Outcome,
    ServoReason,
    ServoStage,
    ServoState,
    Verdict,
)
from umbra.connectors.tracking import TrackStatus
from umbra.modules.servo.stages import ABORTED, ACTIVE_STAGES, ASSIST, DONE, PAUSED

STARTING, RUNNING, ENDED = "starting", "running", "ended"

#: what the robot does in each of vsServo's stages, in the operator's words
_DOING = {
    ServoStage.ACQUIRE: "waiting for the tracker to hold the patch; the approach starts by itself",
    ServoStage.APPROACH: "moving toward the patch",
    ServoStage.FINAL_GRAB: "final grab: advancing and closing the gripper",
    ServoStage.DONE: "grab complete; the arm holds",
    ServoStage.ASSIST: "stopped: the grab asks for you",
    ServoStage.PAUSED: "paused by the operator; the arm holds",
    ServoStage.ABORTED: "aborted; the arm holds with the gripper open",
}

#: what a click (or a dragged box) on the patch does in each of vsServo's stages, for the page
#: that holds control: the seed always goes to the tracker; whether the arm then moves depends on
#: the stage (after a jog or a pause the grab waits for *Resume*)
_CLICK = {
    ServoStage.ACQUIRE: "seeds the tracker; the approach then starts by itself",
    ServoStage.APPROACH: "re-seeds the tracker; the approach goes on from the new outline",
    ServoStage.FINAL_GRAB: "re-seeds the tracker; the final grab goes on from the new outline",
    ServoStage.DONE: "seeds the tracker; the arm holds until you press Start",
    ServoStage.ASSIST: "re-seeds the tracker; the arm holds until you press Resume",
    ServoStage.PAUSED: "seeds the tracker; the arm holds until you press Resume",
    ServoStage.ABORTED: "seeds the tracker; the arm holds until you press Start",
}
#: what a click does with no grab in the graph (or no word from it yet), before the first
#: picture, after the run, and on a page without control
CLICK_NO_GRAB = "seeds the tracker"
CLICK_STARTING = "nothing yet: no picture from the camera"
CLICK_ENDED = "nothing: the run has ended"
CLICK_WITHOUT_CONTROL = "nothing: take control first"

#: vsServo stages from which *Start* begins a new grab (elsewhere it would change nothing)
STARTABLE = (DONE, ABORTED, PAUSED, ASSIST)
#: stages in which *Pause* holds the arm
PAUSABLE = (*ACTIVE_STAGES, ASSIST)


@dataclass(frozen=True)
class StateLine:
    """What the page's state line says; ``stopped`` is "" while the robot may move; ``outcome``
    is the verdict's (``pending`` before one); ``click`` what a click on the patch does now for
    the page holding control (``click_without_control`` for the others); ``tracker`` the
    tracker's failure in words ("" while it tracks, or when ``stopped`` already says it)."""

    phase: str
    stage: str
    control: str
    doing: str
    stopped: str
    stopped_detail: str
    verdict: str
    outcome: str = Outcome.PENDING.value
    click: str = CLICK_NO_GRAB
    click_without_control: str = CLICK_WITHOUT_CONTROL
    tracker: str = ""

    def for_page(self) -> dict[str, Any]:
        return asdict(self)


def phase_of(images_seen: bool, stopping: bool) -> str:
    """The run's life-cycle phase for the page."""
    if stopping:
        return ENDED
    return RUNNING if images_seen else STARTING


def state_line(
    phase: str,
    servo: ServoState | None,
    guard: GuardState | None,
    world: Verdict | None,
    holder: str,
    jogging: bool,
    contour: Contour | None = None,
) -> StateLine:
    """The state line from vsServo's and REG_VEL's statuses, the world's verdict (None: no
    judge in the graph, or not judged yet), the control holder's name ("" nobody), whether
    a jog is held and the tracker's latest contour (None: none, or too old)."""
    control = holder or "nobody (take control to act)"
    judged = world is not None and world.outcome != Outcome.PENDING
    verdict = world.message if world is not None and judged else ""
    outcome = world.outcome.value if world is not None else Outcome.PENDING.value
    stage = servo.stage if servo is not None else "-"
    if phase == STARTING:
        return StateLine(
            phase,
            stage,
            control,
            "starting: waiting for the camera",
            "",
            "",
            "",
            outcome,
            click=CLICK_STARTING,
        )
    if jogging:
        doing = "jogging by hand (the grab is paused)"
    elif servo is None:
        doing = ""  # no grab in this graph (or no word from it yet): nothing to say
    elif servo.stage == ServoStage.ACQUIRE and servo.code != ServoReason.NONE:
        doing = "waiting for a seed: click the patch (the approach then starts by itself)"
    else:
        doing = _DOING.get(servo.stage, servo.message or servo.stage)
    if phase == ENDED:
        doing = "the run has ended"
    words, exact = _why_stopped(servo, guard, jogging)
    return StateLine(
        phase,
        stage,
        control,
        doing,
        words,
        exact,
        verdict,
        outcome,
        click=click_does(phase, servo, jogging),
        tracker=_tracker_words(contour, words),
    )


def click_does(phase: str, servo: ServoState | None, jogging: bool) -> str:
    """What a click on the patch does now, for the page holding control: the seed goes to the
    tracker; whether the arm moves then depends on vsServo's stage (a held jog pauses an active
    grab, so it is said as paused)."""
    if phase == STARTING:
        return CLICK_STARTING
    if phase == ENDED:
        return CLICK_ENDED
    if servo is None:
        return CLICK_NO_GRAB
    stage = PAUSED if jogging and servo.stage in ACTIVE_STAGES else servo.stage
    return _CLICK.get(stage, CLICK_NO_GRAB)


def _tracker_words(contour: Contour | None, stopped: str) -> str:
    """The tracker's failure in the operator's words (its failed checks'; "" while it tracks,
    or when the line's ``stopped`` already says the same)."""
    if contour is None or contour.status != TrackStatus.FAILED:
        return ""
    checks = words_of(contour.checks)
    if checks and checks == stopped:
        return ""
    said = (
        f"{ServoReason.SNAKE_FAILED.words}: {checks}" if checks else ServoReason.SNAKE_FAILED.words
    )
    return f"{said}; click the patch to re-seed it"


def _why_stopped(
    servo: ServoState | None, guard: GuardState | None, jogging: bool
) -> tuple[str, str]:
    """Why the arm stands still, in the operator's words (from the reason codes) and in the
    producer's exact words ("", "" when it may move)."""
    if guard is not None and not guard.passing and not jogging:
        if servo is not None and servo.stage in (ASSIST, PAUSED, ABORTED, DONE):
            exact = servo.reason or _DOING[servo.stage]
            return (_DOING[servo.stage] if servo.code == ServoReason.NONE else servo.words()), exact
        return guard.code.words, guard.reason
    if servo is not None and servo.stage == ASSIST:
        return servo.words(), servo.reason
    return "", ""


def commands_available(phase: str, stage: str, can_stop: bool = False) -> dict[str, bool]:
    """Which commands would do something now (for the page that holds control; abort is
    offered for as long as the run lives, and *Stop* too when the graph has a judge to end the
    run, ``can_stop``)."""
    live = phase == RUNNING
    return {
        "start": live and stage in STARTABLE,
        "pause": live and stage in PAUSABLE,
        "resume": live and stage in (PAUSED, ASSIST),
        "abort": live,
        "stop": live and can_stop,
    }
