"""Start-up of the VISCA zoom client's device thread: address set, IF_Clear, power and version
(a part that :class:`~umbra.modules.calib.visca.client.ViscaZoomClient` owns)."""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

from umbra.modules.calib.visca import commands as vc
from umbra.modules.calib.visca import protocol as vp
from umbra.modules.calib.visca.client_types import (
    LinkStatus,
    RequestFailedError,
    is_empty_completion,
    is_power_reply,
)

if TYPE_CHECKING:
    from umbra.modules.calib.visca.client import ViscaZoomClient


class StartupSteps:
    """What the device thread does before the camera is ready: requests through the client's
    wire, then marks the client's shared state ready and keeps the camera's version in it."""

    def __init__(self, client: ViscaZoomClient) -> None:
        self._c = client

    def initialise(self) -> bool:
        """Address set, IF_Clear, power and version; False (and the problem set) on a failure."""
        address = self._c.settings.address
        try:
            reply = self._c._wire.request(
                vp.encode_address_set(),
                "address set",
                lambda r: isinstance(r, vp.AddressSetReply),
            )
            assert isinstance(reply, vp.AddressSetReply)
            if reply.camera_count < address:
                raise RequestFailedError(
                    LinkStatus.CAMERA_ERROR,
                    f"address set found {reply.camera_count} camera(s) on {self._c.settings.port}, "
                    f"but the configured address is {address}",
                )
            self._c._wire.request(
                vp.encode_if_clear(address),
                "IF_Clear",
                lambda r: is_empty_completion(r, address),
                error_filter=lambda e: e.address == address and e.socket == 0,
            )
            self._power_up_and_identify(address)
        except RequestFailedError as failure:
            self._c._set_problem("init", failure.link, failure.detail)
            return False
        self._c.counters.initialisations += 1
        with self._c._lock:
            self._c._state.ready = True
            self._c._state.inflight_socket = None
            self._c._state.commanded_raw = None
        self._c._clear_problem("init")
        self._c._ready_event.set()
        return True

    def _power_up_and_identify(self, address: int) -> None:
        """As controllers do at start: CAM_PowerInq, power on from standby (waiting for its
        completion), then CAM_VersionInq (kept in the client's ``version``; a camera without it
        is fine)."""

        def at_zero(error: vp.ErrorReply) -> bool:
            return error.address == address and error.socket == 0

        reply = self._c._wire.request(
            vc.encode_power_inquiry(address),
            "power inquiry",
            lambda r: is_power_reply(r, address),
            error_filter=at_zero,
        )
        if not vc.decode_power(reply):
            ack = self._c._wire.request(
                vc.encode_power(address, True),
                "power on",
                lambda r: isinstance(r, vp.Ack) and r.address == address,
                error_filter=lambda e: e.address == address,
            )
            assert isinstance(ack, vp.Ack)
            self._c.counters.power_ons += 1
            self._await_completion(address, ack.socket, "power on")
        try:
            version = self._c._wire.request(
                vc.encode_version_inquiry(address),
                "version inquiry",
                lambda r: (
                    isinstance(r, vp.Completion)
                    and r.address == address
                    and r.socket == 0
                    and len(r.payload) == 7
                ),
                error_filter=at_zero,
            )
        except RequestFailedError as failure:
            if failure.link is not LinkStatus.CAMERA_ERROR:
                raise
            return
        self._c.version = vc.decode_version(version)

    def _await_completion(self, address: int, socket: int, what: str) -> None:
        """Read replies until the completion of ``what`` in ``socket`` (or its error)."""
        deadline = time.monotonic() + self._c.settings.completion_timeout_s
        while time.monotonic() < deadline and not self._c._stop.is_set():
            for reply in self._c._wire.read_replies():
                if isinstance(reply, vp.Completion | vp.ErrorReply) and (
                    reply.address == address and reply.socket == socket
                ):
                    if isinstance(reply, vp.ErrorReply):
                        raise RequestFailedError(
                            LinkStatus.CAMERA_ERROR, f"{what} ended with {reply.description}"
                        )
                    return
        raise RequestFailedError(
            LinkStatus.NO_REPLY,
            f"no completion for {what} within {self._c.settings.completion_timeout_s:.1f} s",
        )
