"""The joint-driver backend interface of WOLVERINE_JNTS, and its simulated backend.

A backend drives the arm's joints: it accepts joint-rate commands and reports joint angles. The
module calls, once per tick and never expecting to block::

    reading = backend.read(now)      # state at `now` (the sim integrates up to `now` here)
    backend.command(rates, now)      # hold these rates until the next command
    backend.command_gripper("close") # when a gripper command arrives

``start()`` may block (bring-up of drives); ``stop()`` must leave the joints at rest.

Backends are found by name in :data:`BACKENDS` (``"module.path:ClassName"``) and built with
``Class.from_module(table, params, context)``; ``params`` are WOLVERINE_JNTS's parameters. The
``canopen`` backend (CiA 402 drives) lives in ``modules/arm/cia402``.
"""

from __future__ import annotations

import importlib
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.modules.arm.dh import DHTable
from umbra.modules.arm.sim_joints import SimJoints, SimJointSettings

FloatArray = NDArray[np.float64]

BACKENDS: dict[str, str] = {
    "sim": "umbra.modules.arm.joints_backend:SimJointsBackend",
    "canopen": "umbra.modules.arm.cia402.backend:Cia402Backend",
}


class BackendError(ValueError):
    """A backend cannot be found or built from the given parameters."""


@dataclass(frozen=True)
class JointReading:
    """Joint state as the backend reports it.

    Attributes:
        position: joint angles the controller sees (rad or m), in the arm's joint order.
        velocity: joint rates (rad/s or m/s).
        gripper: gripper opening 0 (closed) .. 1 (open); NaN when there is no gripper.
        ok: False when the drives stopped themselves (fault, trip, lost feedback).
        message: one line for the operator ("running", or why not).
        true_position: the plant's true angles (simulation only; None on hardware).
    """

    position: FloatArray
    velocity: FloatArray
    gripper: float = float("nan")
    ok: bool = True
    message: str = "running"
    true_position: FloatArray | None = None


class JointsBackend(ABC):
    """What WOLVERINE_JNTS needs from a joint driver."""

    joint_names: tuple[str, ...]

    @classmethod
    @abstractmethod
    def from_module(cls, table: DHTable, params: Any, context: Any) -> JointsBackend:
        """Build the backend from the arm's DH table and WOLVERINE_JNTS's parameters."""

    @abstractmethod
    def start(self) -> None:
        """Bring the joints up (may block); they hold still until commanded."""

    @abstractmethod
    def read(self, now: float) -> JointReading:
        """The joint state at ``now`` (never blocks)."""

    @abstractmethod
    def command(self, rates: ArrayLike, now: float) -> bool:
        """Hold ``rates`` (rad/s) until the next command; False when refused (tripped)."""

    def command_gripper(self, command: str) -> bool:
        """Start opening (``"open"``) or closing (``"close"``); False when there is no gripper."""
        return False

    @abstractmethod
    def stop(self) -> None:
        """Bring the joints to rest and release the hardware."""

    def counters(self) -> dict[str, int]:
        """Event counts for the run's summary (e.g. drive watchdog stops)."""
        return {}


def backend_class(name: str) -> type[JointsBackend]:
    """The backend class registered as ``name`` (imported on demand)."""
    if name not in BACKENDS:
        raise BackendError(f"unknown joint backend {name!r}; expected one of {sorted(BACKENDS)}")
    module_name, class_name = BACKENDS[name].split(":")
    try:
        cls = getattr(importlib.import_module(module_name), class_name)
    except (ImportError, AttributeError) as exc:
        raise BackendError(
            f"joint backend {name!r} ({BACKENDS[name]}) is not available: {exc}"
        ) from None
    return cls


class SimJointsBackend(JointsBackend):
    """Simulated joints (:class:`umbra.modules.arm.sim_joints.SimJoints`) on the run's clock.

    The held command is integrated from the previous ``read`` to ``now`` in sub-steps of at
    most ``max_substep`` seconds, so results do not depend much on the module's rate. The first
    ``read`` after ``start`` sets the time base (no integration). The drive's watchdog
    (``settings.watchdog``) bounds how long a command is obeyed: a gap between two steps (the
    process stopped, starved or suspended) integrates the command for that long at most, then the
    joints decelerate to rest, and the reading says so until the next command.
    """

    def __init__(
        self,
        table: DHTable,
        q0: ArrayLike | None = None,
        settings: SimJointSettings = SimJointSettings(),  # noqa: B008 - frozen default
        gripper_opening: float = 1.0,
        max_substep: float = 0.002,
    ) -> None:
        self.table = table
        self.joint_names = table.names
        self.sim = SimJoints(table, q0, settings, gripper_opening)
        self.max_substep = max_substep
        self._time: float | None = None

    @classmethod
    def from_module(cls, table: DHTable, params: Any, context: Any) -> SimJointsBackend:
        if params.initial_q_deg is None:
            q0 = np.clip(np.zeros(table.n), table.q_min, table.q_max)
        else:
            q0 = np.radians(np.asarray(params.initial_q_deg, dtype=float))
        error = np.radians(np.asarray(params.calibration_error_deg, dtype=float))
        settings = SimJointSettings(
            accel_max=params.accel_max,
            lag_tau=params.lag_tau,
            calibration_error=tuple(error.tolist()),
            gripper_travel_time=params.gripper_travel_time,
            watchdog=params.drive_watchdog,
        )
        try:
            return cls(table, q0, settings, params.gripper_initial)
        except ValueError as exc:
            raise BackendError(str(exc)) from None

    def start(self) -> None:
        self._time = None  # the first read sets the time base

    def _advance(self, now: float) -> None:
        if self._time is None:
            self._time = now
        elapsed = now - self._time
        if elapsed <= 0:
            return
        self.sim.advance(elapsed, self.max_substep)
        self._time = now

    def read(self, now: float) -> JointReading:
        self._advance(now)
        stopped = self.sim.watchdog_stopped
        return JointReading(
            position=self.sim.q_reported,
            velocity=self.sim.qd,
            gripper=self.sim.gripper_opening,
            ok=not stopped,
            message=(
                f"drive watchdog: no command for over {self.sim.settings.watchdog:g} s, "
                "joints stopped"
                if stopped
                else "running"
            ),
            true_position=self.sim.q_true,
        )

    def command(self, rates: ArrayLike, now: float) -> bool:
        self._advance(now)
        self.sim.hold(rates)
        return True

    def counters(self) -> dict[str, int]:
        return {"drive_watchdog_stops": self.sim.watchdog_stops}

    def command_gripper(self, command: str) -> bool:
        self.sim.command_gripper(command)
        return True

    def stop(self) -> None:
        self.sim.hold(np.zeros(self.table.n))
