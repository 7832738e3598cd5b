"""The station's one state line and the run's life cycle, from the graph's statuses. Pure.

The line answers four questions at a glance: which stage the task is in, who holds control,
what the robot is doing, and, when it stands still, why. The life cycle is ``starting`` (no
camera image yet), ``running``, ``ended`` (the process is stopping: the page says so, with the
verdict, instead of trying to reconnect to a run that is gone).

A seed starts the approach: vsServo waits in ``acquire`` for a healthy snake and moves as soon
as the snake holds the patch for a few frames. *Start* begins a new grab from a stopped stage
(done, aborted, paused, assist); in ``acquire`` there is nothing to start but the seed.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

from umbra.connectors.states import (
    GuardState,
    Outcome,
    ServoReason,
    ServoStage,
    ServoState,
    Verdict,
)
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

#: vsServo stages from which *Start* begins a new grab (elsewhere it would change nothing)
STARTABLE = (DONE, ABORTED, PAUSED, ASSIST)
#: stages in which *Pause* holds the arm
PAUSABLE = (*ACTIVE_STAGES, ASSIST)


@dataclass(frozen=True)
class StateLine:
    """What the page's state line says; ``stopped`` is "" while the robot may move; ``outcome``
    is the verdict's (``pending`` before one)."""

    phase: str
    stage: str
    control: str
    doing: str
    stopped: str
    stopped_detail: str
    verdict: str
    outcome: str = Outcome.PENDING.value

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
) -> StateLine:
    """The state line from vsServo's and REG_VEL's statuses, the world's verdict (None: no
    judge in the graph, or not judged yet), the control holder's name ("" nobody) and whether
    a jog is held."""
    control = holder or "nobody (take control to act)"
    judged = world is not None and world.outcome != Outcome.PENDING
    verdict = world.message if world is not None and judged else ""
    outcome = world.outcome.value if world is not None else Outcome.PENDING.value
    stage = servo.stage if servo is not None else "-"
    if phase == STARTING:
        return StateLine(
            phase, stage, control, "starting: waiting for the camera", "", "", "", outcome
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
    return StateLine(phase, stage, control, doing, words, exact, verdict, outcome)


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
