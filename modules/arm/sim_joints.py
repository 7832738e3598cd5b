"""A simulated arm's joints: commanded rates in, joint angles out, with a drive's imperfections.

Per step of ``dt`` seconds, for each joint:

1. the commanded rate is clipped to the joint's rate limit (a drive saturates joint by joint);
2. a first-order lag with time constant ``lag_tau`` pulls the actual rate towards it;
3. the change of rate is limited to ``accel_max * dt``;
4. the angle integrates the rate (trapezoid rule) and is clamped at the joint limits, where
   the rate drops to zero.

Calibration error: the joint angles that the arm *reports* (and that the controller believes)
differ from the *true* ones by fixed unknown offsets, ``q_true = q_reported + calibration_error``.
The plant (rendering, the true tool pose) uses ``q_true``; kinematics run on ``q_reported``.
This is what makes an open-loop grab miss and a visual servo necessary.

The gripper opening goes from 0 (closed) to 1 (open) in ``gripper_travel_time`` seconds.

The drive's own watchdog: a rate given with :meth:`SimJoints.hold` is obeyed for at most
``watchdog`` seconds of plant time; after that :meth:`SimJoints.advance` integrates a zero command
(the joints decelerate through the lag and the acceleration limit and stay at rest) until the next
``hold``, however long the gap between two calls is. This is what a real CiA 402 drive does with a
heartbeat consumer (0x1016) on its master or a command deadline: a master that freezes (SIGSTOP,
Ctrl-Z, a hung process) cannot leave the arm running at its last rate. :meth:`SimJoints.step` is
the bare plant step under a rate the caller gives for that step.

Units: radians (metres for prismatic joints), seconds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.connectors.commands import GripperAction
from umbra.modules.arm.dh import DHTable

FloatArray = NDArray[np.float64]

GRIPPER_COMMANDS = tuple(GripperAction)

#: Joint speed below which a joint coasting on the watchdog's zero command is at rest [rad/s].
REST_SPEED = 1e-9


@dataclass(frozen=True)
class SimJointSettings:
    """Drive model of the simulated joints, built from validated parameters (WOLVERINE_JNTS's
    ``Params`` holds their bounds, the joint limits of the start and one offset per joint).

    Attributes:
        accel_max: acceleration limit per joint (rad/s^2), a scalar for all joints.
        lag_tau: time constant of the rate response (s); 0 for none.
        calibration_error: offsets ``q_true - q_reported`` per joint (rad); empty for none.
        gripper_travel_time: time for a full open or close (s).
        watchdog: the drive's command timeout (s): a held rate is obeyed this long at most.
    """

    accel_max: float = 8.0
    lag_tau: float = 0.02
    calibration_error: tuple[float, ...] = ()
    gripper_travel_time: float = 0.5
    watchdog: float = 0.1


class SimJoints:
    """State of a simulated arm; call :meth:`step` with commanded rates each tick."""

    def __init__(
        self,
        table: DHTable,
        q0: ArrayLike | None = None,
        settings: SimJointSettings = SimJointSettings(),
        gripper_opening: float = 1.0,
    ) -> None:
        self.table = table
        self.settings = settings
        q = np.zeros(table.n) if q0 is None else table.check_q(q0)
        error = np.asarray(settings.calibration_error, dtype=float)
        if error.size == 0:
            error = np.zeros(table.n)
        self._calibration_error = error
        self._q = q.copy()
        self._qd = np.zeros(table.n)
        self._gripper = float(np.clip(gripper_opening, 0.0, 1.0))
        self._gripper_target = self._gripper
        self._command = np.zeros(table.n)
        self._command_left = 0.0  # plant time the held command is still obeyed (s)
        self._cut = False  # a non-zero held command outlived its watchdog
        self.watchdog_stops = 0  # how many held non-zero commands the watchdog cut
        self.time = 0.0

    @property
    def q_reported(self) -> FloatArray:
        """Joint angles as the encoders report them (what the controller sees)."""
        return self._q.copy()

    @property
    def q_true(self) -> FloatArray:
        """Joint angles the arm really has (reported + calibration error)."""
        return self._q + self._calibration_error

    @property
    def qd(self) -> FloatArray:
        """Actual joint rates."""
        return self._qd.copy()

    @property
    def gripper_opening(self) -> float:
        """Gripper opening, 0 closed .. 1 open."""
        return self._gripper

    @property
    def gripper_moving(self) -> bool:
        """True while the gripper travels towards its commanded opening."""
        return self._gripper != self._gripper_target

    @property
    def watchdog_stopped(self) -> bool:
        """True while the watchdog holds the joints at zero (a non-zero command timed out)."""
        return self._cut

    def hold(self, commanded_rates: ArrayLike) -> None:
        """Obey ``commanded_rates`` (rad/s) from now for at most ``settings.watchdog`` seconds."""
        self._command = self.table.check_q(commanded_rates).copy()
        self._command_left = self.settings.watchdog
        self._cut = False

    def advance(self, elapsed: float, max_substep: float) -> None:
        """Run the plant ``elapsed`` seconds in sub-steps of at most ``max_substep`` seconds:
        the held command until its watchdog time is used up, a zero command after."""
        if elapsed <= 0:
            return
        held = min(elapsed, self._command_left)
        self._run(self._command, held, max_substep)
        self._command_left -= held
        rest = elapsed - held
        if rest <= 0:
            return
        if not self._cut and np.any(self._command != 0):
            self._cut = True
            self.watchdog_stops += 1
        self._command = np.zeros(self.table.n)
        self._command_left = 0.0
        self._run(self._command, rest, max_substep, coast=True)

    def _run(
        self, command: FloatArray, elapsed: float, max_substep: float, coast: bool = False
    ) -> None:
        """Equal sub-steps over ``elapsed``; ``coast``: a zero command, stop stepping at rest."""
        if elapsed <= 0:
            return
        steps = max(1, int(np.ceil(elapsed / max_substep - 1e-9)))
        dt = elapsed / steps
        for done in range(steps):
            if coast and not self.gripper_moving and np.all(np.abs(self._qd) < REST_SPEED):
                self._qd = np.zeros(self.table.n)
                self.time += dt * (steps - done)
                return
            self.step(command, dt)

    def command_gripper(self, command: str) -> None:
        """Start opening (``"open"``) or closing (``"close"``) the gripper."""
        if command not in GRIPPER_COMMANDS:
            raise ValueError(f"gripper command must be 'open' or 'close', got {command!r}")
        self._gripper_target = 1.0 if command == GripperAction.OPEN else 0.0

    def step(self, commanded_rates: ArrayLike, dt: float) -> None:
        """Advance the joints by ``dt`` seconds under ``commanded_rates`` (rad/s)."""
        if dt <= 0:
            return
        table = self.table
        command = np.clip(table.check_q(commanded_rates), -table.qd_max, table.qd_max)
        tau = self.settings.lag_tau
        blend = 1.0 if tau == 0 else 1.0 - np.exp(-dt / tau)
        wanted = self._qd + (command - self._qd) * blend
        max_change = self.settings.accel_max * dt
        qd_new = self._qd + np.clip(wanted - self._qd, -max_change, max_change)
        q_new = self._q + 0.5 * (self._qd + qd_new) * dt
        low = q_new <= table.q_min
        high = q_new >= table.q_max
        q_new = np.clip(q_new, table.q_min, table.q_max)
        qd_new[(low & (qd_new < 0)) | (high & (qd_new > 0))] = 0.0
        self._q = q_new
        self._qd = qd_new
        step = dt / self.settings.gripper_travel_time
        delta = self._gripper_target - self._gripper
        if abs(delta) <= step:
            self._gripper = self._gripper_target
        else:
            self._gripper += float(np.sign(delta)) * step
        self.time += dt
