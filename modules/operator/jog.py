"""The jog pad's dead-man: motion only while the operator holds a button or key.

The page sends the held jog again every 40 ms while a button or key is down, and a release
when it goes up, when the page loses focus or is hidden, or before it unloads. The console
forwards one twist per keep-alive, so the register's watchdog zeroes a silent jog too.
:class:`DeadMan` gives the twist to command now: zero once no keep-alive came for
``deadman_s`` (a frozen page, a dropped socket) or after a release. Time is the wall clock of
the operator's hands (monotonic seconds), passed in. Pure.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from umbra.modules.geometry.transforms import twist_camera_from_tool

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class JogLimits:
    """Full-speed jog: ``linear`` [m/s] along x, y, z and ``angular`` [rad/s] in roll."""

    linear: float = 0.02
    angular: float = 0.2


def jog_twist(
    axes: list[float],
    speed: float,
    jog_frame: str,
    limits: JogLimits,
    T_tool_camera: FloatArray,
) -> FloatArray:
    """The camera-frame twist ``[v; w]`` for a jog of ``axes`` (x, y, z, roll in [-1, 1]) at
    ``speed`` (0..1 of ``limits``) given in ``jog_frame`` (``tool`` or ``camera``).

    A tool-frame jog is moved into the camera frame with the rigid transform ``T_tool_camera``
    (the camera's pose in the tool frame), so the arm moves as the operator asked in the frame
    they chose, whichever frame the register works in.
    """
    a = np.clip(np.asarray(axes, dtype=float), -1.0, 1.0)
    s = float(np.clip(speed, 0.0, 1.0))
    twist = np.array(
        [
            a[0] * limits.linear * s,
            a[1] * limits.linear * s,
            a[2] * limits.linear * s,
            0.0,
            0.0,
            a[3] * limits.angular * s,
        ]
    )
    if jog_frame == "tool":
        return twist_camera_from_tool(T_tool_camera, twist)
    if jog_frame == "camera":
        return twist
    raise ValueError(f"jog frame must be `tool` or `camera`, got {jog_frame!r}")


@dataclass
class HeldJog:
    """A jog being held: by whom, what, and the wall time of its latest keep-alive [s]."""

    session: str
    axes: list[float]
    speed: float
    jog_frame: str
    last_seen: float


class DeadMan:
    """The held jog, dropped on release, on silence longer than ``deadman_s`` [s] (> 0: the
    console's ``Params`` holds the bound), or on leave."""

    def __init__(self, deadman_s: float = 0.15) -> None:
        self.deadman_s = deadman_s
        self.held: HeldJog | None = None
        self.expired = 0  #: jogs dropped for silence (no keep-alive in time)

    def update(
        self, session: str, held: bool, axes: list[float], speed: float, jog_frame: str, now: float
    ) -> None:
        """A jog message from ``session`` at wall time ``now`` [s]."""
        if not held or not any(axes) or speed <= 0:
            if self.held is not None and self.held.session == session:
                self.held = None
            return
        self.held = HeldJog(session, list(axes), speed, jog_frame, now)

    def release(self, session: str | None = None) -> None:
        """Drop the jog (of ``session`` only, when given): a disconnect or loss of control."""
        if self.held is not None and (session is None or self.held.session == session):
            self.held = None

    def current(self, now: float) -> HeldJog | None:
        """The jog to command at wall time ``now`` [s], or None."""
        if self.held is None:
            return None
        if now - self.held.last_seen > self.deadman_s:
            self.held = None
            self.expired += 1
            return None
        return self.held
