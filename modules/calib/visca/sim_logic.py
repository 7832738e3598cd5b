"""What a simulated FCB camera does with each command: sockets, power, the lens, and the replies.

Pure state, no I/O and no threads: :class:`FcbLogic` takes decoded commands with the time they are
executed and returns the reply packets; :meth:`FcbLogic.due` returns the completions that fall due
(a zoom direct arriving, power-on finished). Times are ``time.monotonic()`` seconds. The wire,
the command buffer and injected faults are :mod:`umbra.modules.calib.visca.sim_camera`'s.

Sockets: a command that runs on after its ACK (zoom direct until the lens arrives, power on while
the camera starts) holds socket 1 or 2 until its completion. Zoom tele/wide/stop and power off
complete at once. A new lens command takes the free socket and ends a running zoom direct with
"command cancelled" (``y0 6z 04 FF``) in that one's socket; ``8x 2z FF`` cancels socket z (or
answers "no socket", ``05``, when nothing runs there). With both sockets busy a command gets
"command buffer full" (``y0 60 03 FF``). In standby (power off) or while starting, lens commands
get "command not executable" (``y0 6z 41 FF``, z the socket they would have taken); inquiries,
power, cancel and IF_Clear are always answered. Unknown packets get "syntax error" (``02``).
"""

from __future__ import annotations

from dataclasses import dataclass

from umbra.modules.calib.visca import commands as vc
from umbra.modules.calib.visca import protocol as vp
from umbra.modules.calib.visca.zoom_motion import Motion, ZoomSpeeds


@dataclass
class _Running:
    """A command holding a socket until ``until`` [s] (zoom direct: its arrival)."""

    kind: str  # "zoom" or "power"
    until: float


