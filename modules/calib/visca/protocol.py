"""VISCA framing for a Sony FCB block camera: encode commands, decode replies, split a byte stream.

Pure functions and small value types, no I/O. Byte layouts follow Sony's FCB technical manuals:

==========================  ==================================  ===========================
message                     controller -> camera                camera -> controller
==========================  ==================================  ===========================
Address set (broadcast)     ``88 30 01 FF``                     ``88 30 0w FF`` (w = n + 1)
IF_Clear (broadcast)        ``88 01 00 01 FF``                  ``88 01 00 01 FF`` (echoed)
IF_Clear                    ``8x 01 00 01 FF``                  ``y0 50 FF``
CAM_Zoom direct             ``8x 01 04 47 0p 0q 0r 0s FF``      ACK then completion
CAM_ZoomPosInq              ``8x 09 04 47 FF``                  ``y0 50 0p 0q 0r 0s FF``
ACK                                                             ``y0 4z FF``
Completion                                                      ``y0 5z FF``
Error                                                           ``y0 6z ee FF``
Network change                                                  ``y0 38 FF``
==========================  ==================================  ===========================

The rest of the FCB command set a controller sends (zoom tele/wide/stop, power, version, cancel)
and the decoding of controller packets are in :mod:`umbra.modules.calib.visca.commands`.

``x`` is the camera address (1..7), ``y = x + 8`` (so camera 1 answers with ``90``), ``z`` the
socket number (1 or 2 for commands, 0 for inquiries and interface commands), ``pqrs`` a 16-bit
value sent one nibble per byte, ``ee`` the error code (:class:`ErrorCode`).

Zoom positions: on the FCB cameras the optical zoom range is raw ``0x0000`` (full wide) to
``0x4000`` (full optical tele); values above ``0x4000`` (up to ``0x7AC0`` on the EX series, less
on older models such as the FCB-IX10A) select digital zoom, which crops and upsamples the image
and is not part of a calibrated optical model. Normalized zoom 0..1 (0 = full wide, 1 = full
zoom, as in the calibration file of the Sandia report, Appendix D) therefore maps linearly onto
the optical range 0x0000..0x4000 and is clamped at both ends.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

TERMINATOR = 0xFF
MAX_PACKET_LENGTH = 16
"""Longest VISCA packet in bytes, header and terminator included."""

BROADCAST_HEADER = 0x88
ZOOM_RAW_WIDE = 0x0000
ZOOM_RAW_OPTICAL_TELE = 0x4000
"""Raw zoom position of full optical tele on the FCB cameras (normalized zoom 1.0)."""
ZOOM_RAW_MAX = 0xFFFF
"""Largest value a four-nibble field can carry."""


class ViscaDecodeError(ValueError):
    """A packet that is framed (ends in FF) but is not a reply this decoder understands."""


class ErrorCode(enum.IntEnum):
    """Error codes of the VISCA error reply ``y0 6z ee FF``."""

    MESSAGE_LENGTH = 0x01
    SYNTAX = 0x02
    BUFFER_FULL = 0x03
    CANCELLED = 0x04
    NO_SOCKET = 0x05
    NOT_EXECUTABLE = 0x41

    @property
    def description(self) -> str:
        """Human-readable meaning, as worded in Sony's manuals."""
        return _ERROR_DESCRIPTIONS[self]


_ERROR_DESCRIPTIONS = {
    ErrorCode.MESSAGE_LENGTH: "message length error",
    ErrorCode.SYNTAX: "syntax error",
    ErrorCode.BUFFER_FULL: "command buffer full",
    ErrorCode.CANCELLED: "command cancelled",
    ErrorCode.NO_SOCKET: "no socket",
    ErrorCode.NOT_EXECUTABLE: "command not executable",
}


# --------------------------------------------------------------------------------------------
# zoom scaling


