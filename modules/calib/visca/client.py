"""Client for a Sony FCB zoom camera over VISCA on a serial port (pyserial, 9600 8N1 by default).

All serial traffic happens in one device thread, the only thread here: it sets the address and
clears the interface at start (address set broadcast, then IF_Clear; then, as controllers do,
CAM_PowerInq, power on from standby, and CAM_VersionInq), sends zoom direct commands
and tracks their ACK and completion, sends continuous zoom tele/wide/stop commands, and polls the
zoom position at ``poll_period_s``. Callers never block: :meth:`ViscaZoomClient.zoom_to` stores a
target and :meth:`ViscaZoomClient.zoom_hold` / :meth:`ViscaZoomClient.zoom_stop` a continuous
zoom (one register: the latest request wins), and :meth:`ViscaZoomClient.latest` returns the
latest :class:`ZoomReading`.

A misbehaving camera never raises. Every request waits ``reply_timeout_s`` for its answer and is
sent again up to ``retries`` times; what went wrong is kept in the reading's ``status``:

* ``ok``
* ``starting: ...`` address set and IF_Clear not done yet
* ``no_reply: ...`` the camera said nothing (powered off, cable out, wrong port or baud rate)
* ``garbled: ...`` bytes came back but no reply could be decoded from them (noise, wrong baud)
* ``camera_error: ...`` the camera answered with a VISCA error (syntax, buffer full, ...)
* ``port_error: ...`` the serial port itself failed (USB adapter unplugged); it is reopened

A problem clears as soon as the request that had it succeeds. After ``reinit_after_failures``
consecutive failed requests the client sets the address and clears the interface again (a
camera that lost power forgets its address). Only :meth:`ViscaZoomClient.start` raises:
:class:`umbra.connectors.errors.UserError` when the port cannot be opened.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass, field

import serial

from umbra.connectors.errors import UserError
from umbra.modules.calib.visca import commands as vc
from umbra.modules.calib.visca import protocol as vp
from umbra.modules.calib.visca.client_moves import STOP, Move, MoveSteps
from umbra.modules.calib.visca.client_startup import StartupSteps
from umbra.modules.calib.visca.client_types import (
    LinkStatus,
    Problem,
    RequestFailedError,
    ViscaCounters,
    ViscaSettings,
    ZoomReading,
    is_position_reply,
    status_text,
)
from umbra.modules.calib.visca.client_wire import WireRequests

__all__ = ["LinkStatus", "ViscaCounters", "ViscaSettings", "ViscaZoomClient", "ZoomReading"]


@dataclass
class _State:
    """Everything shared between the device thread and callers (guarded by the client's lock)."""

    target_raw: int | None = None
    target_zoom: float | None = None
    raw: int = -1
    position_time: float = math.nan
    position_changed: bool = False
    inflight_socket: int | None = None
    inflight_raw: int | None = None
    inflight_since: float = 0.0
    commanded_raw: int | None = None
    move_pending: Move | None = None
    move_active: Move | None = None
    lens_started: bool = False
    """A tele/wide was sent and no zoom stop or zoom direct has been acknowledged since: the
    lens may still be moving, and :meth:`ViscaZoomClient.stop` stops it."""
    problems: dict[str, Problem] = field(default_factory=dict)
    ready: bool = False


class ViscaZoomClient:
    """Drive and watch the zoom of one FCB camera on a serial port (see the module docstring)."""

    def __init__(self, settings: ViscaSettings) -> None:
        self.settings = settings
        self.counters = ViscaCounters()
        self._lock = threading.Lock()
        self._state = _State(problems={"init": Problem(LinkStatus.STARTING, "not started")})
        self._serial: serial.Serial | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._wake = threading.Event()
        self._ready_event = threading.Event()
        self._zoom_retry_at = 0.0
        self.version: vc.Version | None = None
        """What CAM_VersionInq reported at the last initialisation (None: not known)."""
        self._wire = WireRequests(self)  #: requests on the line, in the device thread
        self._startup = StartupSteps(self)  #: address set, IF_Clear, power, version
        self._moves = MoveSteps(self)  #: tele / wide / stop

    # -- lifecycle ---------------------------------------------------------------------------

    def start(self) -> None:
        """Open the port and start the device thread. Raises ``UserError`` if the port fails."""
        if self._thread is not None:
            return
        self._serial = self._open_port()
        self._stop.clear()
        self._set_problem("init", LinkStatus.STARTING, "setting address and clearing interface")
        self._thread = threading.Thread(
            target=self._run, name=f"visca-io:{self.settings.port}", daemon=True
        )
        self._thread.start()

    def stop(self) -> None:
        """Stop the device thread, stop a zoom this client started, close the port (idempotent).

        A zoom still running (a tele/wide not yet stopped, or a zoom direct not yet complete) is
        stopped with CAM_Zoom stop (``8x 01 04 07 00 FF``, waiting for its ACK with the usual
        timeout and retries), so the camera does not zoom on after its controller is gone.
        """
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        if self._serial is not None:
            try:
                self._moves.stop_started_zoom()
            finally:
                self._serial.close()
                self._serial = None

    def __enter__(self) -> ViscaZoomClient:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def wait_ready(self, timeout_s: float) -> bool:
        """Block up to ``timeout_s`` until address set and IF_Clear succeeded (for start-up)."""
        return self._ready_event.wait(timeout_s)

    # -- caller side (never blocks on the device) --------------------------------------------

    def zoom_to(self, zoom: float) -> None:
        """Request normalized zoom ``zoom`` (clamped to 0..1); the device thread sends it."""
        raw = vp.zoom_normalized_to_raw(zoom)
        with self._lock:
            self._state.target_raw = raw
            self._state.target_zoom = vp.zoom_raw_to_normalized(raw)
            self._state.move_pending = None  # the latest request wins
        self._wake.set()

    def zoom_hold(self, direction: vc.ZoomDirection, speed: int | None = None) -> None:
        """Zoom toward ``direction`` at variable speed ``speed`` (0..7; None: standard) until
        :meth:`zoom_stop` or another request (sent once, not again while it holds)."""
        if speed is not None and not 0 <= speed <= vc.MAX_ZOOM_SPEED:
            raise ValueError(f"zoom speed must be 0..{vc.MAX_ZOOM_SPEED} or None, got {speed}")
        self._moves.request((direction, speed))

    def zoom_stop(self) -> None:
        """Stop a held zoom (CAM_Zoom stop); retried until the camera takes it."""
        self._moves.request(STOP)

    def latest(self) -> ZoomReading:
        """The latest zoom reading and link status."""
        with self._lock:
            s = self._state
            link, status = status_text(s.problems)
            moving = s.inflight_socket is not None or s.position_changed
            return ZoomReading(
                zoom=vp.zoom_raw_to_normalized(s.raw) if s.raw >= 0 else math.nan,
                raw=s.raw,
                moving=moving,
                target=s.target_zoom,
                status=status,
                link=link,
                ready=s.ready,
                position_time=s.position_time,
            )

    # -- device thread -----------------------------------------------------------------------

    def _open_port(self) -> serial.Serial:
        s = self.settings
        try:
            return serial.Serial(
                port=s.port,
                baudrate=s.baudrate,
                bytesize=serial.EIGHTBITS,
                parity=serial.PARITY_NONE,
                stopbits=serial.STOPBITS_ONE,
                timeout=s.read_slice_s,
                write_timeout=1.0,
            )
        except (serial.SerialException, OSError, ValueError) as exc:
            raise UserError(
                f"cannot open VISCA serial port {s.port!r} at {s.baudrate} baud: {exc} "
                "(expected a serial device such as /dev/ttyUSB0, or 'sim' for the simulated camera)"
            ) from exc

    def _run(self) -> None:
        next_poll = 0.0
        while not self._stop.is_set():
            try:
                if not self._is_ready():
                    if not self._startup.initialise():
                        self._idle(time.monotonic() + self.settings.retry_backoff_s)
                        continue
                    next_poll = 0.0
                self._moves.send_if_needed()
                self._send_zoom_if_needed()
                if time.monotonic() >= next_poll:
                    next_poll = time.monotonic() + self.settings.poll_period_s
                    self._poll_position()
                self._idle(next_poll)
            except (serial.SerialException, OSError) as exc:
                self._port_failed(exc)
            except Exception as exc:  # a bug here must show in the status, not vanish silently
                self._set_problem(
                    "thread",
                    LinkStatus.PORT_ERROR,
                    f"VISCA device thread stopped: {type(exc).__name__}: {exc}",
                )
                with self._lock:
                    self._state.ready = False
                return

    def _is_ready(self) -> bool:
        with self._lock:
            return self._state.ready

    def _send_zoom_if_needed(self) -> None:
        self._check_completion_timeout()
        with self._lock:
            target = self._state.target_raw
            wanted = target is not None and target != self._state.commanded_raw
            old_socket = self._state.inflight_socket
        if not wanted or time.monotonic() < self._zoom_retry_at:
            return
        assert target is not None
        address = self.settings.address

        def ours(error: vp.ErrorReply) -> bool:
            superseded = error.code in (vp.ErrorCode.CANCELLED, vp.ErrorCode.NO_SOCKET)
            return error.address == address and not (superseded and error.socket == old_socket)

        self.counters.zoom_commands += 1
        try:
            ack = self._wire.request(
                vp.encode_zoom_direct(address, target),
                f"zoom direct to raw {target:#06x}",
                lambda r: isinstance(r, vp.Ack) and r.address == address,
                error_filter=ours,
            )
        except RequestFailedError as failure:
            self._zoom_retry_at = time.monotonic() + self.settings.retry_backoff_s
            self._set_problem("zoom", failure.link, failure.detail)
            return
        assert isinstance(ack, vp.Ack)
        with self._lock:
            self._state.move_active = None
            self._state.inflight_socket = ack.socket
            self._state.inflight_raw = target
            self._state.inflight_since = time.monotonic()
            self._state.commanded_raw = target
            self._state.lens_started = False  # the zoom direct replaced a tele/wide
        self._clear_problem("zoom")

    def _check_completion_timeout(self) -> None:
        late_raw: int | None = None
        with self._lock:
            s = self._state
            if (
                s.inflight_socket is not None
                and time.monotonic() - s.inflight_since > self.settings.completion_timeout_s
            ):
                s.inflight_socket = None
                late_raw = s.inflight_raw
        if late_raw is not None:
            self._set_problem(
                "zoom",
                LinkStatus.NO_REPLY,
                f"no completion for zoom direct to raw {late_raw:#06x} within "
                f"{self.settings.completion_timeout_s:.1f} s",
            )

    def _poll_position(self) -> None:
        address = self.settings.address
        self.counters.polls += 1
        try:
            self._wire.request(
                vp.encode_zoom_position_inquiry(address),
                "zoom position inquiry",
                lambda r: is_position_reply(r, address),
                error_filter=lambda e: e.address == address and e.socket == 0,
            )
        except RequestFailedError as failure:
            self._set_problem("poll", failure.link, failure.detail)
            return
        self._clear_problem("poll")

    def _idle(self, until: float) -> None:
        """Read and handle unsolicited replies (completions) until ``until`` or a new target."""
        self._wake.clear()
        while not self._stop.is_set() and time.monotonic() < until:
            self._wire.read_replies()
            if self._wake.is_set():
                return

    # -- requests ----------------------------------------------------------------------------

    def _handle(self, reply: vp.Reply) -> None:
        """Update the shared state from any reply, whichever request is waiting."""
        address = self.settings.address
        if isinstance(reply, vp.NetworkChange):
            with self._lock:
                self._state.ready = False
            return
        if isinstance(reply, vp.AddressSetReply | vp.IfClearBroadcastReply):
            return
        if reply.address != address:
            self.counters.foreign_replies += 1
            return
        now = time.monotonic()
        with self._lock:
            s = self._state
            if is_position_reply(reply, address):
                raw = vp.decode_zoom_position(reply)
                s.position_changed = s.raw >= 0 and raw != s.raw
                s.raw = raw
                s.position_time = now
                if (
                    s.inflight_socket is not None
                    and s.inflight_raw is not None
                    and abs(raw - s.inflight_raw) <= self.settings.arrival_tolerance_raw
                    and not s.position_changed
                ):
                    s.inflight_socket = None
            elif isinstance(reply, vp.Completion) and reply.socket == s.inflight_socket:
                s.inflight_socket = None
                self.counters.zoom_completions += 1
            elif (
                isinstance(reply, vp.ErrorReply)
                and reply.socket != 0
                and reply.socket == s.inflight_socket
            ):
                s.inflight_socket = None

    def _port_failed(self, exc: BaseException) -> None:
        self._set_problem("port", LinkStatus.PORT_ERROR, f"serial port {self.settings.port}: {exc}")
        with self._lock:
            self._state.ready = False
        if self._serial is not None:
            self._serial.close()
        while not self._stop.wait(self.settings.retry_backoff_s):
            try:
                self._serial = self._open_port()
            except UserError:
                continue
            self._wire.drop_partial()
            self._clear_problem("port")
            return

    # -- status ------------------------------------------------------------------------------

    def _set_problem(self, key: str, link: LinkStatus, detail: str) -> None:
        with self._lock:
            self._state.problems[key] = Problem(link, detail)

    def _clear_problem(self, key: str) -> None:
        with self._lock:
            self._state.problems.pop(key, None)
