"""Stages of an automated grab (LDRD report section 2.5, Figure 8), as an explicit state machine.

::

    acquire ──(snake healthy for N consecutive frames)──> approach
             (no contour yet, or a stale one: keep waiting; a failed snake: assist)
    approach ──(every error within tolerance for M frames)──> final_grab
    final_grab: advance ``grab_distance`` plus the depth error still measured when the approach
                settled, along the optical axis at ``grab_speed`` (open loop),
                then close the gripper and wait ``gripper_close_time``  ──> done
    any active stage ──(snake failure)──> assist  (zero velocity at once), except while the
                gripper closes: the arm stands still, and the closing fingers in front of the
                camera hide the patch the snake tracks (the grab no longer needs it)
    approach / final_grab ──(no contour, or one older than max_contour_age)──> assist
                (not while the gripper closes, as above)
    assist ──operator "resume"──> acquire        any stage ──operator "abort"──> aborted
    done / aborted ──operator "resume"──> acquire (a new grab)
    acquire / approach / final_grab / assist ──operator "pause"──> paused (zero, the arm holds)
    paused ──operator "resume"──> acquire          "start" is "resume" (the console's Start grab)
    abort opens the gripper (a safe stop)

The machine is pure: each :meth:`ServoStages.step` takes the time and the latest observation and
returns the camera twist and the status; nothing here reads a clock.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from umbra.connectors.commands import GrabAction, GripperAction
from umbra.connectors.states import ServoReason, ServoStage
from umbra.connectors.tracking import SnakeCheck
from umbra.modules.servo.features import MomentFeatures
from umbra.modules.servo.law import ServoGains, servo_twist

FloatArray = NDArray[np.float64]

ACQUIRE = ServoStage.ACQUIRE
APPROACH = ServoStage.APPROACH
FINAL_GRAB = ServoStage.FINAL_GRAB
DONE = ServoStage.DONE
ASSIST = ServoStage.ASSIST
ABORTED = ServoStage.ABORTED
PAUSED = ServoStage.PAUSED
STAGES = tuple(ServoStage)
ACTIVE_STAGES = (ACQUIRE, APPROACH, FINAL_GRAB)


@dataclass(frozen=True)
class StageSettings:
    """Thresholds of the stage machine, built from validated parameters (vsServo's ``Params``
    holds their bounds), not checked again here.

    Attributes:
        acquire_frames: healthy snake frames needed before the approach (N).
        settle_frames: consecutive in-tolerance frames that end the approach (M).
        tolerance: per-axis error tolerance ``(x m, y m, z m, roll rad)``.
        grab_distance: open-loop advance along the optical axis in the final grab (m).
        grab_speed: speed of that advance (m/s).
        gripper_close_time: wait after the close command (s).
        max_contour_age: a contour older than this counts as a snake failure (s).
    """

    acquire_frames: int = 5
    settle_frames: int = 5
    tolerance: tuple[float, float, float, float] = (0.002, 0.002, 0.003, np.radians(1.0))
    grab_distance: float = 0.05
    grab_speed: float = 0.02
    gripper_close_time: float = 0.5
    max_contour_age: float = 0.5


@dataclass(frozen=True)
class Observation:
    """What the snake said this tick.

    ``healthy`` is False when the snake failed (``code`` says how: its checks failed, named in
    ``checks``, or its contour gave no features; ``reason`` in exact words); ``features`` is
    None when the snake has no contour yet (idle); ``stamp`` is the time (s) the contour was
    produced or received, on the caller's clock.
    """

    features: MomentFeatures | None
    healthy: bool
    stamp: float
    reason: str = ""
    code: ServoReason = ServoReason.SNAKE_FAILED
    checks: tuple[SnakeCheck, ...] = ()
    #: False while the safety guard holds the arm at zero (old data, a late command): the final
    #: grab's dead reckoning counts only the advance the guard let through
    commands_pass: bool = True
    #: the guard's odometer along the optical axis [m] (what it let through), when it reports
    #: one: the final grab measures its advance on it instead of its own commands
    guard_travel_z: float | None = None


@dataclass(frozen=True)
class ServoOutput:
    """One tick's result: camera twist ``[v; w]`` (camera frame), stage and operator status
    (``code`` and ``checks`` say why it waits or stopped, ``reason`` in exact words)."""

    camera_twist: FloatArray
    stage: ServoStage
    assist: bool = False
    reason: str = ""
    message: str = ""
    gripper: GripperAction | None = None  #: a command to send this tick
    error: FloatArray = field(default_factory=lambda: np.full(4, np.nan))
    code: ServoReason = ServoReason.NONE
    checks: tuple[SnakeCheck, ...] = ()


#: Final-grab advance left [m] below which the advance is complete.
ADVANCE_DONE = 1e-5
#: Step interval [s] assumed for the first step of the final grab (a 30 Hz camera).
NOMINAL_STEP = 1.0 / 30.0

_ZERO_TWIST = np.zeros(6)
_ZERO_TWIST.setflags(write=False)


class ServoStages:
    """The grab's state: stage, counters and timers. Feed it with :meth:`step` every tick."""

    def __init__(
        self,
        goal: MomentFeatures,
        gains: ServoGains = ServoGains(),  # noqa: B008 - frozen default
        settings: StageSettings = StageSettings(),
    ) -> None:
        self.goal = goal
        self.gains = gains
        self.settings = settings
        self.stage = ACQUIRE
        self.reason = ""
        self.code = ServoReason.NONE
        self.checks: tuple[SnakeCheck, ...] = ()
        self._healthy_frames = 0
        self._settled_frames = 0
        self._settled_depth_sum = 0.0  # sum of the depth errors of the settled frames [m]
        self._grab_depth = 0.0  # depth still to go when the final grab starts [m]
        self._grab_start: float | None = None
        self._grab_travel_base: float | None = None  #: the guard's odometer at the grab's start
        self._grab_tick = (0.0, 0.0, 0.0)  # last step's time [s], speed [m/s], advance so far [m]
        self._close_start: float | None = None
        self._pending_gripper: GripperAction | None = GripperAction.OPEN

    # -- operator -------------------------------------------------------------------------
    def operator(self, command: GrabAction) -> None:
        """Apply an operator command: ``resume`` / ``start`` (back to acquire from any stopped
        stage), ``pause`` (zero, hold) or ``abort`` (stop, open the gripper)."""
        try:
            command = GrabAction(command)
        except ValueError:
            known = [str(a) for a in GrabAction]
            raise ValueError(f"operator command must be one of {known}, got {command!r}") from None
        if command == GrabAction.ABORT:
            self._enter(ABORTED, "aborted by the operator", ServoReason.ABORTED)
            self._pending_gripper = GripperAction.OPEN
        elif command == GrabAction.PAUSE:
            if self.stage in (*ACTIVE_STAGES, ASSIST):
                self._enter(PAUSED, "paused by the operator", ServoReason.PAUSED)
        elif self.stage not in ACTIVE_STAGES:
            self._enter(ACQUIRE, "")
            self._pending_gripper = GripperAction.OPEN

    # -- tick -----------------------------------------------------------------------------
    def step(self, now: float, observation: Observation | None) -> ServoOutput:
        """Advance the machine to time ``now`` (s) with the latest observation (or None)."""
        waiting, why = "", ServoReason.NONE
        if self.stage in ACTIVE_STAGES and not self._closing:
            if observation is not None and not observation.healthy:
                self._enter(
                    ASSIST,
                    f"snake failure: {observation.reason or 'sanity check failed'}",
                    observation.code,
                    observation.checks,
                )
            else:
                why, waiting = self._unusable(now, observation)
                if waiting and self.stage != ACQUIRE:
                    self._enter(ASSIST, waiting, why)
                elif self.stage == ACQUIRE:
                    self._healthy_frames = 0 if waiting else self._healthy_frames + 1
        gripper, self._pending_gripper = self._pending_gripper, None
        if self.stage == ACQUIRE:
            return self._acquire(gripper, waiting, why)
        if self.stage == APPROACH:
            assert observation is not None and observation.features is not None
            return self._approach(observation.features, gripper)
        if self.stage == FINAL_GRAB:
            passing = observation is None or observation.commands_pass
            travel = None if observation is None else observation.guard_travel_z
            return self._final_grab(now, gripper, passing, travel)
        message = {
            DONE: "grab complete",
            ASSIST: "operator assistance requested",
            ABORTED: "aborted",
            PAUSED: "paused by the operator",
        }[self.stage]
        return ServoOutput(
            _ZERO_TWIST,
            self.stage,
            self.stage == ASSIST,
            self.reason,
            message,
            gripper,
            code=self.code,
            checks=self.checks,
        )

    @property
    def _closing(self) -> bool:
        """The final grab has advanced and the gripper closes: the arm stands still and the
        camera sees the fingers close over the patch, so the snake's view no longer counts."""
        return self.stage == FINAL_GRAB and self._close_start is not None

    def _unusable(self, now: float, observation: Observation | None) -> tuple[ServoReason, str]:
        """Why a healthy-flagged observation cannot be used, as a code and in exact words
        (``NONE`` and "" when it can)."""
        if observation is None:
            return ServoReason.NO_CONTOUR, "no contour from the snake"
        if observation.features is None:
            return ServoReason.NOT_SEEDED, "snake has no contour"
        age = now - observation.stamp
        if age > self.settings.max_contour_age:
            limit = self.settings.max_contour_age
            return ServoReason.CONTOUR_LATE, f"contour is {age:.3f} s old (max {limit:.3f} s)"
        return ServoReason.NONE, ""

    def _enter(
        self,
        stage: ServoStage,
        reason: str,
        code: ServoReason = ServoReason.NONE,
        checks: tuple[SnakeCheck, ...] = (),
    ) -> None:
        self.stage = stage
        self.reason = reason
        self.code = code
        self.checks = checks
        self._healthy_frames = 0
        self._settled_frames = 0
        self._settled_depth_sum = 0.0
        self._grab_start = None
        self._close_start = None

    def _acquire(
        self, gripper: GripperAction | None, waiting: str, why: ServoReason
    ) -> ServoOutput:
        count = self._healthy_frames
        if count >= self.settings.acquire_frames:
            self._enter(APPROACH, "")
        message = f"waiting: {waiting}" if waiting else f"snake healthy {count} frame(s)"
        return ServoOutput(
            _ZERO_TWIST, ACQUIRE, reason=waiting, message=message, gripper=gripper, code=why
        )

    def _approach(self, features: MomentFeatures, gripper: GripperAction | None) -> ServoOutput:
        twist, error = servo_twist(features, self.goal, self.gains)
        if np.all(np.abs(error) <= np.asarray(self.settings.tolerance)):
            self._settled_frames += 1
            self._settled_depth_sum += float(error[2])
        else:
            self._settled_frames = 0
            self._settled_depth_sum = 0.0
        if self._settled_frames >= self.settings.settle_frames:
            # The approach stops once the depth error is within tolerance, from the side it came
            # from: the mean depth error of the settled frames is still to go, so the open-loop
            # advance takes it along (no systematic depth offset at the grasp).
            depth_to_go = self._settled_depth_sum / self._settled_frames
            self._enter(FINAL_GRAB, "")
            self._grab_depth = depth_to_go
            return ServoOutput(
                _ZERO_TWIST, FINAL_GRAB, message="goal reached", gripper=gripper, error=error
            )
        return ServoOutput(twist, APPROACH, message="approaching", gripper=gripper, error=error)

    def _final_grab(
        self,
        now: float,
        gripper: GripperAction | None,
        passing: bool = True,
        travel_z: float | None = None,
    ) -> ServoOutput:
        if self._grab_start is None:
            self._grab_start = now
            self._grab_tick = (now, 0.0, 0.0)
            self._grab_travel_base = travel_z
        # Dead reckoning of the advance: on the guard's odometer when it reports one (what it
        # let through); else of the commands, each held until the next step, time the guard
        # held the arm at zero advancing nothing. The last command is cut to what is left.
        last_now, last_speed, advanced = self._grab_tick
        base = self._grab_travel_base
        if travel_z is not None and base is not None:
            advanced = travel_z - base
        elif passing:
            advanced += last_speed * (now - last_now)
        left = max(self.settings.grab_distance + self._grab_depth, 0.0) - advanced
        if left > ADVANCE_DONE:
            interval = now - last_now if now > last_now else NOMINAL_STEP
            speed = min(self.settings.grab_speed, left / interval)
            self._grab_tick = (now, speed, advanced)
            twist = np.array([0.0, 0.0, speed, 0.0, 0.0, 0.0])
            return ServoOutput(twist, FINAL_GRAB, message="advancing", gripper=gripper)
        self._grab_tick = (now, 0.0, advanced)
        if self._close_start is None:
            self._close_start = now
            return ServoOutput(
                _ZERO_TWIST, FINAL_GRAB, message="closing gripper", gripper=GripperAction.CLOSE
            )
        if now - self._close_start >= self.settings.gripper_close_time:
            self._enter(DONE, "")
            return ServoOutput(_ZERO_TWIST, DONE, message="grab complete", gripper=gripper)
        return ServoOutput(_ZERO_TWIST, FINAL_GRAB, message="closing gripper", gripper=gripper)
