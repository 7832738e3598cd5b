"""Continuous zoom (tele / wide at a speed, stop) for the VISCA zoom client: the caller's
requests and the device thread's sending (a part that
:class:`~umbra.modules.calib.visca.client.ViscaZoomClient` owns)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import serial

from umbra.modules.calib.visca import commands as vc
from umbra.modules.calib.visca import protocol as vp
from umbra.modules.calib.visca.client_types import LinkStatus, RequestFailedError

if TYPE_CHECKING:
    from umbra.modules.calib.visca.client import ViscaZoomClient


Move = tuple[vc.ZoomDirection | None, int | None]
"""A continuous zoom: (direction, variable speed 0..7 or None for standard); (None, None) stops."""
STOP: Move = (None, None)


class MoveSteps:
    """Tele / wide / stop: the caller's request into the client's shared state, and its sending
    through the client's wire by the device thread."""

    def __init__(self, client: ViscaZoomClient) -> None:
        self._c = client

    def request(self, move: Move) -> None:
        """Store ``move`` as the latest request (it replaces a zoom target) and wake the thread;
        the move already active and not superseded is not stored again."""
        with self._c._lock:
            s = self._c._state
            if s.move_pending is None and s.move_active == move and s.target_raw is None:
                return
            s.move_pending = move
            s.target_raw = s.commanded_raw = None  # a later zoom_to is sent even if unchanged
            s.target_zoom = None
        self._c._wake.set()

    def send_if_needed(self) -> None:
        """Send the pending tele/wide/stop; a stop that fails is tried again (dead-man)."""
        with self._c._lock:
            move = self._c._state.move_pending
            self._c._state.move_pending = None
            if move is not None:  # taken: the same request again while it is sent is no news
                self._c._state.move_active = move
                if move != STOP:  # the camera may take it even if its ACK is lost
                    self._c._state.lens_started = True
            old_socket = self._c._state.inflight_socket
        if move is None:
            return
        address = self._c.settings.address
        direction, speed = move
        if direction is None:
            packet, what = vc.encode_zoom_stop(address), "zoom stop"
        else:
            packet = vc.encode_zoom_move(address, direction, speed)
            what = f"zoom {direction.value} at speed {'standard' if speed is None else speed}"

        def ours(error: vp.ErrorReply) -> bool:
            superseded = error.code in (vp.ErrorCode.CANCELLED, vp.ErrorCode.NO_SOCKET)
            return error.address == address and not (superseded and error.socket == old_socket)

        self._c.counters.zoom_moves += 1
        try:
            self._c._wire.request(
                packet, what, lambda r: isinstance(r, vp.Ack) and r.address == address, ours
            )
        except RequestFailedError as failure:
            self._c._set_problem("zoom", failure.link, failure.detail)
            with self._c._lock:
                if self._c._state.move_active == move:
                    self._c._state.move_active = None
                latest = self._c._state.move_pending is None and self._c._state.target_raw is None
                if move == STOP and latest:
                    self._c._state.move_pending = STOP
            return
        if move == STOP:
            with self._c._lock:
                self._c._state.lens_started = False
        self._c._clear_problem("zoom")

    def stop_started_zoom(self) -> None:
        """At the client's stop (device thread ended, port open): send CAM_Zoom stop if a zoom
        this client started may still run; its failure is counted, never raised."""
        with self._c._lock:
            running = self._c._state.lens_started or self._c._state.inflight_socket is not None
        if not running:
            return
        address = self._c.settings.address
        self._c.counters.end_stops += 1
        acked: list[int] = []

        def ack_then_completion(reply: vp.Reply) -> bool:
            """The stop's ACK, then its completion: no reply of it is left on the line."""
            if isinstance(reply, vp.Ack) and reply.address == address:
                acked.append(reply.socket)
                return False
            return (
                isinstance(reply, vp.Completion)
                and reply.address == address
                and bool(acked)
                and reply.socket == acked[-1]
            )

        def refused(error: vp.ErrorReply) -> bool:  # not the cancel of a running zoom direct
            return error.address == address and (
                error.socket == 0 or error.code is vp.ErrorCode.NOT_EXECUTABLE
            )

        try:
            self._c._wire.request(
                vc.encode_zoom_stop(address),
                "zoom stop at the end",
                ack_then_completion,
                refused,
                stoppable=False,
            )
        except (RequestFailedError, serial.SerialException, OSError) as failure:
            link = (
                failure.link if isinstance(failure, RequestFailedError) else LinkStatus.PORT_ERROR
            )
            self._c._set_problem("zoom", link, f"zoom stop at the end: {failure}")
            self._c.counters.end_stop_failures += 1
            return
        with self._c._lock:
            self._c._state.lens_started = False
            self._c._state.inflight_socket = None