class FcbLogic:
    """State of one simulated FCB camera (see the module docstring).

    ``max_raw`` is the tele end of the lens (raw units); ``speeds`` its travel times;
    ``power_on_s`` [s] how long power-on takes; ``model`` and ``rom`` what CAM_VersionInq
    reports (the defaults claim no real model: code 0x0000).
    """

    def __init__(
        self,
        speeds: ZoomSpeeds,
        max_raw: int = vp.ZOOM_RAW_OPTICAL_TELE,
        initial_raw: int = 0,
        address: int = 1,
        power_on_s: float = 0.5,
        model: int = 0x0000,
        rom: int = 0x0100,
    ) -> None:
        self.speeds = speeds
        self.max_raw = max_raw
        self.power_on_s = power_on_s
        self.model, self.rom = model, rom
        self.address = address
        self.powered = True
        self.motion = Motion(initial_raw, initial_raw, 0.0, self._rate(speeds.direct_s))
        self._running: dict[int, _Running] = {}
        self.cancelled = 0

    def _rate(self, full_range_s: float) -> float:
        return self.max_raw / full_range_s

    # -- queries -----------------------------------------------------------------------------

    def position(self, now: float) -> int:
        return self.motion.position(now)

    def busy_sockets(self) -> list[int]:
        return sorted(self._running)

    def next_due(self) -> float | None:
        """When the next completion falls due (None: nothing runs)."""
        return min((r.until for r in self._running.values()), default=None)

    # -- commands ----------------------------------------------------------------------------

    def execute(self, command: vc.Command, now: float) -> list[bytes]:
        """Replies to ``command`` (addressed to this camera, or broadcast) executed at ``now``."""
        a = self.address
        if isinstance(command, vc.AddressSetCommand):
            self.address = command.address
            return [vp.encode_address_set_reply(command.address + 1)]
        if isinstance(command, vc.IfClearCommand):
            self.clear(now)
            if command.address is None:
                return [vp.encode_if_clear_broadcast()]
            return [vp.encode_completion(a, 0)]
        if isinstance(command, vc.ZoomPositionInquiry):
            return [vp.encode_zoom_position_reply(a, self.motion.position(now))]
        if isinstance(command, vc.PowerInquiry):
            return [vc.encode_power_reply(a, self.powered)]
        if isinstance(command, vc.VersionInquiry):
            return [vc.encode_version_reply(a, self.model, self.rom)]
        if isinstance(command, vc.CancelCommand):
            return self._cancel(command.socket, now)
        if isinstance(command, vc.PowerCommand):
            return self._power(command.on, now)
        if isinstance(command, vc.ZoomStopCommand | vc.ZoomMoveCommand | vc.ZoomDirectCommand):
            return self._lens(command, now)
        return [vp.encode_error(a, 0, vp.ErrorCode.SYNTAX)]

    def clear(self, now: float) -> None:
        """IF_Clear: stop the lens, forget running commands (they get no reply)."""
        self.motion = self.motion.stopped(now)
        if "power" in (r.kind for r in self._running.values()):
            self.powered = True  # the start-up itself goes on; only its completion is dropped
        self._running.clear()

    def due(self, now: float) -> list[bytes]:
        """Completions of running commands whose time has come."""
        replies = []
        for socket, running in sorted(self._running.items()):
            if now >= running.until:
                del self._running[socket]
                replies.append(vp.encode_completion(self.address, socket))
        return replies

    def _free_socket(self) -> int | None:
        return next((s for s in range(1, vc.SOCKETS + 1) if s not in self._running), None)

    def _zoom_socket(self) -> int | None:
        return next((s for s, r in self._running.items() if r.kind == "zoom"), None)

    def _cancel(self, socket: int, now: float) -> list[bytes]:
        running = self._running.pop(socket, None)
        if running is None:
            return [vp.encode_error(self.address, socket, vp.ErrorCode.NO_SOCKET)]
        if running.kind == "zoom":
            self.motion = self.motion.stopped(now)
        self.cancelled += 1
        return [vp.encode_error(self.address, socket, vp.ErrorCode.CANCELLED)]

    def _power(self, on: bool, now: float) -> list[bytes]:
        a, socket = self.address, self._free_socket()
        if socket is None:
            return [vp.encode_error(a, 0, vp.ErrorCode.BUFFER_FULL)]
        replies = [vp.encode_ack(a, socket)]
        if on and not self.powered:
            self._running[socket] = _Running("power", now + self.power_on_s)
            self.powered = True
            return replies
        if not on:
            self.powered = False
            self.motion = self.motion.stopped(now)
            for other in [s for s, r in self._running.items() if r.kind == "zoom"]:
                del self._running[other]
                self.cancelled += 1
                replies.append(vp.encode_error(a, other, vp.ErrorCode.CANCELLED))
        return [*replies, vp.encode_completion(a, socket)]

    def _lens(self, command: vc.Command, now: float) -> list[bytes]:
        a = self.address
        old = self._zoom_socket()
        socket = self._free_socket()
        if socket is None:
            return [vp.encode_error(a, 0, vp.ErrorCode.BUFFER_FULL)]
        if not self.powered or "power" in (r.kind for r in self._running.values()):
            return [vp.encode_error(a, socket, vp.ErrorCode.NOT_EXECUTABLE)]
        replies = [vp.encode_ack(a, socket)]
        if old is not None:  # the new lens command replaces the running zoom direct
            del self._running[old]
            self.cancelled += 1
            replies.append(vp.encode_error(a, old, vp.ErrorCode.CANCELLED))
        here = self.motion.position(now)
        if isinstance(command, vc.ZoomDirectCommand):
            target = min(command.raw, self.max_raw)
            self.motion = Motion(here, target, now, self._rate(self.speeds.direct_s))
            self._running[socket] = _Running("zoom", self.motion.arrival())
            return replies
        if isinstance(command, vc.ZoomMoveCommand):
            end = self.max_raw if command.direction is vc.ZoomDirection.TELE else 0
            rate = self._rate(self.speeds.seconds(command.speed))
            self.motion = Motion(here, end, now, rate)
        else:
            self.motion = self.motion.stopped(now)
        return [*replies, vp.encode_completion(a, socket)]
