"""Playing a checked :class:`ToolPath` on the arm: the VCR's path parameter, joint tracking
and the gripper events on the way.

Each tick the player advances the VCR (:mod:`umbra.modules.trajectory.vcr`), reads the desired
joints ``q(s)`` and the feed-forward joint rates ``dq/ds * s_dot`` from the path's spline, adds
a proportional correction ``gain * (q(s) - q_measured)``, and turns the joint rates into the
tool twist they produce at the measured joints (``J(q) qd``, re-expressed in the tool frame).
That twist is the command that goes through the safety guard (REG_VEL) and the resolved-rate
kinematics (WOLVERINE_KIN), which give back the same joint rates away from singularities.
Only a moving VCR commands motion along the path: paused, halted, done or waiting for the
gripper, the command only settles the last of the tracking lag (every joint within
``SETTLE_BAND`` of the path) and is zero otherwise (the player never pulls an arm that was
moved off the path back to it on its own), and play / back / resume
/ seek are refused while the arm is more than ``max_start_error`` from the path where it
stands (it was moved since: plan again). After a halt (a hard stop that froze the path
parameter while the arm coasted on) a start first takes up the path where the arm is: the
nearest point within ``RESYNC_WINDOW`` of where it froze.

Gripper events: where the path's gripper opening changes at a waypoint, the VCR stops there
(a stop point); the player commands the gripper ("close" / "open" going forwards, the reverse
going backwards), waits ``gripper_time`` and carries on in the same direction. A change at the
path's end is made on arrival, and undone before backing away from the end.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.connectors.commands import GripperAction
from umbra.connectors.path_messages import VCR_MOVING, ToolPath, VcrAction, VcrMode
from umbra.modules.arm.dh import DHTable
from umbra.modules.arm.jacobian import jacobian_and_pose
from umbra.modules.trajectory.joint_path import JointPath
from umbra.modules.trajectory.vcr import STARTS, Vcr, VcrError, VcrLimits

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class PlayerOutput:
    """One tick: tool twist ``[v; w]`` (m/s, rad/s; tool point, tool frame), a gripper command
    (None: none this tick), the desired joints, and the VCR's mode and parameter."""

    twist_tool: FloatArray
    gripper: GripperAction | None
    q_desired: FloatArray
    mode: VcrMode
    s: float
    s_dot: float
    s_ddot: float
    reason: str


MAX_WAYPOINTS = 20_000
RESYNC_WINDOW = 0.3  #: path units (rad of joint arc)
SETTLE_BAND = 0.01  #: rad: standing still, a smaller tracking error is still corrected


def _check_path(path: ToolPath, table: DHTable, rate: float) -> None:
    """The servo side checks what it is given: bounded size, finite numbers, joints within the
    limits, and joint rates at the nominal playing rate within the arm's limits."""
    s = np.asarray(path.s)
    q = np.asarray(path.joints)
    if not 2 <= s.size <= MAX_WAYPOINTS or s.ndim != 1:
        raise VcrError(f"path {path.path_id}: expected 2..{MAX_WAYPOINTS} waypoints, got {s.shape}")
    if q.shape != (s.size, table.n):
        raise VcrError(f"path {path.path_id}: expected joints {(s.size, table.n)}, got {q.shape}")
    if not (np.all(np.isfinite(s)) and np.all(np.isfinite(q))):
        raise VcrError(f"path {path.path_id}: non-finite parameters or joints")
    if np.any(q < table.q_min - 1e-9) or np.any(q > table.q_max + 1e-9):
        raise VcrError(f"path {path.path_id}: joints outside the arm's limits")
    ds = np.diff(s)
    if np.any(ds <= 0):
        raise VcrError(f"path {path.path_id}: the path parameter must increase strictly")
    peak = np.max(np.abs(np.diff(q, axis=0)) / ds[:, None], axis=0) * rate
    if np.any(peak > table.qd_max * (1 + 1e-6)):
        raise VcrError(
            f"path {path.path_id}: at its playing rate the joints would need "
            f"{np.round(peak, 3).tolist()} rad/s, over the limits {table.qd_max.tolist()}"
        )


