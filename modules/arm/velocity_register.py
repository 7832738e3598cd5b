"""The velocity register (REG_VEL) logic: hold the latest twist, drop to zero on any doubt.

The register passes the latest commanded twist through, with its linear and angular speeds
clamped (each part scaled as a vector, so the direction is kept). It outputs zero, and says
why, when:

* no command has arrived yet;
* the latest command arrived longer than ``timeout`` ago (the link's watchdog);
* the latest command was made from sensor data older than ``max_origin_age`` (its ``origin``:
  a command computed now from a 30-second-old image is refused however recently it arrived);
* the producer is gone (the caller says so, e.g. from link liveliness);
* the caller names another reason to halt (e.g. a failed sanity check upstream);
* the command is not a finite 6-vector.

Pure: time comes in as arguments, there is no clock or thread here. Units: m/s, rad/s, seconds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.connectors.states import GuardReason
from umbra.modules.geometry.transforms import clamp_twist

FloatArray = NDArray[np.float64]

_ZERO = np.zeros(6)
_ZERO.setflags(write=False)


@dataclass(frozen=True)
class RegisterSettings:
    """Watchdog and clamps of the register, built from validated parameters (REG_VEL's
    ``Params`` holds their bounds), not checked again here.

    Attributes:
        timeout: largest accepted time since the command arrived (s).
        max_linear: largest linear speed |v| (m/s).
        max_angular: largest angular speed |w| (rad/s).
        max_origin_age: oldest sensor data a passed command may be made from (s).
    """

    timeout: float = 0.2
    max_linear: float = 0.1
    max_angular: float = 0.5
    max_origin_age: float = 0.25


@dataclass(frozen=True)
class RegisterOutput:
    """What the register emits: ``twist`` ``[v; w]``; ``zero_reason`` is empty when it passes,
    else the exact reason, and ``code`` says why in a code (``GuardReason.PASSING`` when it
    passes).

    ``clamped`` tells that a speed limit scaled the command; ``age`` is the time since the
    command arrived (s) and ``origin_age`` the age of the sensor data it was made from (s), both
    infinite when there is none. ``stale`` tells that the zero is for old data (``origin_age``
    over the bound): the run's verdict then says "stopped: data too old".
    """

    twist: FloatArray
    zero_reason: str
    clamped: bool
    age: float
    origin_age: float = float("inf")
    stale: bool = False
    code: GuardReason = GuardReason.PASSING

    @property
    def passing(self) -> bool:
        """True when the output is the (possibly clamped) command, not a forced zero."""
        return self.code == GuardReason.PASSING


class VelocityRegister:
    """Latest twist command and its stamp; :meth:`output` applies the watchdog and clamps."""

    def __init__(self, settings: RegisterSettings = RegisterSettings()) -> None:
        self.settings = settings
        self._twist: FloatArray | None = None
        self._stamp = -np.inf
        self._origin = -np.inf
        self._bad = ""

    @property
    def origin(self) -> float:
        """Capture time [s] of the oldest sensor data behind the held command (-inf: none)."""
        return self._origin

    def put(self, twist: ArrayLike, stamp: float, origin: float | None = None) -> None:
        """Store a command ``[v; w]`` that arrived at ``stamp`` and was made from sensor data
        captured at ``origin`` (seconds on the run's clock; None: ``stamp``; -inf: undatable)."""
        xi = np.asarray(twist, dtype=float).reshape(-1)
        if xi.shape != (6,) or not np.all(np.isfinite(xi)):
            self._twist = None
            self._bad = f"command rejected: expected 6 finite numbers, got {xi.tolist()}"
        else:
            self._twist = xi.copy()
            self._bad = ""
        self._stamp = float(stamp)
        self._origin = float(stamp if origin is None else origin)

    @property
    def empty(self) -> bool:
        """True when no command is held (none yet, cleared, or rejected)."""
        return self._twist is None

    def clear(self) -> None:
        """Forget the held command (output is zero until the next :meth:`put`)."""
        self._twist = None
        self._stamp = -np.inf
        self._origin = -np.inf
        self._bad = ""

    def output(
        self,
        now: float,
        producer_alive: bool = True,
        halt: str = "",
        halt_code: GuardReason = GuardReason.HALTED,
    ) -> RegisterOutput:
        """The twist to pass on at time ``now``, or zero with the reason.

        Args:
            now: current time (s), same clock as the stamps.
            producer_alive: False when the command's producer has disappeared.
            halt: a non-empty reason forces zero (e.g. an upstream failure), with ``halt_code``.
        """
        age = float(now - self._stamp)
        origin_age = float(now - self._origin)
        settings = self.settings
        reason, stale, code = "", False, GuardReason.PASSING
        if halt:
            reason, code = halt, halt_code
        elif not producer_alive:
            reason, code = "command producer is gone", GuardReason.PRODUCER_GONE
        elif self._bad:
            reason, code = self._bad, GuardReason.REJECTED
        elif self._twist is None:
            reason, code = "no command received yet", GuardReason.NO_COMMAND_YET
        elif origin_age > settings.max_origin_age:
            stale = True
            limit = settings.max_origin_age
            reason = f"command made from {_sensor_data(origin_age)} (limit {limit:.2f} s)"
            code = GuardReason.STALE_DATA if np.isfinite(origin_age) else GuardReason.UNDATABLE
        elif age > settings.timeout:
            reason = f"no new command for {age:.3f} s (link watchdog {settings.timeout:.3f} s)"
            code = GuardReason.WATCHDOG
        if reason:
            return RegisterOutput(_ZERO, reason, False, age, origin_age, stale, code)
        assert self._twist is not None  # a missing command gave a reason above
        twist, clamped = clamp_twist(self._twist, settings.max_linear, settings.max_angular)
        return RegisterOutput(twist, "", clamped, age, origin_age)


def _sensor_data(age: float) -> str:
    """Old data in the operator's words: "sensor data 1.30 s old", or undatable."""
    return (
        f"sensor data {age:.2f} s old" if np.isfinite(age) else "sensor data that cannot be dated"
    )
