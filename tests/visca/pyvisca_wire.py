"""Reading the simulated camera's replies through pyvisca's own reader, for the conformance tests
that drive it with pyvisca (an independent VISCA library from PyPI)."""

from __future__ import annotations

import time

from umbra.modules.calib.visca import protocol as vp


def replies(ptz: object, count: int, timeout_s: float = 5.0) -> list[str]:
    """The next ``count`` reply packets as lower-case hex text (``"9041ff"``), read with
    pyvisca's ``read`` and split at the terminator byte (not at an "ff" inside the text)."""
    data, deadline = b"", time.monotonic() + timeout_s
    while data.count(vp.TERMINATOR) < count and time.monotonic() < deadline:
        data += bytes.fromhex(ptz.read())  # type: ignore[attr-defined]
        time.sleep(0.01)
    return [(p + b"\xff").hex() for p in data.split(b"\xff") if p][:count]


def inquire(ptz: object, packet: str) -> bytes:
    """Send an inquiry with pyvisca's ``inq`` and return its reply's payload (``y0 50 .. FF``)."""
    reply = vp.decode_reply(bytes.fromhex(ptz.inq(packet)))  # type: ignore[attr-defined]
    assert isinstance(reply, vp.Completion) and reply.socket == 0, reply
    return reply.payload
