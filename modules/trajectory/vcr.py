"""The VCR: a jerk-limited path-parameter player (play, pause, back up, speed, seek, resume).

The planned path is a curve ``q(s)`` with path parameter ``s`` in ``[0, length]``; the player
owns ``s`` and its rate ``s_dot`` and acceleration ``s_ddot``, and only ever changes them through
Ruckig's time-optimal, jerk-limited single-target interfaces (1 degree of freedom):

* play / back / seek: Ruckig's position interface towards the next stop point ahead (the path's
  end or start, a gripper event, or the seek target) with velocity limit ``speed * rate``;
* pause and halts: Ruckig's velocity interface to ``s_dot = 0``: a smooth stop on the path;
* speed change: a new velocity limit from the current state (Ruckig brings a state above the
  limit down within the acceleration and jerk limits).

Because every transition starts from the current ``(s, s_dot, s_ddot)``, position, velocity and
acceleration are continuous at every command; jerk stays within ``max_jerk``. A guard stop
(the safety register zeroed the arm) freezes ``s`` at once: the arm has already stopped.
Units: ``s`` in path units (the planner's; radians of weighted joint arc), time in seconds.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from umbra.connectors.path_messages import VcrAction, VcrMode

if TYPE_CHECKING:  # imported where used: checking a graph loads this file without it
    from ruckig import InputParameter

#: Every VCR command, and the argument each takes: ``speed`` (0.1 .. 1), ``s`` (path units)
#: or nothing.
ARGUMENT = {
    VcrAction.PLAY: "speed",
    VcrAction.BACK: "speed",
    VcrAction.PAUSE: "",
    VcrAction.RESUME: "speed",
    VcrAction.SPEED: "speed",
    VcrAction.SEEK: "s",
    VcrAction.STOP: "",
}
#: The actions' names, as a person writes them.
ACTIONS = tuple(str(action) for action in VcrAction)
#: Commands that set the path parameter moving from standstill.
STARTS = frozenset({VcrAction.PLAY, VcrAction.RESUME, VcrAction.BACK, VcrAction.SEEK})
#: Range of the speed override (fraction of the path's nominal rate).
SPEED_MIN, SPEED_MAX = 0.1, 1.0
#: Round-off allowed at the ends of the speed range (the VCR clips into it).
_SPEED_SLACK = 1e-9
_STILL = 1e-9


class VcrError(ValueError):
    """A VCR command that cannot be obeyed (unknown action, speed out of range, no path)."""


def check_command(
    action: str, speed: float | None = None, s: float | None = None, length: float | None = None
) -> VcrAction:
    """The one rule for a VCR command, wherever it is written (text, script, message): VcrError
    saying what was expected unless ``action`` is known, ``speed`` (when given, or required by
    ``speed``) is finite within ``SPEED_MIN .. SPEED_MAX``, and a seek has a finite target
    ``s`` >= 0, within ``0 .. length`` when the path's ``length`` is known (path units).
    Returns the action, typed."""
    typed = VcrAction.named(action, "unknown VCR action", VcrError)
    speeds = f"a speed within {SPEED_MIN:g} .. {SPEED_MAX:g}"
    if typed == VcrAction.SPEED and speed is None:
        raise VcrError(f"expected {speeds}")
    if speed is not None and not (
        np.isfinite(speed) and SPEED_MIN - _SPEED_SLACK <= speed <= SPEED_MAX + _SPEED_SLACK
    ):
        raise VcrError(f"expected {speeds}, got {speed}")
    if typed == VcrAction.SEEK:
        top = np.inf if length is None else length
        if s is None or not (np.isfinite(s) and 0.0 <= s <= top):
            within = ">= 0" if length is None else f"within 0 .. {length:.4g}"
            raise VcrError(f"expected a seek target {within}, got {s}")
    return typed


@dataclass(frozen=True)
class VcrLimits:
    """Limits of the path parameter: ``rate`` (path units/s at speed 1), ``max_accel``
    (units/s²), ``max_jerk`` (units/s³)."""

    rate: float
    max_accel: float
    max_jerk: float

    @classmethod
    def for_stop_time(cls, rate: float, stop_time_s: float) -> VcrLimits:
        """Limits that stop from full ``rate`` in ``stop_time_s`` with a pure jerk profile:
        ``j = 4 v / t²``, ``a = 2 v / t`` (the acceleration peak of that profile)."""
        if not (rate > 0 and stop_time_s > 0):
            raise VcrError(f"rate and stop time must be > 0, got {rate}, {stop_time_s}")
        return cls(rate, 2.0 * rate / stop_time_s, 4.0 * rate / stop_time_s**2)


@dataclass
class VcrState:
    """Where the player is: mode, ``s``, ``s_dot``, ``s_ddot``, speed override, halt reason."""

    mode: VcrMode = VcrMode.IDLE
    s: float = 0.0
    s_dot: float = 0.0
    s_ddot: float = 0.0
    speed: float = 1.0
    reason: str = ""
    target: float = 0.0
    direction: VcrMode = VcrMode.IDLE  #: PLAYING or BACKING when at a stop point


class Vcr:
    """Path-parameter player over ``[0, length]`` with stop points ``stops`` (gripper events)."""

    def __init__(self, length: float, limits: VcrLimits, stops: ArrayLike = ()) -> None:
        from ruckig import Ruckig, Trajectory

        if not (np.isfinite(length) and length > 0):
            raise VcrError(f"path length must be finite and > 0, got {length}")
        self.length = float(length)
        self.limits = limits
        self.stops = sorted(
            {float(x) for x in np.asarray(stops, dtype=float).ravel() if 0.0 < x < length}
        )
        self.state = VcrState(mode=VcrMode.PAUSED)
        self._otg = Ruckig(1)
        self._trajectory = Trajectory(1)
        self._plan_key: tuple | None = None  # (interface, goal, velocity limit) of the plan
        self._plan_time = 0.0  # seconds into the current plan

    # -- commands -----------------------------------------------------------------------------
    def command(self, action: str, speed: float | None = None, s: float | None = None) -> None:
        """Obey a VCR command: play, back, pause, resume (= play), speed, seek, stop."""
        action = check_command(action, speed, s, self.length)
        st = self.state
        self._plan_key = None
        if speed is not None:
            st.speed = float(np.clip(speed, SPEED_MIN, SPEED_MAX))
        if action in (VcrAction.PLAY, VcrAction.RESUME):
            if st.s >= self.length - 1e-9:
                st.mode = VcrMode.DONE
                return
            st.mode, st.reason = VcrMode.PLAYING, ""
        elif action == VcrAction.BACK:
            st.mode, st.reason = VcrMode.BACKING, ""
        elif action in (VcrAction.PAUSE, VcrAction.STOP):
            if st.mode not in (VcrMode.PAUSED, VcrMode.HALTED, VcrMode.DONE):
                st.mode = VcrMode.PAUSING
        elif action == VcrAction.SEEK:
            st.mode, st.reason, st.target = VcrMode.SEEKING, "", float(s)  # type: ignore[arg-type]

    def halt(self, reason: str, *, freeze: bool = False) -> None:
        """Stop on the path and stay stopped until the next play/back: smoothly (jerk-limited)
        or, with ``freeze`` (the guard already stopped the arm), at once."""
        st = self.state
        if st.mode in (VcrMode.PAUSED, VcrMode.DONE, VcrMode.IDLE) and not freeze:
            st.reason = st.reason or reason
            return
        st.reason = reason
        self._plan_key = None
        if freeze:
            st.s_dot = st.s_ddot = 0.0
            st.mode = VcrMode.HALTED
        elif st.mode != VcrMode.HALTED:
            st.mode = VcrMode.HALTING

    # -- time ---------------------------------------------------------------------------------
    def step(self, dt: float) -> VcrState:
        """Advance ``dt`` seconds and return the state."""
        if not (np.isfinite(dt) and dt > 0):
            raise VcrError(f"time step must be finite and > 0, got {dt}")
        st = self.state
        if st.mode in (VcrMode.PAUSING, VcrMode.HALTING) or (
            st.mode == VcrMode.HALTED and not self._still()
        ):
            self._advance_velocity(dt)
            if self._still():
                st.s_dot = st.s_ddot = 0.0
                st.mode = VcrMode.HALTED if st.mode == VcrMode.HALTING else VcrMode.PAUSED
        elif st.mode in (VcrMode.PLAYING, VcrMode.BACKING, VcrMode.SEEKING):
            goal = self._goal()
            self._advance_position(goal, dt)
            if abs(st.s - goal) < 1e-9 and self._still():
                st.s, st.s_dot, st.s_ddot = goal, 0.0, 0.0
                st.mode = self._arrived(goal)
        return st

    def _goal(self) -> float:
        st = self.state
        if st.mode == VcrMode.SEEKING:
            ahead = [x for x in self.stops if min(st.s, st.target) < x < max(st.s, st.target)]
            if not ahead:
                return st.target
            return min(ahead) if st.target > st.s else max(ahead)
        if st.mode == VcrMode.PLAYING:
            return min([x for x in self.stops if x > st.s + 1e-9] + [self.length])
        return max([x for x in self.stops if x < st.s - 1e-9] + [0.0])

    def _arrived(self, goal: float) -> VcrMode:
        st = self.state
        if goal in self.stops and st.mode in (VcrMode.PLAYING, VcrMode.BACKING):
            st.direction = st.mode
            return VcrMode.AT_STOP  # a gripper event: the caller acts, then resumes
        if st.mode == VcrMode.SEEKING:
            return VcrMode.PAUSED
        if st.mode == VcrMode.PLAYING and goal >= self.length:
            return VcrMode.DONE
        return VcrMode.PAUSED

    def _still(self) -> bool:
        st = self.state
        return abs(st.s_dot) < _STILL and abs(st.s_ddot) < 1e-6

    def _input(self) -> InputParameter:
        from ruckig import InputParameter

        st, lim = self.state, self.limits
        inp = InputParameter(1)
        inp.current_position = [st.s]
        inp.current_velocity = [st.s_dot]
        inp.current_acceleration = [st.s_ddot]
        inp.max_velocity = [lim.rate * st.speed]
        inp.max_acceleration = [lim.max_accel]
        inp.max_jerk = [lim.max_jerk]
        inp.target_velocity = [0.0]
        inp.target_acceleration = [0.0]
        return inp

    def _advance_position(self, goal: float, dt: float) -> None:
        key = ("position", goal, self.limits.rate * self.state.speed)
        if key != self._plan_key:
            inp = self._input()
            inp.target_position = [goal]
            self._plan(inp, key)
        self._sample(dt)

    def _advance_velocity(self, dt: float) -> None:
        from ruckig import ControlInterface

        key = ("velocity", 0.0, self.limits.rate * self.state.speed)
        if key != self._plan_key:
            inp = self._input()
            inp.control_interface = ControlInterface.Velocity
            self._plan(inp, key)
        self._sample(dt)

    def _plan(self, inp: InputParameter, key: tuple) -> None:
        """A new time-optimal plan from the current state; kept until the command changes, so
        the state follows one exact jerk-limited trajectory (no re-planning chatter)."""
        from ruckig import Result

        result = self._otg.calculate(inp, self._trajectory)
        if result not in (Result.Working, Result.Finished):
            raise VcrError(f"ruckig could not time the path parameter: {result}")
        self._plan_key = key
        self._plan_time = 0.0

    def _sample(self, dt: float) -> None:
        st = self.state
        self._plan_time += dt
        t = min(self._plan_time, self._trajectory.duration)
        pos, vel, acc = self._trajectory.at_time(t)
        st.s = float(np.clip(pos[0], 0.0, self.length))
        st.s_dot, st.s_ddot = float(vel[0]), float(acc[0])
        if t < self._plan_time:  # the plan is complete: rest at its end
            st.s_dot = st.s_ddot = 0.0
