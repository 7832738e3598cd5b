"""A simulated Sony FCB zoom camera speaking VISCA on a pseudo-terminal.

The simulator owns the master side of a pty (``os.openpty``); a client opens the slave side
(:attr:`SimFcbCamera.path`, e.g. ``/dev/pts/7``) with pyserial exactly as it would open
``/dev/ttyUSB0``. It answers:

* address set ``88 30 0w FF`` (takes address w, replies ``88 30 0w+1 FF``);
* IF_Clear, broadcast (echoed) and addressed (``y0 50 FF``), which stops a running zoom;
* zoom direct: ACK ``y0 4z FF`` at once, completion ``y0 5z FF`` when the zoom arrives. The zoom
  position moves at a constant rate toward the target, full optical range in ``full_range_s``
  (about 2.4 s on an FCB at top speed). A new zoom direct during a move takes the other socket
  and the old one ends with "command cancelled" (``y0 6z 04 FF``);
* zoom position inquiry ``y0 50 0p 0q 0r 0s FF`` with the position at that instant;
* anything else addressed to it: syntax error ``y0 60 02 FF``.

Replies leave after ``reply_delay_s`` plus their time on a 9600 baud line. Faults can be injected
at any time (:meth:`SimFcbCamera.inject`): garbled replies, silence, or an error reply to every
request. Run ``python -m modules.calib.visca.sim_camera`` to serve one on its own; it prints the
pty path.
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
from dataclasses import dataclass

from modules.calib.visca import protocol as vp


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


@dataclass(frozen=True)
class _Motion:
    """Zoom travel at a constant rate [raw/s] from ``start_raw`` at time ``t0`` [s]."""

    start_raw: int
    target_raw: int
    t0: float
    rate: float

    def position(self, now: float) -> int:
        span = self.target_raw - self.start_raw
        travelled = self.rate * max(0.0, now - self.t0)
        if travelled >= abs(span):
            return self.target_raw
        return self.start_raw + round(travelled if span > 0 else -travelled)

    def arrival(self) -> float:
        return self.t0 + abs(self.target_raw - self.start_raw) / self.rate


class SimFcbCamera:
    """Simulated FCB camera on a pty. Use as a context manager or call start()/stop().

    ``address`` is the camera's address until an address set arrives. ``full_range_s`` [s] is the
    travel time from raw 0 to ``max_raw`` (default the optical tele end, 0x4000); commands beyond
    ``max_raw`` stop there (digital zoom off). ``seed`` makes the garbling reproducible.
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
    ) -> None:
        if full_range_s <= 0:
            raise ValueError(f"full_range_s must be > 0, got {full_range_s}")
        self.full_range_s = full_range_s
        self.max_raw = max_raw
        self.reply_delay_s = reply_delay_s
        self.byte_time_s = 10.0 / baudrate
        self.counters = SimCounters()
        self._rate = max_raw / full_range_s
        self._rng = random.Random(seed)
        self._lock = threading.Lock()
        self._address = address
        self._motion = _Motion(initial_raw, initial_raw, 0.0, self._rate)
        self._motion_socket: int | None = None
        self._next_socket = 1
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
            return self._address

    def position_raw(self) -> int:
        """True zoom position now (raw FCB units)."""
        with self._lock:
            return self._motion.position(time.monotonic())

    def target_raw(self) -> int:
        with self._lock:
            return self._motion.target_raw

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
            self._finish_arrivals()
            self._flush_outbox()

    def _wait_s(self) -> float:
        now = time.monotonic()
        waits = [0.05]
        with self._lock:
            if self._motion_socket is not None:
                waits.append(self._motion.arrival() - now)
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
                command = vp.decode_command(packet)
            except vp.ViscaDecodeError:
                self.counters.garbage_in += 1
                continue
            self._execute(command)
        self.counters.garbage_in += self._splitter.errors - errors_before

    def _execute(self, command: vp.Command) -> None:
        now = time.monotonic()
        with self._lock:
            if isinstance(command, vp.AddressSetCommand):
                self._address = command.address
                self._send(vp.encode_address_set_reply(command.address + 1), now)
                return
            if command.address is not None and command.address != self._address:
                return  # for another camera on the chain
            if isinstance(command, vp.ZoomPositionInquiry):
                self.counters.inquiries += 1
            else:
                self.counters.commands += 1
            if self._fault is Fault.ERROR and command.address is not None:
                self._send_error_fault(command, now)
                return
            if isinstance(command, vp.IfClearCommand):
                self._stop_motion(now)
                if command.address is None:
                    self._send(vp.encode_if_clear_broadcast(), now)
                else:
                    self._send(vp.encode_completion(self._address, 0), now)
            elif isinstance(command, vp.ZoomDirectCommand):
                self._start_zoom(command.raw, now)
            elif isinstance(command, vp.ZoomPositionInquiry):
                position = self._motion.position(now)
                self._send(vp.encode_zoom_position_reply(self._address, position), now)
            else:
                self._send(vp.encode_error(self._address, 0, vp.ErrorCode.SYNTAX), now)

    def _send_error_fault(self, command: vp.Command, now: float) -> None:
        code = self._error_code
        socket_level = code in (vp.ErrorCode.CANCELLED, vp.ErrorCode.NO_SOCKET) or (
            code is vp.ErrorCode.NOT_EXECUTABLE and isinstance(command, vp.ZoomDirectCommand)
        )
        self._send(vp.encode_error(self._address, 1 if socket_level else 0, code), now)

    def _start_zoom(self, raw: int, now: float) -> None:
        target = min(raw, self.max_raw)
        old_socket = self._motion_socket
        socket = self._next_socket
        self._next_socket = 2 if socket == 1 else 1
        self._motion = _Motion(self._motion.position(now), target, now, self._rate)
        self._motion_socket = socket
        self._send(vp.encode_ack(self._address, socket), now)
        if old_socket is not None:
            self._send(vp.encode_error(self._address, old_socket, vp.ErrorCode.CANCELLED), now)

    def _stop_motion(self, now: float) -> None:
        here = self._motion.position(now)
        self._motion = _Motion(here, here, now, self._rate)
        self._motion_socket = None

    def _finish_arrivals(self) -> None:
        now = time.monotonic()
        with self._lock:
            if self._motion_socket is not None and now >= self._motion.arrival():
                self._send(vp.encode_completion(self._address, self._motion_socket), now)
                self._motion_socket = None

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
        prog="python -m modules.calib.visca.sim_camera",
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
