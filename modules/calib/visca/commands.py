"""The FCB command set a controller sends (controller -> camera): encoders and the decoder the
simulated camera uses. Framing, replies and zoom scaling are in
:mod:`umbra.modules.calib.visca.protocol`.

==========================  ==================================  ===============================
command                     controller -> camera                camera -> controller
==========================  ==================================  ===============================
Address set (broadcast)     ``88 30 01 FF``                     ``88 30 0w FF``
IF_Clear (broadcast)        ``88 01 00 01 FF``                  echoed
IF_Clear                    ``8x 01 00 01 FF``                  ``y0 50 FF``
Command cancel              ``8x 2z FF`` (z: socket)            ``y0 6z 04 FF`` / ``y0 6z 05 FF``
CAM_Power on / off          ``8x 01 04 00 02 / 03 FF``          ACK, completion
CAM_Zoom stop               ``8x 01 04 07 00 FF``               ACK, completion
CAM_Zoom tele / wide (std)  ``8x 01 04 07 02 / 03 FF``          ACK, completion
CAM_Zoom tele / wide (var)  ``8x 01 04 07 2p / 3p FF``          ACK, completion (p 0..7)
CAM_Zoom direct             ``8x 01 04 47 0p 0q 0r 0s FF``      ACK, completion on arrival
CAM_PowerInq                ``8x 09 04 00 FF``                  ``y0 50 02 FF`` on, ``03`` off
CAM_ZoomPosInq              ``8x 09 04 47 FF``                  ``y0 50 0p 0q 0r 0s FF``
CAM_VersionInq              ``8x 09 00 02 FF``                  ``y0 50 00 20 mn pq rs tu vw FF``
==========================  ==================================  ===============================

The focus and memory commands a PTZ panel sends are
:mod:`umbra.modules.calib.visca.commands_panel`; :func:`decode_command` decodes them too.

The tele/wide commands start a movement and complete at once (the lens keeps moving until a stop,
another zoom command, or the end of the range); zoom direct completes when the lens arrives.
The version reply carries the vendor (``0020``: Sony), the model code ``mnpq``, the ROM version
``rstu`` and the number of command sockets ``vw`` (2).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

from umbra.modules.calib.visca import protocol as vp
from umbra.modules.calib.visca.commands_panel import (
    PanelCommand,
    PanelInquiry,
    PanelSocketCommand,
    decode_panel,
)

SONY_VENDOR_ID = 0x0020
SOCKETS = 2
"""Command sockets (buffers) of an FCB camera: commands run in socket 1 or 2."""
MAX_ZOOM_SPEED = 7
"""Fastest variable zoom speed ``p`` (0 is the slowest)."""


class ZoomDirection(enum.Enum):
    """Direction of a continuous zoom: toward tele (narrow view) or wide."""

    TELE = "tele"
    WIDE = "wide"


# --------------------------------------------------------------------------------------------
# encoding (controller side)


def encode_cancel(address: int, socket: int) -> bytes:
    """Command cancel ``8x 2z FF``: stop the command running in socket ``socket`` (1 or 2)."""
    if not 1 <= socket <= SOCKETS:
        raise ValueError(f"cancel names socket 1..{SOCKETS}, got {socket}")
    return bytes((vp.command_header(address), 0x20 | socket, vp.TERMINATOR))


def encode_power(address: int, on: bool) -> bytes:
    """CAM_Power ``8x 01 04 00 02 FF`` (on) / ``03`` (off, standby)."""
    return bytes((vp.command_header(address), 0x01, 0x04, 0x00, 0x02 if on else 0x03, 0xFF))


def encode_zoom_stop(address: int) -> bytes:
    """CAM_Zoom stop ``8x 01 04 07 00 FF``."""
    return bytes((vp.command_header(address), 0x01, 0x04, 0x07, 0x00, vp.TERMINATOR))


def encode_zoom_move(address: int, direction: ZoomDirection, speed: int | None = None) -> bytes:
    """CAM_Zoom tele/wide: standard speed (``02``/``03``) when ``speed`` is None, else variable
    (``2p``/``3p``, p = ``speed`` 0..7)."""
    tele = direction is ZoomDirection.TELE
    if speed is None:
        code = 0x02 if tele else 0x03
    elif 0 <= speed <= MAX_ZOOM_SPEED:
        code = (0x20 if tele else 0x30) | speed
    else:
        raise ValueError(f"variable zoom speed must be 0..{MAX_ZOOM_SPEED}, got {speed}")
    return bytes((vp.command_header(address), 0x01, 0x04, 0x07, code, vp.TERMINATOR))


def encode_power_inquiry(address: int) -> bytes:
    """CAM_PowerInq ``8x 09 04 00 FF``."""
    return bytes((vp.command_header(address), 0x09, 0x04, 0x00, vp.TERMINATOR))


def encode_version_inquiry(address: int) -> bytes:
    """CAM_VersionInq ``8x 09 00 02 FF``."""
    return bytes((vp.command_header(address), 0x09, 0x00, 0x02, vp.TERMINATOR))


# --------------------------------------------------------------------------------------------
# replies with a payload (camera side, used by the simulator)


def encode_power_reply(address: int, on: bool) -> bytes:
    """CAM_PowerInq reply ``y0 50 02 FF`` (on) / ``y0 50 03 FF`` (off)."""
    return vp.encode_completion(address, 0, bytes((0x02 if on else 0x03,)))


def encode_version_reply(address: int, model: int, rom: int) -> bytes:
    """CAM_VersionInq reply ``y0 50 00 20 mn pq rs tu vw FF`` (each of mnpq, rstu 7-bit bytes)."""
    for what, value in (("model code", model), ("ROM version", rom)):
        if not 0 <= value <= 0x7F7F or (value & 0x80) or (value >> 8) & 0x80:
            raise ValueError(f"{what} must be two 7-bit bytes, got {value:#06x}")
    payload = bytes((0x00, SONY_VENDOR_ID, model >> 8, model & 0xFF, rom >> 8, rom & 0xFF, SOCKETS))
    return vp.encode_completion(address, 0, payload)


@dataclass(frozen=True, slots=True)
class Version:
    """What CAM_VersionInq reports."""

    vendor: int
    model: int
    rom: int
    sockets: int


def decode_version(reply: vp.Reply) -> Version:
    """The fields of a CAM_VersionInq reply; ``ViscaDecodeError`` if it is not one."""
    if not isinstance(reply, vp.Completion) or reply.socket != 0 or len(reply.payload) != 7:
        raise vp.ViscaDecodeError(f"not a version inquiry reply: {reply!r}")
    p = reply.payload
    return Version((p[0] << 8) | p[1], (p[2] << 8) | p[3], (p[4] << 8) | p[5], p[6])


def decode_power(reply: vp.Reply) -> bool:
    """True (on) or False (standby) from a CAM_PowerInq reply."""
    if (
        not isinstance(reply, vp.Completion)
        or reply.socket != 0
        or reply.payload
        not in (
            b"\x02",
            b"\x03",
        )
    ):
        raise vp.ViscaDecodeError(f"not a power inquiry reply: {reply!r}")
    return reply.payload == b"\x02"


# --------------------------------------------------------------------------------------------
# decoding (camera side)


@dataclass(frozen=True, slots=True)
class AddressSetCommand:
    """``88 30 0w FF``: take address ``address`` and pass ``address + 1`` on."""

    address: int


@dataclass(frozen=True, slots=True)
class IfClearCommand:
    """IF_Clear; ``address`` is None for the broadcast form."""

    address: int | None


@dataclass(frozen=True, slots=True)
class CancelCommand:
    address: int
    socket: int


@dataclass(frozen=True, slots=True)
class PowerCommand:
    address: int
    on: bool


@dataclass(frozen=True, slots=True)
class ZoomStopCommand:
    address: int


@dataclass(frozen=True, slots=True)
class ZoomMoveCommand:
    """Tele or wide until stopped; ``speed`` None for the standard speed, else 0..7."""

    address: int
    direction: ZoomDirection
    speed: int | None


@dataclass(frozen=True, slots=True)
class ZoomDirectCommand:
    address: int
    raw: int


@dataclass(frozen=True, slots=True)
class ZoomPositionInquiry:
    address: int


@dataclass(frozen=True, slots=True)
class PowerInquiry:
    address: int


@dataclass(frozen=True, slots=True)
class VersionInquiry:
    address: int


@dataclass(frozen=True, slots=True)
class UnknownCommand:
    """Framed and addressed, but not a command of this set (a camera answers syntax error)."""

    address: int | None
    packet: bytes


Command = (
    AddressSetCommand
    | IfClearCommand
    | CancelCommand
    | PowerCommand
    | ZoomStopCommand
    | ZoomMoveCommand
    | ZoomDirectCommand
    | ZoomPositionInquiry
    | PowerInquiry
    | VersionInquiry
    | PanelCommand
    | UnknownCommand
)
Inquiry = ZoomPositionInquiry | PowerInquiry | VersionInquiry | PanelInquiry
SocketCommand = (
    PowerCommand | ZoomStopCommand | ZoomMoveCommand | ZoomDirectCommand | PanelSocketCommand
)
"""Commands that are executed in a socket (ACK ``y0 4z FF``, then completion or an error)."""

_FIXED: dict[bytes, type] = {
    b"\x01\x04\x07\x00": ZoomStopCommand,
    b"\x09\x04\x47": ZoomPositionInquiry,
    b"\x09\x04\x00": PowerInquiry,
    b"\x09\x00\x02": VersionInquiry,
}


def decode_command(packet: bytes) -> Command:
    """Decode one complete packet sent by a controller (address 0).

    Raises ``ViscaDecodeError`` when the packet is not a controller packet at all (bad framing or
    header); well-framed packets that are not understood come back as :class:`UnknownCommand`.
    """
    if len(packet) < 3 or packet[-1] != vp.TERMINATOR or vp.TERMINATOR in packet[:-1]:
        raise vp.ViscaDecodeError(f"not a VISCA packet: {vp.hex_bytes(packet)}")
    header, body = packet[0], packet[1:-1]
    if header == vp.BROADCAST_HEADER:
        if body[0] == 0x30 and len(body) == 2 and 1 <= body[1] <= 7:
            return AddressSetCommand(body[1])
        if body == b"\x01\x00\x01":
            return IfClearCommand(None)
        return UnknownCommand(None, bytes(packet))
    if header & 0xF0 != 0x80 or not 1 <= header & 0x0F <= 7:
        raise vp.ViscaDecodeError(f"bad command header {header:02X} (expected 81..87, 88)")
    address = header & 0x0F
    return _decode_addressed(address, bytes(body)) or UnknownCommand(address, bytes(packet))


def _decode_addressed(address: int, body: bytes) -> Command | None:
    if body == b"\x01\x00\x01":
        return IfClearCommand(address)
    if len(body) == 1 and body[0] & 0xF0 == 0x20 and 1 <= body[0] & 0x0F <= SOCKETS:
        return CancelCommand(address, body[0] & 0x0F)
    fixed = _FIXED.get(body)
    if fixed is not None:
        return fixed(address)
    if body[:3] == b"\x01\x04\x00" and len(body) == 4 and body[3] in (0x02, 0x03):
        return PowerCommand(address, body[3] == 0x02)
    if body[:3] == b"\x01\x04\x07" and len(body) == 4:
        return _zoom_move(address, body[3])
    if body[:3] == b"\x01\x04\x47" and len(body) == 7:
        try:
            return ZoomDirectCommand(address, vp.from_nibbles(body[3:]))
        except vp.ViscaDecodeError:
            return None
    return decode_panel(address, body)


def _zoom_move(address: int, code: int) -> ZoomMoveCommand | None:
    if code in (0x02, 0x03):
        direction = ZoomDirection.TELE if code == 0x02 else ZoomDirection.WIDE
        return ZoomMoveCommand(address, direction, None)
    kind, speed = code & 0xF0, code & 0x0F
    if kind in (0x20, 0x30) and speed <= MAX_ZOOM_SPEED:
        direction = ZoomDirection.TELE if kind == 0x20 else ZoomDirection.WIDE
        return ZoomMoveCommand(address, direction, speed)
    return None
