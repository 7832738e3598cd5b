"""The focus and memory commands of the FCB command set, as a PTZ control panel sends them
(controller -> camera): decoded for the simulated camera, encoded for tests and tools. The zoom,
power and interface commands are :mod:`umbra.modules.calib.visca.commands`.

============================  ==================================  =============================
command                       controller -> camera                camera -> controller
============================  ==================================  =============================
CAM_Focus stop                ``8x 01 04 08 00 FF``               ACK, completion
CAM_Focus far / near (std)    ``8x 01 04 08 02 / 03 FF``          ACK, completion
CAM_Focus far / near (var)    ``8x 01 04 08 2p / 3p FF``          ACK, completion (p 0..7)
CAM_Focus direct              ``8x 01 04 48 0p 0q 0r 0s FF``      ACK, completion on arrival
CAM_Focus auto / manual       ``8x 01 04 38 02 / 03 FF``          ACK, completion
CAM_Focus auto/manual toggle  ``8x 01 04 38 10 FF``               ACK, completion
CAM_Focus one push trigger    ``8x 01 04 18 01 FF``               ACK, completion
CAM_Memory reset / set        ``8x 01 04 3F 00 / 01 0p FF``       ACK, completion (p 0..5)
CAM_Memory recall             ``8x 01 04 3F 02 0p FF``            ACK, completion on arrival
CAM_FocusModeInq              ``8x 09 04 38 FF``                  ``y0 50 02 FF`` auto, ``03``
CAM_FocusPosInq               ``8x 09 04 48 FF``                  ``y0 50 0p 0q 0r 0s FF``
============================  ==================================  =============================

Focus far/near/direct are manual-focus commands: in auto focus the camera answers them "command
not executable" (``y0 6z 41 FF``), as the VISCA command list says for manual focus control
during auto focus. A memory number outside 0..5 (the six memories of an FCB) is a syntax error.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

from umbra.modules.calib.visca import protocol as vp

MAX_FOCUS_SPEED = 7
"""Fastest variable focus speed ``p`` (0 is the slowest)."""
MEMORIES = 6
"""Memory positions of an FCB camera (numbers 0..5)."""


class FocusDirection(enum.Enum):
    """Direction of a continuous focus: toward far (infinity) or near."""

    FAR = "far"
    NEAR = "near"


class FocusMode(enum.Enum):
    """What CAM_Focus mode sets: auto focus, manual focus, or the other of the two."""

    AUTO = 0x02
    MANUAL = 0x03
    TOGGLE = 0x10


class MemoryAction(enum.Enum):
    """CAM_Memory: reset a memory to the power-on state, set it from now, recall it."""

    RESET = 0x00
    SET = 0x01
    RECALL = 0x02


@dataclass(frozen=True, slots=True)
class FocusStopCommand:
    address: int


@dataclass(frozen=True, slots=True)
class FocusMoveCommand:
    """Far or near until stopped; ``speed`` None for the standard speed, else 0..7."""

    address: int
    direction: FocusDirection
    speed: int | None


@dataclass(frozen=True, slots=True)
class FocusDirectCommand:
    address: int
    raw: int


@dataclass(frozen=True, slots=True)
class FocusModeCommand:
    address: int
    mode: FocusMode


@dataclass(frozen=True, slots=True)
class FocusOnePushCommand:
    address: int


@dataclass(frozen=True, slots=True)
class MemoryCommand:
    address: int
    action: MemoryAction
    number: int


@dataclass(frozen=True, slots=True)
class FocusPositionInquiry:
    address: int


@dataclass(frozen=True, slots=True)
class FocusModeInquiry:
    address: int


PanelCommand = (
    FocusStopCommand
    | FocusMoveCommand
    | FocusDirectCommand
    | FocusModeCommand
    | FocusOnePushCommand
    | MemoryCommand
    | FocusPositionInquiry
    | FocusModeInquiry
)
PanelInquiry = FocusPositionInquiry | FocusModeInquiry
PanelSocketCommand = (
    FocusStopCommand
    | FocusMoveCommand
    | FocusDirectCommand
    | FocusModeCommand
    | FocusOnePushCommand
    | MemoryCommand
)
"""Panel commands executed in a socket (ACK ``y0 4z FF``, then completion or an error)."""


def decode_panel(address: int, body: bytes) -> PanelCommand | None:
    """The panel command in ``body`` (a packet without header and terminator), or None."""
    if body == b"\x09\x04\x48":
        return FocusPositionInquiry(address)
    if body == b"\x09\x04\x38":
        return FocusModeInquiry(address)
    if body == b"\x01\x04\x18\x01":
        return FocusOnePushCommand(address)
    if len(body) == 4 and body[:3] == b"\x01\x04\x08":
        return _focus_move(address, body[3])
    if len(body) == 4 and body[:3] == b"\x01\x04\x38":
        modes = {m.value: m for m in FocusMode}
        return FocusModeCommand(address, modes[body[3]]) if body[3] in modes else None
    if len(body) == 7 and body[:3] == b"\x01\x04\x48":
        try:
            return FocusDirectCommand(address, vp.from_nibbles(body[3:]))
        except vp.ViscaDecodeError:
            return None
    if len(body) == 5 and body[:3] == b"\x01\x04\x3f":
        actions = {a.value: a for a in MemoryAction}
        if body[3] in actions and body[4] < MEMORIES:
            return MemoryCommand(address, actions[body[3]], body[4])
    return None


def _focus_move(address: int, code: int) -> FocusStopCommand | FocusMoveCommand | None:
    if code == 0x00:
        return FocusStopCommand(address)
    if code in (0x02, 0x03):
        direction = FocusDirection.FAR if code == 0x02 else FocusDirection.NEAR
        return FocusMoveCommand(address, direction, None)
    kind, speed = code & 0xF0, code & 0x0F
    if kind in (0x20, 0x30) and speed <= MAX_FOCUS_SPEED:
        direction = FocusDirection.FAR if kind == 0x20 else FocusDirection.NEAR
        return FocusMoveCommand(address, direction, speed)
    return None


# --------------------------------------------------------------------------------------------
# encoding (controller side) and the camera's inquiry replies


def encode_focus_move(address: int, direction: FocusDirection | None, speed: int | None) -> bytes:
    """CAM_Focus stop (``direction`` None), far/near at the standard speed (``speed`` None) or
    at variable speed ``speed`` 0..7."""
    if direction is None:
        code = 0x00
    elif speed is None:
        code = 0x02 if direction is FocusDirection.FAR else 0x03
    elif 0 <= speed <= MAX_FOCUS_SPEED:
        code = (0x20 if direction is FocusDirection.FAR else 0x30) | speed
    else:
        raise ValueError(f"variable focus speed must be 0..{MAX_FOCUS_SPEED}, got {speed}")
    return bytes((vp.command_header(address), 0x01, 0x04, 0x08, code, vp.TERMINATOR))


def encode_memory(address: int, action: MemoryAction, number: int) -> bytes:
    """CAM_Memory reset/set/recall ``8x 01 04 3F 0a 0p FF`` of memory ``number`` 0..5."""
    if not 0 <= number < MEMORIES:
        raise ValueError(f"memory number must be 0..{MEMORIES - 1}, got {number}")
    return bytes((vp.command_header(address), 0x01, 0x04, 0x3F, action.value, number, 0xFF))


def encode_focus_position_reply(address: int, raw: int) -> bytes:
    """CAM_FocusPosInq reply ``y0 50 0p 0q 0r 0s FF``."""
    return vp.encode_completion(address, 0, vp.nibbles(raw))


def encode_focus_mode_reply(address: int, auto: bool) -> bytes:
    """CAM_FocusModeInq reply ``y0 50 02 FF`` (auto focus) / ``03`` (manual)."""
    return vp.encode_completion(address, 0, bytes((0x02 if auto else 0x03,)))