def zoom_normalized_to_raw(zoom: float) -> int:
    """Raw FCB zoom position for a normalized zoom (0 = full wide, 1 = full optical tele).

    The input is clamped to [0, 1]; NaN is rejected with ``ValueError``.
    """
    if zoom != zoom:
        raise ValueError("normalized zoom is NaN; expected a number in [0, 1]")
    clamped = min(1.0, max(0.0, float(zoom)))
    return round(ZOOM_RAW_WIDE + clamped * (ZOOM_RAW_OPTICAL_TELE - ZOOM_RAW_WIDE))


def zoom_raw_to_normalized(raw: int) -> float:
    """Normalized zoom in [0, 1] for a raw FCB zoom position (digital zoom clamps to 1)."""
    span = ZOOM_RAW_OPTICAL_TELE - ZOOM_RAW_WIDE
    return min(1.0, max(0.0, (int(raw) - ZOOM_RAW_WIDE) / span))


# --------------------------------------------------------------------------------------------
# encoding


def _check_address(address: int) -> None:
    if not 1 <= address <= 7:
        raise ValueError(f"VISCA camera address must be 1..7, got {address}")


def command_header(address: int) -> int:
    """First byte of a packet from the controller (address 0) to camera ``address``."""
    _check_address(address)
    return 0x80 | address


def reply_header(address: int) -> int:
    """First byte of a reply from camera ``address`` (``y0`` with y = address + 8)."""
    _check_address(address)
    return (address + 8) << 4


def nibbles(value: int) -> bytes:
    """A 16-bit value as four bytes ``0p 0q 0r 0s``, most significant nibble first."""
    if not 0 <= value <= 0xFFFF:
        raise ValueError(f"VISCA four-nibble field must be 0..0xFFFF, got {value}")
    return bytes(((value >> 12) & 0xF, (value >> 8) & 0xF, (value >> 4) & 0xF, value & 0xF))


def from_nibbles(field: bytes) -> int:
    """Inverse of :func:`nibbles`; ``ViscaDecodeError`` if a byte is not a nibble."""
    if len(field) != 4 or any(b > 0x0F for b in field):
        raise ViscaDecodeError(f"expected four nibble bytes 0p 0q 0r 0s, got {hex_bytes(field)}")
    return (field[0] << 12) | (field[1] << 8) | (field[2] << 4) | field[3]


def encode_address_set() -> bytes:
    """Address set broadcast ``88 30 01 FF``: the first camera on the chain takes address 1."""
    return bytes((BROADCAST_HEADER, 0x30, 0x01, TERMINATOR))


def encode_if_clear_broadcast() -> bytes:
    """IF_Clear broadcast ``88 01 00 01 FF`` (every camera echoes it)."""
    return bytes((BROADCAST_HEADER, 0x01, 0x00, 0x01, TERMINATOR))


def encode_if_clear(address: int) -> bytes:
    """IF_Clear to one camera ``8x 01 00 01 FF``: clears its buffers, cancels running commands."""
    return bytes((command_header(address), 0x01, 0x00, 0x01, TERMINATOR))


def encode_zoom_direct(address: int, raw: int) -> bytes:
    """CAM_Zoom direct ``8x 01 04 47 0p 0q 0r 0s FF`` to raw position ``raw``."""
    return bytes((command_header(address), 0x01, 0x04, 0x47)) + nibbles(raw) + b"\xff"


def encode_zoom_position_inquiry(address: int) -> bytes:
    """CAM_ZoomPosInq ``8x 09 04 47 FF``."""
    return bytes((command_header(address), 0x09, 0x04, 0x47, TERMINATOR))


def encode_ack(address: int, socket: int) -> bytes:
    """ACK ``y0 4z FF`` (camera side, used by the simulator)."""
    return bytes((reply_header(address), 0x40 | _socket(socket), TERMINATOR))


