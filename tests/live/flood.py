"""A connection flood without the token, run as its own process so that its CPU is not the
server's: ``python -m tests.live.flood HOST PORT SECONDS [--source ADDR] [--hold N]``.

Two threads open TCP connections as fast as they can (from ``--source``, a loopback address of
its own, so a viewer on 127.0.0.1 keeps its own per-client share) and leave them half-open: in
turn nothing at all, a request head that never ends, a WebSocket upgrade without the token, and
garbage (a TLS hello). It holds the newest ``--hold`` connections (closing the oldest itself
beyond that) and watches each for the server closing it: at once (aborted over a limit, refused,
answered) or late (a half-open one closed at the door's deadline).

Prints ``flooding`` once its threads started, and one JSON line at the end: connections opened,
those the server closed within :data:`AT_ONCE_S`, the delays of the half-open ones it closed
later, and how many it still held open past the deadline when the flood stopped.
"""

from __future__ import annotations

import argparse
import json
import queue
import selectors
import socket
import sys
import threading
import time

#: A connection closed within this time of opening was closed "at once" [s].
AT_ONCE_S = 0.5
_KINDS = ("nothing", "partial", "upgrade", "garbage")


def _first_bytes(kind: str, host: str, port: int) -> bytes:
    if kind == "partial":
        return f"GET /?token=guess HTTP/1.1\r\nHost: {host}:{port}\r\nX-Slow: ".encode()
    if kind == "upgrade":
        return (
            f"GET / HTTP/1.1\r\nHost: {host}:{port}\r\nUpgrade: websocket\r\n"
            "Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
            "Sec-WebSocket-Version: 13\r\nSec-WebSocket-Protocol: foxglove.websocket.v1\r\n\r\n"
        ).encode()
    if kind == "garbage":
        return b"\x16\x03\x01\x02\x00\x01\x00\x01\xfc\x03\x03" + b"\x00" * 64
    return b""


class Flood:
    """The flood's sockets and what became of them (see the module docstring)."""

    def __init__(self, host: str, port: int, source: str, hold: int, deadline: float) -> None:
        self.host, self.port, self.source, self.hold = host, port, source, hold
        self.deadline = deadline  #: the door's deadline on a request head [s]
        self.new: queue.SimpleQueue[tuple[socket.socket, str, float]] = queue.SimpleQueue()
        self.lock = threading.Lock()
        self.counts = {"opened": 0, "connect_failed": 0, "closed_at_once": 0, "closed_late": 0}
        self.counts["closed_by_flood"] = 0  #: beyond ``hold``: closed by the flood itself
        self.counts |= {f"opened_{k}": 0 for k in _KINDS}
        self.late: list[float] = []  #: delays of the connections the server closed later [s]
        self.open_past_deadline = 0

    def connect(self, end: float) -> None:
        n = 0
        while time.monotonic() < end:
            n += 1
            kind = _KINDS[n % len(_KINDS)]
            s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            try:
                s.bind((self.source, 0))
                s.settimeout(0.1)  # a full accept queue drops the SYN: try the next one
                s.connect((self.host, self.port))
                opened = time.monotonic()
                data = _first_bytes(kind, self.host, self.port)
                if data:
                    s.sendall(data)
            except OSError:
                s.close()
                with self.lock:
                    self.counts["connect_failed"] += 1
                continue
            s.setblocking(False)
            with self.lock:
                self.counts["opened"] += 1
                self.counts[f"opened_{kind}"] += 1
            self.new.put((s, kind, opened))

    def watch(self, end: float) -> None:
        sel = selectors.DefaultSelector()
        held: dict[socket.socket, None] = {}  #: open ones, oldest first
        while time.monotonic() < end or not self.new.empty():
            while not self.new.empty():
                s, kind, opened = self.new.get()
                sel.register(s, selectors.EVENT_READ, (kind, opened))
                held[s] = None
                while len(held) > self.hold:  # the flooder's own limit: close its oldest
                    old = next(iter(held))
                    del held[old]
                    sel.unregister(old)
                    old.close()
                    self.counts["closed_by_flood"] += 1
            for key, _ in sel.select(timeout=0.01):
                s = key.fileobj
                assert isinstance(s, socket.socket)
                try:
                    gone = s.recv(65536) == b""
                except BlockingIOError:
                    continue
                except OSError:  # reset: aborted by the server
                    gone = True
                if gone:
                    self._closed(key.data[1])
                    sel.unregister(s)
                    del held[s]
                    s.close()
        now = time.monotonic()
        for key in list(sel.get_map().values()):
            if now - key.data[1] > self.deadline + 2.0:
                self.open_past_deadline += 1
            key.fileobj.close()  # type: ignore[union-attr]
        sel.close()

    def _closed(self, opened: float) -> None:
        delay = time.monotonic() - opened
        if delay <= AT_ONCE_S:
            self.counts["closed_at_once"] += 1
        else:
            self.counts["closed_late"] += 1
            self.late.append(delay)

    def report(self) -> dict:
        late = sorted(self.late)
        return {
            **self.counts,
            "late_min_s": late[0] if late else None,
            "late_max_s": late[-1] if late else None,
            "late_s": late,
            "open_past_deadline": self.open_past_deadline,
        }


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("host")
    parser.add_argument("port", type=int)
    parser.add_argument("seconds", type=float)
    parser.add_argument("--source", default="127.0.0.2", help="the flood's own address")
    parser.add_argument("--hold", type=int, default=4000, help="connections held at most")
    parser.add_argument("--deadline", type=float, default=5.0, help="the door's head deadline")
    parser.add_argument("--linger", type=float, default=0.0, help="watch this long after")
    args = parser.parse_args(argv)
    flood = Flood(args.host, args.port, args.source, args.hold, args.deadline)
    end = time.monotonic() + args.seconds
    threads = [threading.Thread(target=flood.connect, args=(end,)) for _ in range(2)]
    watcher = threading.Thread(target=flood.watch, args=(end + args.linger,))
    for t in [*threads, watcher]:
        t.start()
    print("flooding", flush=True)
    for t in [*threads, watcher]:
        t.join()
    print(json.dumps(flood.report()), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
