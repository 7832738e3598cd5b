"""VCR_PLAYER: the SMART-side trajectory player of Active Sketch (LDRD report section 3)."""

from __future__ import annotations

import numpy as np

from umbra.connectors import Input, Module, Output, from_param, param
from umbra.connectors.commands import GripperCommand
from umbra.connectors.limits import MAX_PATH_AGE_S
from umbra.connectors.messages import JointState, Twist
from umbra.connectors.path_messages import VCR_MOVING, ToolPath, VcrCommand, VcrMode, VcrState
from umbra.connectors.states import GuardState
from umbra.modules.arm.arm_params import ArmParams
from umbra.modules.geometry.transforms import transform_from_xyz_rpy_deg
from umbra.modules.trajectory.player import PathPlayer, PlayerOutput
from umbra.modules.trajectory.vcr import ARGUMENT, STARTS, VcrError


class VcrPlayer(Module["VcrPlayer.Params"]):
    """Plays a checked tool path with VCR commands: play, pause (jerk-limited stop on the path),
    back (along the same path), speed 0.1..1, seek, resume.

    Its output is a tool twist (tool point, tool frame) for the safety register (REG_VEL, frame
    ``tool``) and the kinematics; gripper events of the path go out as open / close through the
    register too. It halts on the path, and stays halted until the next play or back, when:
    the command link's producer is gone (lost console: a jerk-limited stop), a command older
    than ``max_command_age`` arrives (it is refused, and a moving player stops smoothly: the
    console's link is lagging), the joint state is older than ``max_state_age`` or the register
    reports a guard stop (then ``s`` freezes at once: the guard has already stopped the arm).
    A path is checked again here before it is loaded (size, finite numbers, joint limits, joint
    rates at its playing rate), and a new path is refused while the current one moves the arm.
    Standing still it commands no motion; play / back / resume / seek are refused while the arm
    is more than ``max_start_error`` off the path. Give it a ``rate``.
    """

    TYPE = "VCR_PLAYER"

    class Params(ArmParams):
        tool_xyz: list[float] = param(
            [0.0, 0.0, 0.14], "tool point in the flange", unit="m", min_length=3, max_length=3
        )
        tool_rpy_deg: list[float] = param(
            [0.0, 0.0, 0.0], "tool frame in the flange", unit="deg", min_length=3, max_length=3
        )
        tool_frame: str = param("tool", "frame of the output twist")
        stop_time: float = param(0.25, "pause: stop from full speed within", unit="s", gt=0)
        gain: float = param(4.0, "joint tracking gain", unit="1/s", ge=0, le=50)
        gripper_time: float = param(0.7, "wait for a gripper event", unit="s", gt=0)
        max_command_age: float = param(0.5, "older commands are refused", unit="s", gt=0)
        max_state_age: float = param(0.2, "oldest joint state used", unit="s", gt=0)
        max_start_error: float = param(
            0.05, "play refused when a joint is off the path by more than", unit="rad", gt=0, le=0.5
        )
        max_path_age: float = param(
            300.0,
            "paths planned from snapshots older than this are refused (the scene may have moved)",
            unit="s",
            gt=0,
            le=MAX_PATH_AGE_S,
        )

    path = Input(
        ToolPath,
        required=False,
        max_origin_age=from_param("max_path_age"),
        doc="the checked path to play (from the planner)",
    )
    command = Input(VcrCommand, required=False, doc="VCR commands from the console")
    joint_state = Input(JointState, feedback=True, doc="measured joints")
    guard = Input(
        GuardState, required=False, feedback=True, doc="REG_VEL's state: zero = guard stop"
    )
    twist = Output(
        Twist,
        frame=from_param("tool_frame"),
        origin_from=("joint_state",),  # the path is judged on loading and at play (max_path_age)
        doc="tool twist command (to REG_VEL)",
    )
    gripper = Output(GripperCommand, events=True, doc="gripper events: open / close (to REG_VEL)")
    state = Output(VcrState, doc="mode, path parameter, speed, halt reason")

    def start(self) -> None:
        p = self.params
        self.table = p.table
        self.T_flange_tool = transform_from_xyz_rpy_deg(p.tool_xyz, p.tool_rpy_deg)
        self.player: PathPlayer | None = None
        self._last: float | None = None
        self._problem = ""
        self._halts = 0
        self._refused = 0

    def step(self, now: float) -> None:
        dt = 0.0 if self._last is None else now - self._last
        self._last = now
        path = self.path.get(now)
        if path is not None and self.path.fresh:
            self._load(path, now)
        state = self.joint_state.get(now)
        command = self.command.get(now)
        if command is not None and self.command.fresh:
            self._obey(command, now, state)
        if self.player is None or state is None or dt <= 0:
            self._send_idle()
            return
        mode = self.player.vcr.state.mode
        age = self.joint_state.age(now)
        if age > self.params.max_state_age and mode in VCR_MOVING:
            self._halt(f"joint state is stale ({age:.3f} s old)", freeze=True)
        if self.command.link_gone and mode in VCR_MOVING:
            self._halt("console lost")
        guard = self.guard.get(now)
        if guard is not None and not guard.passing and mode in VCR_MOVING:
            self._halt(f"guard stop: {guard.reason}", freeze=True)
        out = self.player.step(dt, np.asarray(state.position, dtype=float))
        self._send(out)

    def _path_too_old(self, path: ToolPath, now: float) -> str:
        """Why ``path`` is too old to play at ``now`` (its data's origin), or ""."""
        age = now - path.origin
        if age <= self.params.max_path_age:
            return ""
        seen = f"{age:.0f} s ago" if np.isfinite(age) else "at a time that cannot be dated"
        return (
            f"path {path.path_id} was planned from images taken {seen} (limit "
            f"{self.params.max_path_age:g} s): take a new snapshot and plan again"
        )

    def _load(self, path: ToolPath, now: float) -> None:
        old = self._path_too_old(path, now)
        if old:
            self._refused += 1
            self._problem = old
            self.log.warning("VCR_PLAYER %s: %s", self.name, old)
            return
        if self.player is not None and self.player.vcr.state.mode in VCR_MOVING:
            self._refused += 1
            self._problem = (
                f"path {path.path_id} refused: {self.player.path.path_id} is "
                f"{self.player.vcr.state.mode}; pause it first"
            )
            self.log.warning("VCR_PLAYER %s: %s", self.name, self._problem)
            return
        try:
            self.player = PathPlayer(
                path,
                self.table,
                self.T_flange_tool,
                stop_time_s=self.params.stop_time,
                gain=self.params.gain,
                gripper_time=self.params.gripper_time,
                max_start_error=self.params.max_start_error,
            )
            self._problem = ""
        except VcrError as exc:
            self.player = None
            self._problem = str(exc)
            self.log.warning("VCR_PLAYER %s: %s", self.name, exc)

    def _obey(self, command: VcrCommand, now: float, state: JointState | None) -> None:
        age = now - command.stamp
        if not age <= self.params.max_command_age:
            self._refused += 1
            self._problem = (
                f"stale command {command.action!r}: {age:.3f} s old, expected at most "
                f"{self.params.max_command_age:.3f} s"
            )
            if self.player is not None and self.player.vcr.state.mode in VCR_MOVING:
                self._halt(self._problem)
            return
        if self.player is None:
            self._problem = f"command {command.action!r} but no path is loaded"
            return
        old = self._path_too_old(self.player.path, now)
        if old and command.action in STARTS:
            self._refused += 1
            self._problem = old
            return
        if command.path_id and command.path_id != self.player.path.path_id:
            self._problem = (
                f"command for path {command.path_id!r}, loaded is {self.player.path.path_id!r}"
            )
            return
        try:
            speed = None
            if command.speed > 0 and ARGUMENT.get(command.action) == "speed":
                speed = command.speed
            q = None if state is None else np.asarray(state.position, dtype=float)
            if q is None and command.action in STARTS:
                raise VcrError(f"{command.action} refused: no joint state from the arm yet")
            self.player.command(command.action, speed=speed, s=command.s, q_measured=q)
            self._problem = ""
        except VcrError as exc:
            self._refused += 1
            self._problem = str(exc)

    def _halt(self, reason: str, freeze: bool = False) -> None:
        assert self.player is not None
        if self.player.vcr.state.mode == VcrMode.HALTING and not freeze:
            return  # already stopping smoothly on the path
        self._halts += 1
        self.player.halt(reason, freeze=freeze)

    def _send(self, out: PlayerOutput) -> None:
        assert self.player is not None
        self.twist.send(Twist(vector=out.twist_tool, frame=self.params.tool_frame))
        if out.gripper is not None:
            self.gripper.send(GripperCommand(action=out.gripper))
        length = self.player.joint_path.length
        self.state.send(
            VcrState(
                path_id=self.player.path.path_id,
                mode=out.mode,
                s=out.s,
                s_dot=out.s_dot,
                speed=self.player.vcr.state.speed,
                progress=out.s / length,
                reason=out.reason or self._problem,
            )
        )

    def _send_idle(self) -> None:
        self.twist.send(Twist(vector=np.zeros(6), frame=self.params.tool_frame))
        path_id = self.player.path.path_id if self.player else ""
        self.state.send(VcrState(path_id=path_id, mode=VcrMode.IDLE, reason=self._problem))

    def stop(self) -> None:
        self._final = self.summary()
        self.player = None  # the Ruckig objects go before the interpreter's teardown

    def summary(self) -> dict[str, object]:
        if getattr(self, "_final", None) is not None:
            return dict(self._final)
        player = self.player
        st = player.vcr.state if player else None
        return {
            "path": player.path.path_id if player else "",
            "mode": str(st.mode if st else VcrMode.IDLE),
            "progress": float(st.s / player.joint_path.length) if player and st else 0.0,
            "halts": self._halts,
            "refused_commands": self._refused,
        }
