"""REG_VEL: the velocity register on the servo side, a safety guard between vision and the arm."""

from __future__ import annotations

from connectors import Input, Module, Output, Parameters, from_param, param
from connectors.messages import Status, Text, Twist
from modules.arm.velocity_register import RegisterSettings, VelocityRegister


class RegVel(Module):
    """Velocity register with a watchdog: passes the latest twist command, or zero and why.

    The output drops to zero when the command is older than ``timeout`` (by arrival time),
    when its producer's process is gone (link liveliness), when ``halt`` reports an operator
    assistance request, or when the command is not a finite 6-vector. Linear and angular speeds
    are clamped (each part scaled as a vector, keeping its direction). Gripper commands pass
    only while the command link is healthy. Give it a ``rate``: the watchdog acts on its own
    clock, not on the arrival of commands.
    """

    TYPE = "REG_VEL"
    SAFETY_GUARD = True

    class Params(Parameters):
        timeout: float = param(0.2, "largest accepted command age", unit="s", gt=0)
        max_linear: float = param(0.1, "linear speed clamp |v|", unit="m/s", ge=0)
        max_angular: float = param(0.5, "angular speed clamp |w|", unit="rad/s", ge=0)
        frame: str = param("camera", "frame of the twist in and out")

    command = Input(Twist, frame=from_param("frame"), doc="twist command (e.g. from vsServo)")
    gripper_in = Input(Text, required=False, doc="gripper command: open / close")
    halt = Input(Status, required=False, doc="upstream status; assist=True forces zero")
    twist = Output(Twist, frame=from_param("frame"), doc="guarded, clamped twist")
    gripper = Output(Text, doc="gripper command, passed while the link is healthy")
    status = Output(Status, doc="'passing' or 'zero' with the reason (sent when it changes)")

    def start(self) -> None:
        p = self.params
        self._register = VelocityRegister(RegisterSettings(p.timeout, p.max_linear, p.max_angular))
        self._last_reason: str | None = None
        self._last_zero_reason = ""
        self._frame_problem = ""
        self._zeroed = 0
        self._clamped = 0

    def step(self, now: float) -> None:
        command = self.command.get(now)
        if command is not None and self.command.fresh:
            if command.frame == self.params.frame:
                self._register.put(command.vector, self.command.received_at)
                self._frame_problem = ""
            else:
                self._register.clear()
                self._frame_problem = (
                    f"command in frame `{command.frame}`, expected `{self.params.frame}`"
                )
        halt = self.halt.get(now)
        halt_reason = self._frame_problem if self._register.empty else ""
        if halt is not None and halt.assist:
            halt_reason = f"halted by {halt.stage}: {halt.reason or halt.message}"
        out = self._register.output(now, self.command.link_alive, halt_reason)
        self.twist.send(Twist(vector=out.twist, frame=self.params.frame))
        self._zeroed += not out.passing
        self._clamped += out.clamped
        gripper = self.gripper_in.get(now)
        if gripper is not None and self.gripper_in.fresh and out.passing:
            self.gripper.send(Text(text=gripper.text, stamp=gripper.stamp))
        if out.zero_reason != self._last_reason:
            self._last_reason = out.zero_reason
            if out.zero_reason:
                self._last_zero_reason = out.zero_reason
            self.status.send(
                Status(
                    stage="zero" if out.zero_reason else "passing",
                    message=out.zero_reason or "passing commands",
                    reason=out.zero_reason,
                    values={"age": float(min(out.age, 1e9))},
                )
            )

    def summary(self) -> dict[str, object]:
        return {
            "zeroed_ticks": self._zeroed,
            "clamped_ticks": self._clamped,
            "last_zero_reason": self._last_zero_reason,
        }
