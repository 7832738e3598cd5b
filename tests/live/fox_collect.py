"""A Foxglove WebSocket viewer on its own thread that subscribes to some topics of a live server
and keeps every JSON message it receives on them (``websockets``: a client written elsewhere)."""

from __future__ import annotations

import json
import struct
import threading
import time
from dataclasses import dataclass, field

import websockets.sync.client as ws_client
from websockets.exceptions import ConnectionClosed

from tests.poll import wait_for

#: Foxglove's binary "message data" frame: opcode 0x01, subscription id, log time [ns].
_DATA_HEAD = struct.Struct("<BIQ")


@dataclass
class Received:
    """One message of a subscribed topic: its topic, its JSON body, its arrival [monotonic s]."""

    topic: str
    body: dict
    arrival: float


@dataclass
class FoxCollector:
    """Connects to ``url`` at once and keeps the messages of ``topics`` until :meth:`close`."""

    url: str
    topics: tuple[str, ...]
    received: list[Received] = field(default_factory=list)
    connected_at: float = 0.0  #: when the server welcomed it [monotonic s]
    error: str = ""

    def __post_init__(self) -> None:
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        try:
            with ws_client.connect(
                self.url, subprotocols=["foxglove.websocket.v1"], open_timeout=30
            ) as conn:
                self._serve(conn)
        except (OSError, ConnectionClosed, TimeoutError) as exc:
            self.error = f"{type(exc).__name__}: {exc}"

    def _serve(self, conn: ws_client.ClientConnection) -> None:
        topic_of: dict[int, str] = {}  # subscription id -> topic
        while not self._stop.is_set():
            try:
                frame = conn.recv(timeout=0.2)
            except TimeoutError:
                continue
            if isinstance(frame, str):
                msg = json.loads(frame)
                if msg.get("op") == "serverInfo":
                    self.connected_at = time.monotonic()
                if msg.get("op") == "advertise":
                    wanted = [c for c in msg["channels"] if c["topic"] in self.topics]
                    subs = []
                    for channel in wanted:
                        sub_id = len(topic_of) + 1
                        topic_of[sub_id] = channel["topic"]
                        subs.append({"id": sub_id, "channelId": channel["id"]})
                    if subs:
                        conn.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
                continue
            _op, sub_id, _log_ns = _DATA_HEAD.unpack_from(frame)
            topic = topic_of.get(sub_id)
            if topic is not None:
                body = json.loads(frame[_DATA_HEAD.size :])
                with self._lock:
                    self.received.append(Received(topic, body, time.monotonic()))

    def values(self, topic: str) -> list[float]:
        """The ``value`` of every message received on ``topic`` so far."""
        with self._lock:
            return [r.body["value"] for r in self.received if r.topic == topic]

    def first_arrival(self) -> float:
        """When the first message came [monotonic s]."""
        with self._lock:
            return self.received[0].arrival

    def wait_count(self, topic: str, count: int, timeout: float) -> None:
        """Until ``count`` messages of ``topic`` came; AssertionError after ``timeout`` s."""

        def arrived() -> int:
            assert not self.error, f"{self.url}: {self.error}"
            return len(self.values(topic))

        wait_for(
            arrived,
            timeout,
            f"{count} messages on {topic} from {self.url}",
            0.05,
            ok=lambda n: n >= count,
        )

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)
