"""The jog pad's dead-man: motion only while the operator holds a button or key.

The page sends the held jog again every :data:`KEEPALIVE_S` while a button or key is down (the
console tells the page this period), and a release when it goes up, when the page loses focus
or is hidden, or before it unloads. The console forwards the held jog at that period of its own
clock for as long as :class:`DeadMan` holds it, so a keep-alive that comes late (a page on a
loaded machine) does not zero the arm between two keep-alives; the register's watchdog zeroes
the jog when the console itself goes silent. :class:`DeadMan` gives the twist to command now:
zero once no keep-alive came for ``deadman_s`` (a frozen page, a dropped socket) or after a
release. A hold that was stopped (its keep-alives came too late, the console refused one, or
the register held the jog at zero) stays stopped until the page releases it: the arm stops once
and the page says why (:attr:`DeadMan.stopped`: a :class:`JogStop` code, its words, and the
exact text), instead of moving in bursts as keep-alives come and go. Time is the wall clock of
the operator's hands (monotonic seconds), passed in. Pure.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from umbra.connectors.reasons import Code, Worded
from umbra.modules.geometry.transforms import twist_camera_from_tool

FloatArray = NDArray[np.float64]

#: The page's keep-alive period while a jog is held [s] (sent to the page with the state); the
#: console forwards the held jog at this period too.
KEEPALIVE_S = 0.04


class JogFrame(Code):
    """The frame a jog's axes are given in."""

    TOOL = "tool"
    CAMERA = "camera"


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
    if jog_frame == JogFrame.TOOL:
        return twist_camera_from_tool(T_tool_camera, twist)
    if jog_frame == JogFrame.CAMERA:
        return twist
    raise ValueError(f"jog frame must be one of {', '.join(JogFrame)}, got {jog_frame!r}")


class JogStop(Worded):
    """Why a held jog was stopped; it stays stopped until its page releases it."""

    STALE_PICTURE = "stale_picture", "jog refused: your picture is not live"
    SILENT_PAGE = "silent_page", "jog stopped: the page's keep-alives came too late"
    GUARD = "guard", "jog stopped: the arm's guard held it at zero"


@dataclass(frozen=True)
class JogStopped:
    """A stopped hold: why (``code``) and the exact text (``detail``, for logs and the pad's
    tooltip)."""

    code: JogStop
    detail: str

    def view(self) -> dict[str, str]:
        """What the page is sent: ``code``, the operator's ``words`` and the ``detail``."""
        return {"code": str(self.code), "words": self.code.words, "detail": self.detail}


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
    console's ``Params`` holds the bound), on leave, or when the console refuses it; a hold
    dropped for silence or refused stays stopped until its page releases it."""

    def __init__(self, deadman_s: float = 0.15) -> None:
        self.deadman_s = deadman_s
        self.held: HeldJog | None = None
        self.expired = 0  #: jogs dropped for silence (no keep-alive in time)
        #: session -> why its hold was stopped; its keep-alives are ignored until it releases
        self.stopped: dict[str, JogStopped] = {}

    def update(
        self, session: str, held: bool, axes: list[float], speed: float, jog_frame: str, now: float
    ) -> None:
        """A jog message from ``session`` at wall time ``now`` [s]."""
        if not held or not any(axes) or speed <= 0:
            self.stopped.pop(session, None)  # released: the next press starts afresh
            if self.held is not None and self.held.session == session:
                self.held = None
            return
        if session in self.stopped:
            return  # this hold was stopped (and said why): it waits for its release
        self.held = HeldJog(session, list(axes), speed, jog_frame, now)

    def stop(self, session: str, code: JogStop, detail: str) -> None:
        """Stop the hold of ``session`` for ``code`` (``detail``: the exact text) until it is
        released."""
        self.stopped[session] = JogStopped(code, detail)
        if self.held is not None and self.held.session == session:
            self.held = None

    def release(self, session: str | None = None) -> None:
        """Drop the jog (of ``session`` only, when given): a disconnect or loss of control."""
        if self.held is not None and (session is None or self.held.session == session):
            self.held = None
        if session is None:
            self.stopped.clear()
        else:
            self.stopped.pop(session, None)

    def current(self, now: float) -> HeldJog | None:
        """The jog to command at wall time ``now`` [s], or None."""
        if self.held is None:
            return None
        silent = now - self.held.last_seen
        if silent > self.deadman_s:
            self.stop(
                self.held.session,
                JogStop.SILENT_PAGE,
                f"jog stopped: no keep-alive from the page for {silent:.2f} s, expected one "
                f"every {KEEPALIVE_S:.2f} s and at most {self.deadman_s:.2f} s apart (the page "
                "or its machine is too slow)",
            )
            self.expired += 1
            return None
        return self.held
