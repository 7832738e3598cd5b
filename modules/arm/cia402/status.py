"""What a CANopen arm reports: joint feedback, its run state, and why it stopped.

Angles in radians, rates in rad/s, ages in seconds (monotonic clock).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np
from canopen.emcy import EmcyError
from numpy.typing import NDArray

from umbra.modules.arm.cia402.state_machine import State


class ArmState(enum.Enum):
    """Run state of the arm as a whole."""

    IDLE = "idle"  # not started
    RUNNING = "running"  # every drive in Operation enabled, commands accepted
    TRIPPED = "tripped"  # something went wrong: every drive quick-stopped, commands ignored
    STOPPED = "stopped"  # stopped on request, bus released


class TripCause(enum.Enum):
    """Why the arm tripped."""

    FAULT = "drive fault"  # statusword fault bit
    EMERGENCY = "emergency message"  # EMCY with a non-zero error code
    HEARTBEAT_LOST = "heartbeat lost"
    FEEDBACK_LOST = "feedback lost"  # no TPDO within the feedback timeout
    NMT_STATE = "NMT state"  # drive left NMT OPERATIONAL (reset, stop)
    STATE_LOST = "left operation enabled"
    BUS_ERROR = "bus error"
    BAD_COMMAND = "bad command"  # non-finite joint rate


def describe_error_code(code: int) -> str:
    """'0x2310 (Current)': a CiA 301 error code with its class."""
    text = EmcyError(code, 0, b"", 0.0).get_desc()
    return f"0x{code:04X} ({text})" if text else f"0x{code:04X}"


@dataclass(frozen=True)
class DriveTrip:
    """One reason to stop: which drive (None for the bus as a whole), what, details."""

    cause: TripCause
    detail: str
    joint: str | None = None
    node_id: int | None = None
    error_code: int | None = None

    def __str__(self) -> str:
        where = "CAN bus" if self.node_id is None else f"joint {self.joint!r} (node {self.node_id})"
        return f"{where}: {self.cause.value}: {self.detail}"


@dataclass(frozen=True)
class ArmStatus:
    """Run state, the trips in the order they happened, stale commands, CAN error frames seen."""

    state: ArmState
    trips: tuple[DriveTrip, ...] = ()
    command_stale: bool = False
    error_frames: int = 0

    @property
    def ok(self) -> bool:
        return self.state is ArmState.RUNNING and not self.trips

    @property
    def message(self) -> str:
        """One line a person can read."""
        if not self.trips:
            text = self.state.value
            return text + " (no command: targets held at zero)" if self.command_stale else text
        return f"{self.state.value}: " + "; ".join(str(t) for t in self.trips)


@dataclass(frozen=True)
class JointFeedback:
    """Latest feedback of every joint, in joint order.

    Attributes:
        positions_rad: joint angles from position actual values (rad).
        velocities_rad_s: joint rates from velocity actual values (rad/s).
        ages_s: time since each joint's latest feedback arrived (s); inf if none yet.
        states: each drive's CiA 402 state from its latest statusword (None if none yet).
    """

    positions_rad: NDArray[np.float64]
    velocities_rad_s: NDArray[np.float64]
    ages_s: NDArray[np.float64]
    states: tuple[State | None, ...]
