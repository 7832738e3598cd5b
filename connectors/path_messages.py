"""Message types of a planned arm path and its player: the path, the VCR's commands and state.

Spoken by the planners (Active Sketch), the path player (VCR_PLAYER), the simulated world, the
operator's console and the /sketch page. Units are SI (metres, radians, seconds); tool poses are
4 x 4 homogeneous transforms ``T_base_tool`` in ``frame``.

Flow::

    planner --ToolPath--> VCR player <--VcrCommand-- console
    VCR player --VcrState--> console;  --JointRates--> REG_VEL (safety guard)
"""

from __future__ import annotations

from typing import ClassVar

import msgspec
import numpy as np

from umbra.connectors.messages import Message
from umbra.connectors.reasons import Code
from umbra.connectors.sketch_messages import Macro

_EMPTY = np.zeros(0)
_F8 = "float64"


class ToolPath(Message, frozen=True, kw_only=True):
    """A planned and checked path for the arm, as waypoints along path parameter ``s``.

    ``s`` (N,, m-equivalent, increasing from 0): path parameter at each waypoint (arc length of
    the joint path in the weighted norm of the planner); ``joints`` (N x n, rad): joint positions
    for ``names``; ``T_base_tool`` (N x 4 x 4, m): tool poses (for display); ``gripper`` (N,):
    commanded gripper opening 0 closed .. 1 open at each waypoint. ``ok`` is False when a check
    failed, and ``reason`` says which check, where and by how much. ``checks`` holds the figures
    (min margins, peak rates). ``path_id`` names the plan; VCR commands refer to it.
    """

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "path_id": "names the plan",
        "macro": "the Macro that made it",
        "names": "n joint names",
        "s": f"{_F8} (N,), path parameter, increasing from 0",
        "joints": f"{_F8} (N, n), rad",
        "T_base_tool": f"{_F8} (N, 4, 4) or (0, 4, 4), m",
        "gripper": f"{_F8} (N,) or (0,), 0 closed .. 1 open",
        "ok": "false: a check failed",
        "reason": "which check failed, where, by how much",
        "checks": "map str -> float: margins, peak rates",
        "frame": "frame of the tool poses",
    }

    path_id: str
    macro: Macro
    names: tuple[str, ...]
    s: np.ndarray
    joints: np.ndarray
    T_base_tool: np.ndarray = np.zeros((0, 4, 4))
    gripper: np.ndarray = _EMPTY
    ok: bool = True
    reason: str = ""
    checks: dict[str, float] = msgspec.field(default_factory=dict)
    frame: str = "base"

    HAS_JOINTS: ClassVar[bool] = True


class VcrAction(Code):
    """What a VCR command asks of the player."""

    PLAY = "play"  #: forward along the path
    BACK = "back"  #: reverse along the same path
    PAUSE = "pause"  #: a jerk-limited stop on the path
    RESUME = "resume"  #: play on
    SPEED = "speed"  #: set the speed override
    SEEK = "seek"  #: move along the path to ``s``
    STOP = "stop"  #: as pause


class VcrCommand(Message, frozen=True, kw_only=True):
    """A command to the VCR trajectory player.

    ``action``: "play" (forward), "back" (reverse along the same path), "pause" (jerk-limited
    stop on the path), "speed" (set ``speed``), "seek" (move along the path to ``s``), "stop".
    ``speed``: fraction of the planned speed, 0.1 .. 1 (0: keep the current one) for "play",
    "back" and "speed". ``s``: seek target. ``path_id`` must match the loaded path.
    """

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "action": "VcrAction: " + ", ".join(f'"{a}"' for a in VcrAction),
        "path_id": "must match the loaded path",
        "speed": "fraction of the planned speed, 0.1 .. 1 (0: keep)",
        "s": "seek target (path parameter)",
    }

    action: VcrAction
    path_id: str = ""
    speed: float = 0.0
    s: float = 0.0


class VcrMode(Code):
    """What the VCR player is doing with its path."""

    IDLE = "idle"  #: no path, or one refused
    PLAYING = "playing"
    BACKING = "backing"
    SEEKING = "seeking"  #: moving to a path parameter asked for
    PAUSING = "pausing"  #: slowing to a stop on the path
    PAUSED = "paused"
    AT_STOP = "at_stop"  #: at a stop point (a gripper event) on the path
    GRIPPING = "gripping"  #: waiting there for the gripper
    HALTING = "halting"  #: slowing to a stop for a halt (lost console, stale data, guard)
    HALTED = "halted"
    DONE = "done"  #: played to its end


#: Modes in which the path parameter may be changing: the player drives the arm.
VCR_MOVING = frozenset(
    {VcrMode.PLAYING, VcrMode.BACKING, VcrMode.SEEKING, VcrMode.PAUSING, VcrMode.HALTING}
)
#: Modes in which a path is under way: moving, at a stop point, or waiting for the gripper there.
VCR_BUSY = VCR_MOVING | {VcrMode.AT_STOP, VcrMode.GRIPPING}
#: Modes in which a path is under way and goes on without a new command (not already stopping).
VCR_GOING = VCR_BUSY - {VcrMode.PAUSING, VcrMode.HALTING}


class VcrState(Message, frozen=True, kw_only=True):
    """The VCR player's state: ``mode`` (:class:`VcrMode`), path parameter ``s`` and its rate
    ``s_dot`` [1/s of s], ``speed`` override, ``progress`` 0 .. 1, ``reason`` for a halt (lost
    console, stale command, guard stop)."""

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "path_id": "the loaded path",
        "mode": "VcrMode: " + ", ".join(f'"{m}"' for m in VcrMode),
        "s": "path parameter",
        "s_dot": "1/s (of s)",
        "speed": "override, fraction of the planned speed",
        "progress": "0 .. 1",
        "reason": "why it halted",
    }

    path_id: str
    mode: VcrMode
    s: float = 0.0
    s_dot: float = 0.0
    speed: float = 1.0
    progress: float = 0.0
    reason: str = ""
