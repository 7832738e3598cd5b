"""What a simulated FCB camera does with each command: sockets, power, and the replies.

Pure state, no I/O and no threads: :class:`FcbLogic` takes decoded commands with the time they are
executed and returns the reply packets; :meth:`FcbLogic.due` returns the completions that fall due
(a zoom direct arriving, power-on finished). Times are ``time.monotonic()`` seconds. The wire,
the command buffer and injected faults are :mod:`umbra.modules.calib.visca.sim_camera`'s.

Sockets: a command that runs on after its ACK (zoom or focus direct and memory recall until the
lens arrives, power on while the camera starts) holds socket 1 or 2 until its completion. Zoom and
focus tele/wide/far/near/stop, focus mode, one push, memory set/reset and power off complete at
once. A new lens command takes the free socket and ends a running one that moves the same motion
(zoom, focus; a recall moves both) with "command cancelled" (``y0 6z 04 FF``) in that one's
socket; ``8x 2z FF`` cancels socket z (or answers "no socket", ``05``, when nothing runs there).
With both sockets busy a command gets "command buffer full" (``y0 60 03 FF``). In standby (power
off) or while starting, lens commands get "command not executable" (``y0 6z 41 FF``, z the
socket they would have taken), and so do manual focus commands in auto focus; inquiries, power,
cancel and IF_Clear are always answered. Unknown packets get "syntax error" (``02``). What each
lens command does to zoom, focus and the memories is :mod:`umbra.modules.calib.visca.sim_lens`.
"""

from __future__ import annotations

from dataclasses import dataclass

from umbra.modules.calib.visca import commands as vc
from umbra.modules.calib.visca import commands_panel as cp
from umbra.modules.calib.visca import protocol as vp
from umbra.modules.calib.visca.sim_lens import FOCUS, ZOOM, Axes, FcbLens, LensCommand
from umbra.modules.calib.visca.zoom_motion import Motion, ZoomSpeeds


@dataclass
class _Running:
    """A command holding a socket until ``until`` [s] (a lens command: its arrival)."""

    kind: str  # "lens" or "power"
    until: float
    axes: Axes = frozenset()


class FcbLogic:
    """State of one simulated FCB camera (see the module docstring).

    ``max_raw`` is the tele end of the lens (raw units); ``speeds`` its zoom travel times and
    ``focus_speeds`` its focus travel times (default: the zoom's); ``af_raw`` the focus position
    where the simulated scene is sharp; ``power_on_s`` [s] how long power-on takes; ``model`` and
    ``rom`` what CAM_VersionInq reports (the defaults claim no real model: code 0x0000).
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
        focus_speeds: ZoomSpeeds | None = None,
        af_raw: int = 0x3000,
    ) -> None:
        self.speeds = speeds
        self.max_raw = max_raw
        self.power_on_s = power_on_s
        self.model, self.rom = model, rom
        self.address = address
        self.powered = True
        self.lens = FcbLens(speeds, focus_speeds or speeds, max_raw, initial_raw, af_raw)
        self._running: dict[int, _Running] = {}
        self.cancelled = 0

    # -- queries -----------------------------------------------------------------------------

    @property
    def motion(self) -> Motion:
        """The zoom's motion."""
        return self.lens.zoom

    def position(self, now: float) -> int:
        return self.lens.zoom.position(now)

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
            return [vp.encode_zoom_position_reply(a, self.lens.zoom.position(now))]
        if isinstance(command, cp.FocusPositionInquiry):
            return [cp.encode_focus_position_reply(a, self.lens.focus.position(now))]
        if isinstance(command, cp.FocusModeInquiry):
            return [cp.encode_focus_mode_reply(a, self.lens.focus_auto)]
        if isinstance(command, vc.PowerInquiry):
            return [vc.encode_power_reply(a, self.powered)]
        if isinstance(command, vc.VersionInquiry):
            return [vc.encode_version_reply(a, self.model, self.rom)]
        if isinstance(command, vc.CancelCommand):
            return self._cancel(command.socket, now)
        if isinstance(command, vc.PowerCommand):
            return self._power(command.on, now)
        if isinstance(command, LensCommand):
            return self._lens(command, now)
        return [vp.encode_error(a, 0, vp.ErrorCode.SYNTAX)]

    def clear(self, now: float) -> None:
        """IF_Clear: stop the lens, forget running commands (they get no reply)."""
        self.lens.halt(frozenset((ZOOM, FOCUS)), now)
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

    def _cancel(self, socket: int, now: float) -> list[bytes]:
        running = self._running.pop(socket, None)
        if running is None:
            return [vp.encode_error(self.address, socket, vp.ErrorCode.NO_SOCKET)]
        self.lens.halt(running.axes, now)
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
            self.lens.halt(frozenset((ZOOM, FOCUS)), now)
            for other in [s for s, r in self._running.items() if r.kind == "lens"]:
                del self._running[other]
                self.cancelled += 1
                replies.append(vp.encode_error(a, other, vp.ErrorCode.CANCELLED))
        return [*replies, vp.encode_completion(a, socket)]

    def _lens(self, command: LensCommand, now: float) -> list[bytes]:
        a = self.address
        socket = self._free_socket()
        if socket is None:
            return [vp.encode_error(a, 0, vp.ErrorCode.BUFFER_FULL)]
        starting = "power" in (r.kind for r in self._running.values())
        if not self.powered or starting or self.lens.not_executable(command):
            return [vp.encode_error(a, socket, vp.ErrorCode.NOT_EXECUTABLE)]
        replies = [vp.encode_ack(a, socket)]
        axes = self.lens.axes(command)
        for old in sorted(s for s, r in self._running.items() if r.axes & axes):
            del self._running[old]  # the new lens command takes over that motion
            self.cancelled += 1
            replies.append(vp.encode_error(a, old, vp.ErrorCode.CANCELLED))
        until = self.lens.execute(command, now)
        if until is not None:
            self._running[socket] = _Running("lens", until, axes)
            return replies
        return [*replies, vp.encode_completion(a, socket)]
