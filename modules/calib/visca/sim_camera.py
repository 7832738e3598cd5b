"""A simulated Sony FCB zoom camera speaking VISCA on a pseudo-terminal.

The simulator owns the master side of a pty (``os.openpty``); a client opens the slave side
(:attr:`SimFcbCamera.path`, e.g. ``/dev/pts/7``) with pyserial exactly as it would open
``/dev/ttyUSB0``. It answers the FCB command set of :mod:`umbra.modules.calib.visca.commands`:
address set, IF_Clear (broadcast: echoed; addressed: ``y0 50 FF``, stops the lens and empties the
command buffer), command cancel, power on/off and CAM_PowerInq, CAM_VersionInq, zoom tele/wide at
the standard and the eight variable speeds, zoom stop, zoom direct and CAM_ZoomPosInq, and the
focus and memory commands a PTZ panel sends (:mod:`umbra.modules.calib.visca.commands_panel`:
focus far/near/stop, direct, auto/manual, one push, CAM_FocusPosInq, CAM_FocusModeInq, memory
reset/set/recall). What each command does to sockets and power, and which error it gets, is
:mod:`umbra.modules.calib.visca.sim_logic`; what it does to zoom, focus and memories is
:mod:`umbra.modules.calib.visca.sim_lens`; how fast the lens moves is
:mod:`umbra.modules.calib.visca.zoom_motion` (zoom direct: ``full_range_s`` wide to tele, 2.4 s by
default; focus: the same times over the focus range).

Like the camera, the simulator executes at most one packet per video field (``v_cycle_s``, 1/60 s)
and holds two packets waiting; a third that arrives meanwhile is answered "command buffer full"
(``y0 60 03 FF``) at once. Replies leave after ``reply_delay_s`` plus their time on a 9600 baud
line. Faults can be injected at any time (:meth:`SimFcbCamera.inject`): garbled replies, silence,
or an error reply to every request. Run ``python -m umbra.modules.calib.visca.sim_camera`` to serve
one on its own; it prints the pty path.
"""

from __future__ import annotations

import argparse
import enum
import os
import random
import select
import signal
import sys
import threading
import time
import tty
from collections import deque
from dataclasses import dataclass

from umbra.modules.calib.visca import commands as vc
from umbra.modules.calib.visca import protocol as vp
from umbra.modules.calib.visca.sim_logic import FcbLogic
from umbra.modules.calib.visca.zoom_motion import ZoomSpeeds

BUFFERED_PACKETS = 2
"""Packets a camera holds waiting for execution; one more is refused as "buffer full"."""


class Fault(enum.Enum):
    """What the simulated camera does wrong."""

    NONE = "none"
    GARBLE = "garble"  #: executes commands, but every reply arrives mangled (no valid header)
    SILENT = "silent"  #: receives nothing and says nothing (cable out)
    ERROR = "error"  #: answers every addressed request with an error reply


@dataclass
class SimCounters:
    commands: int = 0
    inquiries: int = 0
    replies: int = 0
    dropped_replies: int = 0
    garbage_in: int = 0
    buffer_full: int = 0


