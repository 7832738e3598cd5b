"""REG_VEL: the velocity register on the servo side, a safety guard between vision and the arm."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from umbra.connectors import Input, Module, Output, Parameters, from_param, param
from umbra.connectors.commands import GripperCommand
from umbra.connectors.limits import (
    MAX_COMMAND_AGE_S,
    MAX_ORIGIN_AGE_S,
    MAX_TOOL_ANGULAR_RAD_S,
    MAX_TOOL_SPEED_M_S,
)
from umbra.connectors.messages import Twist
from umbra.connectors.states import NO_AGE_S, GuardReason, GuardStage, GuardState, ServoState
from umbra.modules.arm.velocity_register import RegisterOutput, RegisterSettings, VelocityRegister


class RegVel(Module["RegVel.Params"]):
    """Velocity register with a watchdog: passes the latest twist command, or zero and why.

    A non-zero ``jog`` (the operator's dead-man teleoperation) replaces the command until a
    zero jog releases it, under the same watchdog and clamps.

    The output drops to zero when the command was made from sensor data older than
    ``max_origin_age`` (its origin: the capture of the image it was computed from, on the
    graph's one time base), when no new command arrived for ``timeout`` (the link's watchdog),
    when its producer's process is gone (link liveliness), when ``halt`` reports an operator
    assistance request, or when the command is not a finite 6-vector. Linear and angular speeds
    are clamped (each part scaled as a vector, keeping its direction). Gripper commands pass
    only while the command link is healthy. Give it a ``rate``: the watchdog acts on its own
    clock, not on the arrival of commands. The twist it passes keeps its command's origin; a
    zero is dated now (stopping needs no data).
    """

    TYPE = "REG_VEL"
    SAFETY_GUARD = True

    class Params(Parameters):
        timeout: float = param(
            0.2, "largest accepted command age", unit="s", gt=0, le=MAX_COMMAND_AGE_S
        )
        max_linear: float = param(
            0.1, "linear speed clamp |v|", unit="m/s", ge=0, le=MAX_TOOL_SPEED_M_S
        )
        max_angular: float = param(
            0.5, "angular speed clamp |w|", unit="rad/s", ge=0, le=MAX_TOOL_ANGULAR_RAD_S
        )
        max_origin_age: float = param(
            0.25,
            "oldest sensor data a passed command may be made from",
            unit="s",
            gt=0,
            le=MAX_ORIGIN_AGE_S,
        )
        frame: str = param("camera", "frame of the twist in and out")

        def rate_problem(self, rate_hz: float | None) -> str:
            """The watchdog acts when it ticks: at least twice per ``timeout``."""
            least = 2.0 / self.timeout
            if rate_hz is None:
                return f"a watchdog needs `rate:` (at least {least:g} Hz, twice per timeout)"
            if rate_hz < least:
                return (
                    f"rate {rate_hz:g} Hz is too slow for timeout {self.timeout:g} s: the watchdog "
                    f"must tick at least twice per timeout ({least:g} Hz)"
                )
            return ""

    command = Input(
        Twist,
        frame=from_param("frame"),
        max_origin_age=from_param("max_origin_age"),
        doc="twist command (e.g. from vsServo)",
    )
    jog = Input(
        Twist,
        frame=from_param("frame"),
        required=False,
        max_origin_age=from_param("max_origin_age"),
        doc="operator's dead-man jog; a non-zero jog replaces the command while fresh",
    )
    gripper_in = Input(GripperCommand, required=False, doc="gripper command: open / close")
    halt = Input(
        ServoState,
        required=False,
        doc="the grab's state (vsServo): an assistance request forces zero",
    )
    twist = Output(Twist, frame=from_param("frame"), doc="guarded, clamped twist")
    gripper = Output(
        GripperCommand, events=True, doc="gripper command, passed while the link is healthy"
    )
    status = Output(
        GuardState,
        origin_from=("command",),  # as old as the command it judges (a held jog is old news)
        doc="passing or zero, why (a code and the exact text), the command's ages and the travel "
        "it let through (on change, and at least every 0.1 s; every 0.02 s while it passes motion)",
    )

    #: Longest time between two status samples [s]: a state stream, so a lost one is replaced.
    STATUS_PERIOD_S = 0.1
    #: ... and while it passes motion, for those who dead-reckon on its travel (vsServo's grab).
    MOVING_STATUS_PERIOD_S = 0.02

    def start(self) -> None:
        p = self.params
        settings = RegisterSettings(p.timeout, p.max_linear, p.max_angular, p.max_origin_age)
        self._register = VelocityRegister(settings)
        self._jog = VelocityRegister(settings)
        self._jog_ticks = 0
        self._jog_held = False
        self._last_reason: str | None = None
        self._last_zero_reason = ""
        self._frame_problem = ""
        self._zeroed = 0
        self._clamped = 0
        self._stale_zeroes = 0  # ticks at zero for old sensor data
        self._watchdog_zeroes = 0  # ticks at zero for want of a new command (a running stream)
        self._status_at = -float("inf")
        self._passing_origin_ages: list[float] = []  # [s] of the commands passed, for the summary
        self._passing_arrival_ages: list[float] = []  # [s] since they arrived, beside them
        self._refused_origin_ages: list[float] = []  # [s] of the commands refused as too old
        self._refused_arrival_ages: list[float] = []  # [s] since they arrived, beside them
        #: [start, end] [s] of each stretch at zero for old data (end None: to the end)
        self._stale_episodes: list[list[float | None]] = []
        self._last_out: RegisterOutput | None = None
        #: linear travel [m] the register let through, in ``frame`` (the odometer of what it
        #: passed: each tick's twist held until the next tick)
        self._travel = np.zeros(3)
        self._passed_at: tuple[float, np.ndarray] | None = None

    def step(self, now: float) -> None:
        command = self.command.get(now)
        if command is not None and self.command.fresh:
            if command.frame == self.params.frame:
                self._register.put(command.vector, self.command.received_at, command.origin)
                self._frame_problem = ""
            else:
                self._register.clear()
                self._frame_problem = (
                    f"command in frame `{command.frame}`, expected `{self.params.frame}`"
                )
        halt = self.halt.get(now)
        halt_reason = self._frame_problem if self._register.empty else ""
        halt_code = GuardReason.WRONG_FRAME
        if halt is not None and halt.assist:
            halt_reason = f"halted by {halt.stage}: {halt.reason or halt.message}"
            halt_code = GuardReason.HALTED
        out = self._register.output(now, self.command.link_alive, halt_reason, halt_code)
        if out.stale and not math.isfinite(out.origin_age) and self.command.clock_problem:
            out = replace(out, zero_reason=f"{out.zero_reason}: {self.command.clock_problem}")
        jogging = self._jog_step(now) if self.jog.value is not None else None
        if jogging is not None:
            out = jogging
        origin = (self._jog if jogging is not None else self._register).origin
        self.twist.send(
            Twist(vector=out.twist, frame=self.params.frame, origin=origin if out.passing else now)
        )
        self._count(out, now, jogging is not None)
        self._odometer(now, out.twist)
        gripper = self.gripper_in.get(now)
        if gripper is not None and self.gripper_in.fresh and out.passing:
            self.gripper.send(GripperCommand(action=gripper.action, stamp=gripper.stamp))
        reason_key = out.zero_reason or ("passing jog" if jogging is not None else "")
        moving = bool(np.any(out.twist[:3]))
        period = self.MOVING_STATUS_PERIOD_S if moving else self.STATUS_PERIOD_S
        if reason_key != self._last_reason or now - self._status_at >= period - 1e-9:
            if reason_key != self._last_reason and out.zero_reason:
                self._last_zero_reason = out.zero_reason
            self._last_reason = reason_key
            self._status_at = now
            self.status.send(
                GuardState(
                    stage=GuardStage.PASSING if out.passing else GuardStage.ZERO,
                    code=out.code,
                    reason=out.zero_reason,
                    jog=jogging is not None,
                    age_s=float(min(out.age, NO_AGE_S)),
                    origin_age_s=float(min(out.origin_age, NO_AGE_S)),
                    stale=out.stale,
                    travel_m=self._travel.copy(),
                )
            )

    def _odometer(self, now: float, twist: np.ndarray) -> None:
        """Add the travel [m] of the twist passed last tick, held until ``now`` [s]."""
        if self._passed_at is not None:
            then, linear = self._passed_at
            self._travel += linear * max(now - then, 0.0)
        self._passed_at = (now, np.array(twist[:3], dtype=float))

    def _count(self, out: RegisterOutput, now: float, jog: bool = False) -> None:
        """Tally the tick for the summary: passed (and from how old data), clamped, zeroed and
        why (old data, with when; a running command stream, not a jog, that paused past the
        watchdog)."""
        self._clamped += out.clamped
        was_stale = self._last_out is not None and self._last_out.stale
        if out.stale and not was_stale and len(self._stale_episodes) < MAX_EPISODES:
            self._stale_episodes.append([now, None])
        elif was_stale and not out.stale and self._stale_episodes:
            self._stale_episodes[-1][1] = now
        if out.passing:
            if len(self._passing_origin_ages) < 1_000_000:
                self._passing_origin_ages.append(out.origin_age)
                self._passing_arrival_ages.append(out.age)
        else:
            self._zeroed += 1
            self._stale_zeroes += out.stale
            if out.stale and len(self._refused_origin_ages) < 1_000_000:
                self._refused_origin_ages.append(out.origin_age)
                self._refused_arrival_ages.append(out.age)
            last = self._last_out
            self._watchdog_zeroes += (out.code == GuardReason.WATCHDOG and not jog) and (
                last is not None and last.passing
            )
        self._last_out = out

    def _jog_step(self, now: float) -> RegisterOutput | None:
        """The jog's output while a jog is held, else None (the command passes).

        A non-zero (or malformed) jog takes over until a zero jog releases it; it has the
        command's watchdog and clamps, so a jog whose keep-alives stop drops to zero. The
        upstream halt does not apply: jogging is the operator taking over by hand.
        """
        jog = self.jog.get(now)
        if jog is not None and self.jog.fresh:
            vector = np.asarray(jog.vector, dtype=float)
            if vector.shape == (6,) and np.all(vector == 0):
                self._jog.clear()  # a release: back to the command
                self._jog_held = False
            else:
                self._jog.put(vector, self.jog.received_at, jog.origin)
                self._jog_held = True
        if not self._jog_held:
            return None
        out = self._jog.output(now, self.jog.link_alive, "")
        if out.passing:
            self._jog_ticks += 1
            return out
        return RegisterOutput(out.twist, f"jog: {out.zero_reason}", False, out.age, code=out.code)

    def summary(self) -> dict[str, object]:
        return {
            "jog_ticks": self._jog_ticks,
            "zeroed_ticks": self._zeroed,
            "clamped_ticks": self._clamped,
            "stale_zero_ticks": self._stale_zeroes,
            "watchdog_zeroes": self._watchdog_zeroes,
            "passed_origin_age_ms": _percentiles_ms(self._passing_origin_ages),
            "passed_arrival_age_ms": _percentiles_ms(self._passing_arrival_ages),
            "refused_origin_age_ms": _percentiles_ms(self._refused_origin_ages),
            "refused_arrival_age_ms": _percentiles_ms(self._refused_arrival_ages),
            "stale_episodes_s": self._stale_episodes,
            "last_zero_reason": self._last_zero_reason,
        }


#: Stretches at zero for old data a summary lists at the most.
MAX_EPISODES = 200


def _percentiles_ms(ages_s: list[float]) -> dict[str, float | int | None]:
    """p50, p99 and max [ms] of the ages [s] that could be dated, how many ticks in all, and
    how many of them were of data that could not be dated (an infinite age)."""
    ages = np.asarray(ages_s, dtype=float)
    dated = ages[np.isfinite(ages)]
    undatable = int(ages.size - dated.size)
    if not dated.size:
        return {
            "p50": None,
            "p99": None,
            "max": None,
            "ticks": int(ages.size),
            "undatable": undatable,
        }
    p50, p99 = np.percentile(dated, [50, 99]) * 1e3
    return {
        "p50": float(p50),
        "p99": float(p99),
        "max": float(dated.max() * 1e3),
        "ticks": int(ages.size),
        "undatable": undatable,
    }
