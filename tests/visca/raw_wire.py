"""Raw VISCA bytes on a pty, for the tests that drive the simulated camera without a client."""

from __future__ import annotations

import serial

from umbra.modules.calib.visca import protocol as vp


def h(text: str) -> bytes:
    """Bytes from hex written as the manual prints them (``"81 09 04 47 FF"``)."""
    return bytes.fromhex(text)


def read_packet(port: serial.Serial) -> bytes:
    """One packet: the bytes up to and including the terminator ``FF``."""
    return port.read_until(b"\xff")


def position(port: serial.Serial) -> int:
    """The zoom position the camera reports (CAM_ZoomPosInq)."""
    port.write(h("81 09 04 47 FF"))
    return vp.decode_zoom_position(vp.decode_reply(read_packet(port)))