class SimFcbCamera:
    """Simulated FCB camera on a pty. Use as a context manager or call start()/stop().

    ``address`` is the camera's address until an address set arrives. ``full_range_s`` [s] is the
    zoom-direct travel time from raw 0 to ``max_raw`` (default the optical tele end, 0x4000);
    commands beyond ``max_raw`` stop there (digital zoom off). ``speeds`` overrides the travel
    times of every speed (default: the model of :mod:`~umbra.modules.calib.visca.zoom_motion` scaled
    to ``full_range_s``). ``power_on_s`` [s]: how long power-on runs before its completion;
    ``v_cycle_s`` [s]: one packet executed per cycle. ``seed`` makes the garbling reproducible.
    """

    def __init__(
        self,
        full_range_s: float = 2.4,
        max_raw: int = vp.ZOOM_RAW_OPTICAL_TELE,
        initial_raw: int = 0,
        address: int = 1,
        reply_delay_s: float = 0.003,
        baudrate: int = 9600,
        seed: int = 0,
        speeds: ZoomSpeeds | None = None,
        power_on_s: float = 0.5,
        v_cycle_s: float = 1.0 / 60.0,
    ) -> None:
        if full_range_s <= 0:
            raise ValueError(f"full_range_s must be > 0, got {full_range_s}")
        self.full_range_s = full_range_s
        self.max_raw = max_raw
        self.reply_delay_s = reply_delay_s
        self.byte_time_s = 10.0 / baudrate
        self.v_cycle_s = v_cycle_s
        self.counters = SimCounters()
        self.logic = FcbLogic(
            speeds or ZoomSpeeds(direct_s=full_range_s),
            max_raw=max_raw,
            initial_raw=initial_raw,
            address=address,
            power_on_s=power_on_s,
        )
        self._waiting: deque[tuple[float, vc.Command]] = deque()
        self._last_execution = -float("inf")
        self._rng = random.Random(seed)
        self._lock = threading.Lock()
        self._fault = Fault.NONE
        self._error_code = vp.ErrorCode.NOT_EXECUTABLE
        self._outbox: list[tuple[float, bytes]] = []
        self._splitter = vp.PacketSplitter()
        self._master: int | None = None
        self._slave: int | None = None
        self._path = ""
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()

    # -- lifecycle ---------------------------------------------------------------------------

    @property
    def path(self) -> str:
        """Path of the pty's slave side, for the client to open (empty before start)."""
        return self._path

    def start(self) -> str:
        """Open the pty and serve it in a thread; returns the slave path."""
        if self._thread is not None:
            return self._path
        master, slave = os.openpty()
        tty.setraw(slave)  # no echo, no line editing, 8 bit clean until the client configures it
        os.set_blocking(master, False)
        self._master, self._slave = master, slave
        self._path = os.ttyname(slave)
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="sim-fcb", daemon=True)
        self._thread.start()
        return self._path

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        for fd in (self._master, self._slave):
            if fd is not None:
                os.close(fd)
        self._master = self._slave = None

    def __enter__(self) -> SimFcbCamera:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # -- control and truth -------------------------------------------------------------------

    def inject(self, fault: Fault, error_code: vp.ErrorCode = vp.ErrorCode.NOT_EXECUTABLE) -> None:
        """Start misbehaving (``Fault.NONE`` heals); ``error_code`` is used by ``Fault.ERROR``."""
        with self._lock:
            self._fault = fault
            self._error_code = error_code

    def heal(self) -> None:
        self.inject(Fault.NONE)

    @property
    def address(self) -> int:
        with self._lock:
            return self.logic.address

    @property
    def powered(self) -> bool:
        with self._lock:
            return self.logic.powered

    def position_raw(self) -> int:
        """True zoom position now (raw FCB units)."""
        with self._lock:
            return self.logic.position(time.monotonic())

    def target_raw(self) -> int:
        """Where the lens is heading (the range end during a tele/wide move)."""
        with self._lock:
            return self.logic.lens.zoom.target_raw

    def moving(self) -> bool:
        with self._lock:
            return self.logic.lens.zoom.moving(time.monotonic())

    def focus_raw(self) -> int:
        """True focus position now (raw FCB units, ``sim_lens.FOCUS_RAW_FAR`` at infinity)."""
        with self._lock:
            return self.logic.lens.focus.position(time.monotonic())

    def focus_auto(self) -> bool:
        """Whether the camera is in auto focus."""
        with self._lock:
            return self.logic.lens.focus_auto

    # -- serving -----------------------------------------------------------------------------

    def _run(self) -> None:
        assert self._master is not None
        while not self._stop.is_set():
            readable, _, _ = select.select([self._master], [], [], self._wait_s())
            if readable:
                try:
                    data = os.read(self._master, 1024)
                except (BlockingIOError, InterruptedError):
                    data = b""
                except OSError:  # slave side gone for good
                    data = b""
                self._receive(data)
            self._execute_waiting()
            self._finish_due()
            self._flush_outbox()

    def _wait_s(self) -> float:
        now = time.monotonic()
        waits = [0.05]
        with self._lock:
            due = self.logic.next_due()
            if due is not None:
                waits.append(due - now)
            if self._waiting:
                waits.append(self._waiting[0][0] - now)
            if self._outbox:
                waits.append(self._outbox[0][0] - now)
        return max(0.0, min(waits))

    def _receive(self, data: bytes) -> None:
        with self._lock:
            if self._fault is Fault.SILENT:
                return
        errors_before = self._splitter.errors
        for packet in self._splitter.feed(data):
            try:
                command = vc.decode_command(packet)
            except vp.ViscaDecodeError:
                self.counters.garbage_in += 1
                continue
            self._execute_waiting()  # a packet due now runs before the next is buffered
            self._arrive(command)
        self.counters.garbage_in += self._splitter.errors - errors_before

    def _arrive(self, command: vc.Command) -> None:
        """Take a packet into the command buffer (IF_Clear and address set act at once)."""
        now = time.monotonic()
        with self._lock:
            broadcast = isinstance(command, vc.AddressSetCommand) or command.address is None
            if not broadcast and command.address != self.logic.address:
                return  # for another camera on the chain
            if isinstance(command, vc.AddressSetCommand | vc.IfClearCommand):
                if isinstance(command, vc.IfClearCommand):
                    self._waiting.clear()
                self._run_command(command, now)
                return
            if len(self._waiting) >= BUFFERED_PACKETS:
                self.counters.buffer_full += 1
                self._send(vp.encode_error(self.logic.address, 0, vp.ErrorCode.BUFFER_FULL), now)
                return
            start = self._waiting[-1][0] if self._waiting else self._last_execution
            self._waiting.append((max(now, start + self.v_cycle_s), command))

    def _execute_waiting(self) -> None:
        now = time.monotonic()
        with self._lock:
            while self._waiting and self._waiting[0][0] <= now:
                _, command = self._waiting.popleft()
                self._last_execution = now
                self._run_command(command, now)

    def _run_command(self, command: vc.Command, now: float) -> None:
        """Execute one command (lock held), through the injected fault."""
        if isinstance(command, vc.Inquiry):
            self.counters.inquiries += 1
        elif not isinstance(command, vc.AddressSetCommand):
            self.counters.commands += 1
        addressed = command.address is not None and not isinstance(command, vc.AddressSetCommand)
        if self._fault is Fault.ERROR and addressed:
            self._send_error_fault(command, now)
            return
        for reply in self.logic.execute(command, now):
            self._send(reply, now)

    def _send_error_fault(self, command: vc.Command, now: float) -> None:
        code = self._error_code
        socket_level = code in (vp.ErrorCode.CANCELLED, vp.ErrorCode.NO_SOCKET) or (
            code is vp.ErrorCode.NOT_EXECUTABLE and isinstance(command, vc.SocketCommand)
        )
        self._send(vp.encode_error(self.logic.address, 1 if socket_level else 0, code), now)

    def _finish_due(self) -> None:
        now = time.monotonic()
        with self._lock:
            for reply in self.logic.due(now):
                self._send(reply, now)

    # -- the wire ----------------------------------------------------------------------------

    def _send(self, packet: bytes, now: float) -> None:
        """Queue a reply (lock held): garbled or dropped according to the fault."""
        if self._fault is Fault.SILENT:
            self.counters.dropped_replies += 1
            return
        if self._fault is Fault.GARBLE:
            packet = self._garble(packet)
        due = now + self.reply_delay_s + len(packet) * self.byte_time_s
        if self._outbox:
            due = max(due, self._outbox[-1][0])
        self._outbox.append((due, packet))

    def _garble(self, packet: bytes) -> bytes:
        """Line noise that no decoder can take for a reply: random 7-bit bytes, header lost."""
        noise = bytes(self._rng.randrange(0x00, 0x80) for _ in range(self._rng.randrange(0, 4)))
        return noise + bytes(b & 0x7F for b in packet[:-1]) + b"\xff"

    def _flush_outbox(self) -> None:
        now = time.monotonic()
        with self._lock:
            due = [packet for when, packet in self._outbox if when <= now]
            self._outbox = [(when, packet) for when, packet in self._outbox if when > now]
        for packet in due:
            try:
                assert self._master is not None
                os.write(self._master, packet)
                self.counters.replies += 1
            except (BlockingIOError, OSError):
                self.counters.dropped_replies += 1


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m umbra.modules.calib.visca.sim_camera",
        description="Serve a simulated Sony FCB zoom camera (VISCA) on a pseudo-terminal.",
    )
    parser.add_argument("--full-range-s", type=float, default=2.4, help="wide to tele time [s]")
    parser.add_argument("--seed", type=int, default=0, help="seed for garbled replies")
    parser.add_argument(
        "--fault", choices=[f.value for f in Fault], default="none", help="inject a fault"
    )
    parser.add_argument("--link", default="", help="also make a symlink to the pty at this path")
    args = parser.parse_args(argv)
    camera = SimFcbCamera(full_range_s=args.full_range_s, seed=args.seed)
    done = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: done.set())
    signal.signal(signal.SIGINT, lambda *_: done.set())
    path = camera.start()
    camera.inject(Fault(args.fault))
    if args.link:
        if os.path.islink(args.link):
            os.unlink(args.link)
        os.symlink(path, args.link)
    print(path, flush=True)
    try:
        while not done.wait(0.5):
            pass
    finally:
        camera.stop()
        if args.link and os.path.islink(args.link):
            os.unlink(args.link)
    return 0


if __name__ == "__main__":
    sys.exit(main())
