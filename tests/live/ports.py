"""What a process listens on, read from ``/proc`` (Linux), and what a raw viewer gets there."""

from __future__ import annotations

import json
import os
from pathlib import Path

import websockets.sync.client as ws_client
from websockets.exceptions import InvalidHandshake, WebSocketException

#: TCP state "listen" in /proc/net/tcp.
_LISTEN = "0A"


def descendants(pid: int) -> list[int]:
    """``pid`` and every process started under it."""
    children: dict[int, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        ppid = int(stat.rsplit(")", 1)[1].split()[1])
        children.setdefault(ppid, []).append(int(entry.name))
    found, todo = [], [pid]
    while todo:
        current = todo.pop()
        found.append(current)
        todo.extend(children.get(current, []))
    return found


def _socket_inodes(pid: int) -> set[str]:
    inodes = set()
    fd_dir = Path(f"/proc/{pid}/fd")
    for fd in fd_dir.iterdir():
        try:
            target = os.readlink(fd)
        except OSError:
            continue
        if target.startswith("socket:["):
            inodes.add(target[8:-1])
    return inodes


def listening_ports(pid: int) -> set[int]:
    """TCP ports (IPv4 and IPv6) a socket of process ``pid`` listens on."""
    inodes = _socket_inodes(pid)
    ports = set()
    for table in ("tcp", "tcp6"):
        path = Path(f"/proc/{pid}/net/{table}")
        if not path.exists():
            continue
        for line in path.read_text().splitlines()[1:]:
            fields = line.split()
            if fields[3] == _LISTEN and fields[9] in inodes:
                ports.add(int(fields[1].rsplit(":", 1)[1], 16))
    return ports


def viewer_gets(port: int, query: str, topic: str, timeout: float = 5.0) -> str:
    """What a Foxglove viewer connecting to ``ws://127.0.0.1:PORT/QUERY`` gets: ``"refused"``
    (no WebSocket), ``"nothing"`` (a socket but no data on ``topic`` within ``timeout``) or
    ``"data"``."""
    url = f"ws://127.0.0.1:{port}/{query}"
    try:
        conn = ws_client.connect(
            url, subprotocols=["foxglove.websocket.v1"], open_timeout=timeout, max_size=None
        )
    except (OSError, InvalidHandshake, WebSocketException, TimeoutError):
        return "refused"
    with conn:
        try:
            while True:
                message = conn.recv(timeout=timeout)
                if isinstance(message, bytes):
                    return "data"
                found = json.loads(message)
                if found.get("op") == "advertise":
                    wanted = [c["id"] for c in found["channels"] if c["topic"] == topic]
                    subs = [{"id": i, "channelId": c} for i, c in enumerate(wanted)]
                    if subs:
                        conn.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
        except (TimeoutError, WebSocketException, ValueError):
            return "nothing"
