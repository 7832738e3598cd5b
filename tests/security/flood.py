"""Floods of a page server, run as their own process (``python -m tests.security.flood KIND URL
SECONDS``) so that their CPU is not the server's: the attack tests and
``benchmarks/bench_page_flood.py`` start them beside a test operator.

- ``junk``: sockets opened with the token (a rogue tab of the operator's browser) sending as fast
  as they can: malformed text, binary, and well-formed commands of a page without control
  (abort, take, jog); a socket the server closes is opened again.
- ``big``: sockets with the token sending 1 MiB messages, opened again when closed.
- ``connections``: TCP connections as fast as they can, most of them left half-open (a request
  head that never ends), the rest websocket handshakes without the token.
- ``burn``: no connection at all, the same busy threads spinning: the CPU load of a flood from
  outside the server (the baseline a flood is compared with on a loaded machine).

Prints ``flooding`` once its threads started, and one JSON line at the end: what was sent and
how often the server closed or refused.
"""

from __future__ import annotations

import json
import logging
import socket
import sys
import threading
import time
from typing import Any
from urllib.parse import urlsplit

from websockets.exceptions import ConnectionClosed, InvalidStatus
from websockets.sync.client import connect

_JUNK = ["{not json", "[]", '{"type": "take"}', "x" * 4000]


def _ws_url(url: str) -> str:
    base, _, query = url.partition("?")
    return base.replace("http://", "ws://").rstrip("/") + "/ws" + (f"?{query}" if query else "")


def junk(url: str, end: float, counts: dict[str, int], lock: threading.Lock) -> None:
    while time.monotonic() < end:
        try:
            with connect(_ws_url(url), open_timeout=5, max_size=None) as ws:
                welcome = json.loads(ws.recv(timeout=5))
                session, seq = welcome.get("session", ""), 0
                with lock:
                    counts["opened"] += 1
                while time.monotonic() < end:
                    seq += 1
                    k = seq % 6
                    if k < 4:
                        ws.send(_JUNK[k])
                    elif k == 4:
                        ws.send(b"\x00" * 64)
                    else:  # well formed, from a page without control: refused by the console
                        kind = ("action", "take", "jog")[seq % 3]
                        fields: dict[str, Any] = {
                            "action": {"action": "abort"},
                            "take": {},
                            "jog": {
                                "held": True,
                                "axes": [1, 0, 0, 0],
                                "jog_frame": "camera",
                                "speed": 1.0,
                                "frame": 0,
                            },
                        }[kind]
                        message = {"session": session, "seq": seq, "type": kind, **fields}
                        ws.send(json.dumps(message))
                    with lock:
                        counts["sent"] += 1
        except (ConnectionClosed, InvalidStatus, OSError, TimeoutError):
            with lock:
                counts["closed"] += 1
            time.sleep(0.005)


def big(url: str, end: float, counts: dict[str, int], lock: threading.Lock) -> None:
    payload = "y" * (1 << 20)
    while time.monotonic() < end:
        try:
            with connect(_ws_url(url), open_timeout=5, max_size=None) as ws:
                with lock:
                    counts["opened"] += 1
                while time.monotonic() < end:
                    ws.send(payload)
                    with lock:
                        counts["sent"] += 1
        except (ConnectionClosed, InvalidStatus, OSError, TimeoutError):
            with lock:
                counts["closed"] += 1
            time.sleep(0.005)


def connections(url: str, end: float, counts: dict[str, int], lock: threading.Lock) -> None:
    parts = urlsplit(url)
    host, port = parts.hostname or "127.0.0.1", parts.port or 80
    held: list[socket.socket] = []
    n = 0
    while time.monotonic() < end:
        n += 1
        try:
            s = socket.create_connection((host, port), timeout=2)
        except OSError:
            with lock:
                counts["refused"] += 1
            time.sleep(0.01)
            continue
        try:
            if n % 4:
                s.sendall(f"GET / HTTP/1.1\r\nHost: {host}:{port}\r\nX-Slow: ".encode())
            else:
                s.sendall(
                    (
                        f"GET /ws HTTP/1.1\r\nHost: {host}:{port}\r\nUpgrade: websocket\r\n"
                        "Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
                        "Sec-WebSocket-Version: 13\r\n\r\n"
                    ).encode()
                )
        except OSError:
            pass
        held.append(s)
        with lock:
            counts["sent"] += 1
        if len(held) > 200:  # keep the oldest open the longest; close the rest as we go
            held.pop(100).close()
    for s in held:
        s.close()


def burn(url: str, end: float, counts: dict[str, int], lock: threading.Lock) -> None:
    n = 0
    while time.monotonic() < end:
        n += sum(range(1000))
    with lock:
        counts["sent"] += 1


FLOODS = {"junk": junk, "big": big, "connections": connections, "burn": burn}
THREADS = {"junk": 8, "big": 4, "connections": 2, "burn": 2}


def main(argv: list[str]) -> int:
    logging.getLogger("websockets").setLevel(logging.CRITICAL)  # a flooder expects closed sockets
    kind, url, seconds = argv[0], argv[1], float(argv[2])
    counts: dict[str, int] = {"sent": 0, "opened": 0, "closed": 0, "refused": 0}
    lock = threading.Lock()
    end = time.monotonic() + seconds
    threads = [
        threading.Thread(target=FLOODS[kind], args=(url, end, counts, lock), daemon=True)
        for _ in range(THREADS[kind])
    ]
    for t in threads:
        t.start()
    print("flooding", flush=True)
    for t in threads:
        t.join(seconds + 10)
    print(json.dumps({"flood": kind, **counts}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
