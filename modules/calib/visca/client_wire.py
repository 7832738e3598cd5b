"""Requests on the VISCA line: send, wait for the answer among unsolicited replies, retry, and
say what went wrong (a part that :class:`~umbra.modules.calib.visca.client.ViscaZoomClient`
owns)."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

from umbra.modules.calib.visca import protocol as vp
from umbra.modules.calib.visca.client_types import (
    LinkStatus,
    RequestFailedError,
)

if TYPE_CHECKING:
    from umbra.modules.calib.visca.client import ViscaZoomClient


class WireRequests:
    """Sending packets and reading replies, in the device thread: reads the client's settings,
    stop event, port and shared state, counts in its counters and hands every reply to it;
    keeps the packet splitter and the count of consecutive failed requests."""

    def __init__(self, client: ViscaZoomClient) -> None:
        self._c = client
        self._splitter = vp.PacketSplitter()
        self._consecutive_failures = 0

    def drop_partial(self) -> None:
        """Forget half a packet read before the port failed (a new splitter)."""
        self._splitter = vp.PacketSplitter()

    def request(
        self,
        packet: bytes,
        what: str,
        accept: Callable[[vp.Reply], bool],
        error_filter: Callable[[vp.ErrorReply], bool] | None = None,
        stoppable: bool = True,
    ) -> vp.Reply:
        """Send ``packet`` until a reply passes ``accept``; raise ``RequestFailedError`` if none.

        ``error_filter`` says which error replies answer this request (others are stale).
        A ``stoppable`` request gives up as soon as the client is stopping; the last request of
        a stopping client (its zoom stop) is not stoppable.
        """
        s = self._c.settings
        stopping = self._c._stop if stoppable else threading.Event()
        tries = 1 + s.retries
        last: RequestFailedError | None = None
        for attempt in range(tries):
            if attempt:
                self._c.counters.retries += 1
            garbled_before = self.garbled_total()
            self.write(packet)
            deadline = time.monotonic() + s.reply_timeout_s
            answer: vp.Reply | None = None
            while answer is None and time.monotonic() < deadline and not stopping.is_set():
                for reply in self.read_replies():
                    if accept(reply):
                        answer = reply
                        break
                    if isinstance(reply, vp.ErrorReply) and error_filter and error_filter(reply):
                        answer = reply
                        break
            if answer is not None and not isinstance(answer, vp.ErrorReply):
                self._consecutive_failures = 0
                return answer
            if isinstance(answer, vp.ErrorReply):
                self._c.counters.camera_errors += 1
                last = RequestFailedError(
                    LinkStatus.CAMERA_ERROR,
                    f"camera answered {what} ({vp.hex_bytes(packet)}) with "
                    f"{answer.description} (error {int(answer.code):02X}, socket {answer.socket})",
                )
                if answer.code is vp.ErrorCode.BUFFER_FULL:
                    stopping.wait(s.reply_timeout_s)
            elif self.garbled_total() > garbled_before:
                self._c.counters.timeouts += 1
                last = RequestFailedError(
                    LinkStatus.GARBLED,
                    f"unreadable reply to {what} ({vp.hex_bytes(packet)}) on {s.port}",
                )
            else:
                self._c.counters.timeouts += 1
                last = RequestFailedError(
                    LinkStatus.NO_REPLY,
                    f"no reply to {what} ({vp.hex_bytes(packet)}) on {s.port} "
                    f"within {s.reply_timeout_s:.2f} s",
                )
            if stopping.is_set():
                break
        assert last is not None
        last = RequestFailedError(last.link, f"{last.detail} ({tries} tries)")
        self._consecutive_failures += 1
        if self._consecutive_failures >= s.reinit_after_failures:
            self._consecutive_failures = 0
            with self._c._lock:
                self._c._state.ready = False
        raise last

    def write(self, packet: bytes) -> None:
        assert self._c._serial is not None
        self._c._serial.write(packet)
        self._c.counters.packets_sent += 1

    def read_replies(self) -> list[vp.Reply]:
        """Read what the port has (waiting at most one read slice), decode and handle it."""
        assert self._c._serial is not None
        data = self._c._serial.read(max(1, self._c._serial.in_waiting))
        replies: list[vp.Reply] = []
        errors_before = self._splitter.errors
        packets = self._splitter.feed(data)
        self._c.counters.garbled += self._splitter.errors - errors_before
        for packet in packets:
            try:
                reply = vp.decode_reply(packet)
            except vp.ViscaDecodeError:
                self._c.counters.garbled += 1
                continue
            self._c.counters.replies += 1
            self._c._handle(reply)
            replies.append(reply)
        return replies

    def garbled_total(self) -> int:
        return self._c.counters.garbled