class PathPlayer:
    """Plays one path: VCR commands in, tool twists out (see module docstring)."""

    def __init__(
        self,
        path: ToolPath,
        table: DHTable,
        T_flange_tool: ArrayLike,
        *,
        stop_time_s: float = 0.25,
        gain: float = 4.0,
        gripper_time: float = 0.7,
        max_start_error: float = 0.05,
    ) -> None:
        if not path.ok:
            raise VcrError(f"path {path.path_id} failed its checks: {path.reason}")
        if tuple(path.names) != table.names:
            raise VcrError(f"path joints {list(path.names)} differ from {list(table.names)}")
        rate = float(path.checks.get("rate", 0.0))
        if not (np.isfinite(rate) and rate > 0):
            raise VcrError(f"path {path.path_id} has no playing rate (checks: {path.checks})")
        _check_path(path, table, rate)
        self.path = path
        self.table = table
        self.T_flange_tool = np.asarray(T_flange_tool, dtype=float)
        self.joint_path = JointPath(path.s, path.joints)
        self.gain = gain
        self.gripper_time = gripper_time
        self.max_start_error = max_start_error
        #: after a halt, how far along the path (path units: rad of joint arc) the arm is
        #: looked for: a stalled servo tick at full rate coasts about rate x stall
        self.resync_window = RESYNC_WINDOW
        g = np.asarray(path.gripper, dtype=float)
        if g.shape != (len(path.s),):
            g = np.full(len(path.s), np.nan)
        #: s of each gripper change -> (opening before, opening after)
        self.events = {
            float(path.s[i]): (float(g[i - 1]), float(g[i]))
            for i in range(1, len(g))
            if np.isfinite(g[i]) and np.isfinite(g[i - 1]) and g[i] != g[i - 1]
        }
        limits = VcrLimits.for_stop_time(rate, stop_time_s)
        self.vcr = Vcr(self.joint_path.length, limits, stops=list(self.events))
        self._hold = 0.0  # seconds left of a gripper wait
        self._after_hold: VcrAction | None = None  # VCR action to take when the wait is over
        self._end_done = False  # the event at the path's end has been made
        self._pending_gripper: GripperAction | None = None

    # -- commands -----------------------------------------------------------------------------
    def command(
        self,
        action: VcrAction,
        speed: float | None = None,
        s: float | None = None,
        q_measured: ArrayLike | None = None,
    ) -> None:
        """A VCR command (play, back, pause, resume, speed, seek, stop). With ``q_measured``
        (rad), a start from standstill is refused (VcrError) when the arm is off the path."""
        st = self.vcr.state
        end = self.joint_path.length
        if action in STARTS and q_measured is not None and st.mode not in VCR_MOVING:
            q = np.asarray(q_measured, dtype=float)
            if st.mode == VcrMode.HALTED:  # the arm may have coasted on after a hard stop: take up
                # the path where the arm is (the nearest point near where it froze)
                near = self.joint_path.nearest_s(q, 200, around=st.s, window=self.resync_window)
                st.s = near
            off = float(np.max(np.abs(self.joint_path.q(st.s) - q)))
            if not off <= self.max_start_error:
                raise VcrError(
                    f"{action} refused: the arm is {np.degrees(off):.1f} deg off path "
                    f"{self.path.path_id} at s={st.s:.3f}; expected at most "
                    f"{np.degrees(self.max_start_error):.1f} deg (it was moved: plan again)"
                )
        back = VcrAction.BACK
        if action == back and self._end_done and st.s >= end - 1e-9 and end in self.events:
            self._grip(self.events[end][0], then=back)  # undo the end's event, then back
            return
        if action in (VcrAction.PAUSE, VcrAction.STOP):
            self._after_hold = None
        if action in (VcrAction.PLAY, VcrAction.RESUME, back) and self._hold > 0:
            self._after_hold = VcrAction.PLAY if action != back else back
            if speed is not None:
                self.vcr.command(VcrAction.SPEED, speed=speed)
            return
        self.vcr.command(action, speed=speed, s=s)

    def halt(self, reason: str, *, freeze: bool = False) -> None:
        """Stop on the path (see :meth:`Vcr.halt`); a gripper wait is abandoned."""
        self._after_hold = None
        self.vcr.halt(reason, freeze=freeze)

    # -- time ---------------------------------------------------------------------------------
    def step(self, dt: float, q_measured: ArrayLike) -> PlayerOutput:
        """Advance ``dt`` seconds with the arm at ``q_measured``."""
        q_meas = np.asarray(q_measured, dtype=float)
        if self._hold > 0:
            self._hold -= dt
            if self._hold <= 0 and self._after_hold is not None:
                self.vcr.command(self._after_hold)
                self._after_hold = None
        before = self.vcr.state.mode
        st = self.vcr.step(dt)
        if st.mode == VcrMode.AT_STOP and before != VcrMode.AT_STOP:
            opening = self.events[st.s][1 if st.direction == VcrMode.PLAYING else 0]
            then = VcrAction.PLAY if st.direction == VcrMode.PLAYING else VcrAction.BACK
            self._grip(opening, then=then)
        end = self.joint_path.length
        if st.s < end - 1e-9:
            self._end_done = False
        if st.mode == VcrMode.DONE and not self._end_done:
            self._end_done = True
            if end in self.events:
                self._grip(self.events[end][1], then=None)
        q_d = self.joint_path.q(st.s)
        error = q_d - q_meas
        if st.mode in VCR_MOVING and self._hold <= 0:
            qd = self.joint_path.dq_ds(st.s) * st.s_dot + self.gain * error
        elif np.max(np.abs(error)) <= SETTLE_BAND:
            qd = self.gain * error  # standing on the path: the last of the lag settles
        else:
            qd = np.zeros_like(q_d)  # standing off the path: no pull back to it
        J, T_base_tool = jacobian_and_pose(self.table, q_meas, self.T_flange_tool)
        twist_base = J @ qd
        R = T_base_tool[:3, :3]
        twist_tool = np.concatenate([R.T @ twist_base[:3], R.T @ twist_base[3:]])
        mode = VcrMode.GRIPPING if self._hold > 0 else st.mode
        gripper, self._pending_gripper = self._pending_gripper, None
        return PlayerOutput(twist_tool, gripper, q_d, mode, st.s, st.s_dot, st.s_ddot, st.reason)

    def _grip(self, opening: float, then: VcrAction | None) -> None:
        self._pending_gripper = GripperAction.CLOSE if opening < 0.5 else GripperAction.OPEN
        self._hold = self.gripper_time
        self._after_hold = then