def encode_completion(address: int, socket: int, payload: bytes = b"") -> bytes:
    """Completion ``y0 5z [payload] FF`` (camera side)."""
    return bytes((reply_header(address), 0x50 | _socket(socket))) + payload + b"\xff"


def encode_error(address: int, socket: int, code: ErrorCode) -> bytes:
    """Error ``y0 6z ee FF`` (camera side)."""
    return bytes((reply_header(address), 0x60 | _socket(socket), int(code), TERMINATOR))


def encode_zoom_position_reply(address: int, raw: int) -> bytes:
    """Zoom position inquiry reply ``y0 50 0p 0q 0r 0s FF`` (camera side)."""
    return encode_completion(address, 0, nibbles(raw))


def encode_address_set_reply(next_address: int) -> bytes:
    """Address set reply ``88 30 0w FF``: w is one more than the last address taken."""
    if not 2 <= next_address <= 8:
        raise ValueError(f"address set reply carries 2..8, got {next_address}")
    return bytes((BROADCAST_HEADER, 0x30, next_address, TERMINATOR))


def _socket(socket: int) -> int:
    if not 0 <= socket <= 0xF:
        raise ValueError(f"VISCA socket must be 0..15, got {socket}")
    return socket


def hex_bytes(data: bytes) -> str:
    """``b'\\x90A\\xff'`` -> ``'90 41 FF'`` for messages and logs."""
    return " ".join(f"{b:02X}" for b in data)


# --------------------------------------------------------------------------------------------
# decoding replies (camera -> controller)


@dataclass(frozen=True, slots=True)
class AddressSetReply:
    """``88 30 0w FF``: ``next_address - 1`` cameras took addresses 1..next_address-1."""

    next_address: int

    @property
    def camera_count(self) -> int:
        return self.next_address - 1


@dataclass(frozen=True, slots=True)
class IfClearBroadcastReply:
    """``88 01 00 01 FF`` echoed back by the chain."""


@dataclass(frozen=True, slots=True)
class Ack:
    """``y0 4z FF``: command accepted into socket ``socket``."""

    address: int
    socket: int


@dataclass(frozen=True, slots=True)
class Completion:
    """``y0 5z [payload] FF``: command in ``socket`` done, or inquiry answered (socket 0)."""

    address: int
    socket: int
    payload: bytes = b""


@dataclass(frozen=True, slots=True)
class ErrorReply:
    """``y0 6z ee FF``."""

    address: int
    socket: int
    code: ErrorCode

    @property
    def description(self) -> str:
        return self.code.description


@dataclass(frozen=True, slots=True)
class NetworkChange:
    """``y0 38 FF``: a device joined or left the chain; addresses must be set again."""

    address: int


Reply = AddressSetReply | IfClearBroadcastReply | Ack | Completion | ErrorReply | NetworkChange


def decode_reply(packet: bytes) -> Reply:
    """Decode one complete reply packet (terminator included).

    Raises ``ViscaDecodeError`` naming the bytes when the packet is not a known reply.
    """
    if len(packet) < 3 or packet[-1] != TERMINATOR:
        raise ViscaDecodeError(
            f"not a VISCA packet (need >= 3 bytes ending FF): {hex_bytes(packet)}"
        )
    if len(packet) > MAX_PACKET_LENGTH:
        raise ViscaDecodeError(f"packet longer than {MAX_PACKET_LENGTH} bytes: {hex_bytes(packet)}")
    if TERMINATOR in packet[:-1]:
        raise ViscaDecodeError(f"terminator FF inside packet: {hex_bytes(packet)}")
    header, kind, body = packet[0], packet[1], packet[2:-1]
    if header == BROADCAST_HEADER:
        return _decode_broadcast(packet, kind, body)
    address = (header >> 4) - 8
    if header & 0x0F or not 1 <= address <= 7:
        raise ViscaDecodeError(
            f"bad reply header {header:02X} (expected 90..F0): {hex_bytes(packet)}"
        )
    message, socket = kind & 0xF0, kind & 0x0F
    if message == 0x40 and not body:
        return Ack(address, socket)
    if message == 0x50:
        return Completion(address, socket, bytes(body))
    if message == 0x60 and len(body) == 1:
        try:
            return ErrorReply(address, socket, ErrorCode(body[0]))
        except ValueError:
            raise ViscaDecodeError(
                f"unknown error code {body[0]:02X}: {hex_bytes(packet)}"
            ) from None
    if kind == 0x38 and not body:
        return NetworkChange(address)
    raise ViscaDecodeError(f"unknown reply: {hex_bytes(packet)}")


