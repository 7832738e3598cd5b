"""Run as another OS user (stdlib only: ``/usr/bin/python3 probe.py PORT SERVER_PID``): try the
console's routes and its socket without a token, and look for the token where another user can
read (the server's command line and environment). Prints one JSON object."""

from __future__ import annotations

import http.client
import json
import os
import socket
import sys


def main() -> int:
    port, pid = int(sys.argv[1]), sys.argv[2]
    statuses = {}
    for method, path in (("GET", "/"), ("GET", "/console.js"), ("POST", "/")):
        conn = http.client.HTTPConnection("127.0.0.1", port, timeout=5)
        conn.request(method, path, body=b"{}" if method == "POST" else None)
        statuses[f"{method} {path}"] = conn.getresponse().status
        conn.close()
    with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
        s.sendall(
            (
                f"GET /ws HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\n"
                "Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
                "Sec-WebSocket-Version: 13\r\n\r\n"
            ).encode()
        )
        websocket = s.recv(200).decode("latin-1")
    readable = ""
    for name in ("cmdline", "environ"):
        try:
            with open(f"/proc/{pid}/{name}", "rb") as f:
                readable += f.read().decode("latin-1")
        except OSError:
            pass
    print(
        json.dumps(
            {"uid": os.getuid(), "statuses": statuses, "websocket": websocket, "readable": readable}
        )
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