def _decode_broadcast(packet: bytes, kind: int, body: bytes) -> Reply:
    if kind == 0x30 and len(body) == 1 and 2 <= body[0] <= 8:
        return AddressSetReply(body[0])
    if kind == 0x01 and body == b"\x00\x01":
        return IfClearBroadcastReply()
    raise ViscaDecodeError(f"unknown broadcast reply: {hex_bytes(packet)}")


def decode_zoom_position(reply: Reply) -> int:
    """Raw zoom position from a zoom-position inquiry reply ``y0 50 0p 0q 0r 0s FF``."""
    if not isinstance(reply, Completion) or reply.socket != 0 or len(reply.payload) != 4:
        raise ViscaDecodeError(f"not a zoom position reply: {reply!r}")
    return from_nibbles(reply.payload)


# --------------------------------------------------------------------------------------------
# stream splitting


class PacketSplitter:
    """Cut a serial byte stream into VISCA packets at FF terminators, surviving garbage.

    ``feed(data)`` returns the complete packets found so far (each ending in FF). Resynchronising
    rules, each counted in ``errors`` (bytes thrown away in ``discarded_bytes``):

    * A packet starts at a header byte (bit 7 set, not FF). Every payload byte of the replies and
      commands handled here is 7-bit, so within the bytes before a terminator the *last* header
      byte starts the packet and anything before it is garbage (for example the tail of a packet
      whose terminator was lost on the line).
    * A run before a terminator with no header byte, or a lone terminator, is garbage.
    * More than ``MAX_PACKET_LENGTH - 1`` bytes without a terminator: everything before the last
      header byte is garbage (or all of it when that header opened the over-long run).
    """

    def __init__(self) -> None:
        self._buffer = bytearray()
        self.errors = 0
        self.discarded_bytes = 0
        self.packets = 0

    def feed(self, data: bytes) -> list[bytes]:
        packets: list[bytes] = []
        for byte in data:
            if byte == TERMINATOR:
                packet = self._take_packet()
                if packet is not None:
                    packets.append(packet)
                continue
            self._buffer.append(byte)
            if len(self._buffer) >= MAX_PACKET_LENGTH:
                self._drop_overflow()
        return packets

    def _drop_overflow(self) -> None:
        """Too long for a packet: keep only a header that may still start a valid packet."""
        start = _last_header_index(self._buffer)
        keep = 0 if start is None or start == 0 else len(self._buffer) - start
        self._discard(len(self._buffer) - keep)
        del self._buffer[: len(self._buffer) - keep]

    def _take_packet(self) -> bytes | None:
        chunk = bytes(self._buffer)
        self._buffer.clear()
        start = _last_header_index(chunk)
        if start is None or len(chunk) - start < 2:
            self._discard(len(chunk) + 1)
            return None
        if start > 0:
            self._discard(start)
        self.packets += 1
        return chunk[start:] + b"\xff"

    def _discard(self, count: int) -> None:
        self.errors += 1
        self.discarded_bytes += count

    @property
    def pending(self) -> int:
        """Bytes waiting for a terminator."""
        return len(self._buffer)


def _last_header_index(chunk: bytes | bytearray) -> int | None:
    for index in range(len(chunk) - 1, -1, -1):
        if chunk[index] & 0x80:
            return index
    return None
