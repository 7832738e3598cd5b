"""The live server's one socket: the Foxglove WebSocket protocol behind the run's door.

Served with ``websockets`` on a thread of its own (its own event loop): the upgrade request is
checked by :mod:`umbra.runtime.live.gate` before anything is sent, then the viewer gets
``serverInfo`` and the channels, subscribes, and receives message data
(:mod:`umbra.runtime.live.protocol`).

- **Publishing never waits.** :meth:`ViewerServer.publish` is called from the encoding threads; it
  hands the frame to the server's loop, which appends it to each subscribed viewer's backlog
  (``MAX_VIEWER_BACKLOG`` frames and ``MAX_VIEWER_BACKLOG_BYTES``; full: the oldest frame of the
  same channel is dropped and counted, else the oldest of the channel holding the most bytes, so a
  video replaces its own old frames and every other channel keeps its newest: a rare message such
  as ``/tf_static`` stays). Each viewer has a
  sender task of its own: a slow or stalled viewer holds only its own backlog.
- **Behind the door of every web server of the run** (:mod:`umbra.connectors.access.door`, by
  :mod:`umbra.runtime.live.door`): each TCP connection is admitted by the connection limits per
  server and per client address before its handshake starts (one over is aborted at once), its
  upgrade request must arrive whole within the door's deadline and size, and refusals of every
  kind are counted and said at most once a second, never with a traceback. Then the upgrade
  request is checked (:mod:`umbra.runtime.live.gate`).
- **Bounded.** At most ``MAX_VIEWERS`` viewers, ``MAX_VIEWER_MESSAGE_BYTES`` per message a viewer
  sends, the operator pages' message budget for what a viewer sends
  (:class:`~umbra.connectors.access.rate.MessageBudget`: rate, burst, malformed messages),
  ``MAX_VIEWER_BACKLOG`` answers waiting for a viewer that asks and does not read (beyond any of
  these its socket is closed, 1008, with the reason).
- **Parameters** are answered by a :class:`ParameterHandler` (get and set), whose refusals go to
  the asking viewer as ``status`` messages.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import logging
import socket
import threading
import time
from collections import deque
from collections.abc import Iterable
from typing import TYPE_CHECKING, Any, Protocol

from websockets.asyncio.server import ServerConnection
from websockets.exceptions import ConnectionClosed
from websockets.http11 import Request, Response
from websockets.server import ServerProtocol
from websockets.typing import Subprotocol

from umbra.connectors.access.door import Connections, Refusals, peer_address
from umbra.connectors.access.hosts import allowed_hosts
from umbra.connectors.access.rate import MessageBudget
from umbra.connectors.access.secret import TOKEN_QUERY
from umbra.connectors.limits import (
    MAX_VIEWER_BACKLOG,
    MAX_VIEWER_BACKLOG_BYTES,
    MAX_VIEWER_MESSAGE_BYTES,
    MAX_VIEWERS,
)
from umbra.runtime.live import protocol
from umbra.runtime.live.door import DoorListener, DoorServer, connection_class
from umbra.runtime.live.gate import origin_netlocs, refusal

#: Send buffer of a viewer's socket [bytes] (Linux doubles it): the kernel holds a few frames,
#: not seconds of video, for a viewer that reads slowly.
SOCKET_BUFFER = 128 * 1024


if TYPE_CHECKING:  # generic at run time only from Python 3.11 on
    _LoggerAdapter = logging.LoggerAdapter[logging.Logger]
else:
    _LoggerAdapter = logging.LoggerAdapter


class _Quiet(_LoggerAdapter):
    """``websockets``' logger: its warnings and errors only (it says ``connection open`` and
    ``connection rejected`` of every connection at INFO; the door counts those)."""

    def isEnabledFor(self, level: int) -> bool:
        return level >= logging.WARNING and self.logger.isEnabledFor(level)


def _listening_socket(host: str, port: int, backlog: int) -> socket.socket:
    """A non-blocking TCP socket listening on ``host``:``port`` (0: any free port) with a queue
    of ``backlog`` connections."""
    family, kind, proto, _name, address = socket.getaddrinfo(
        host or None, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE
    )[0]
    sock = socket.socket(family, kind, proto)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        if family == socket.AF_INET6:
            sock.setsockopt(socket.IPPROTO_IPV6, socket.IPV6_V6ONLY, 1)
        sock.bind(address)
        sock.listen(backlog)
        sock.setblocking(False)
    except OSError:
        sock.close()
        raise
    return sock


class ParameterHandler(Protocol):
    """What answers a viewer's parameter requests."""

    def get(self, names: list[str]) -> list[dict[str, Any]]:
        """``{"name", "value"}`` of ``names`` (all when empty; unknown names left out)."""
        ...

    def set(
        self, viewer: str, changes: list[tuple[str, Any]]
    ) -> tuple[list[dict[str, Any]], list[str]]:
        """Apply what may be applied; ``(values to answer with, refusals to tell the viewer)``:
        the value asked for when it was taken, the current one when refused."""
        ...


class _Viewer:
    """One connected viewer: its subscriptions and its backlog."""

    def __init__(self, conn: ServerConnection, number: int) -> None:
        self.conn = conn
        peer = conn.remote_address
        self.label = f"#{number} ({peer[0] if peer else '?'})"
        self.sub_of_channel: dict[int, int] = {}  #: channel id -> subscription id
        self.data: deque[tuple[int, bytes]] = deque()  #: (channel id, frame), oldest first
        self.data_bytes = 0
        self.control: deque[str] = deque()
        self.wake = asyncio.Event()
        self.dropped = 0
        self.budget = MessageBudget()

    def push_control(self, text: str) -> None:
        self.control.append(text)
        self.wake.set()

    def push_data(self, channel_id: int, frame: bytes) -> None:
        """Hold ``frame``; when the backlog is full, drop the oldest frame of the same channel
        (a stream replaces its own old samples), else the oldest frame of the channel holding the
        most bytes (the oldest of all would starve whichever channel happens to be in front:
        under load a viewer got no contours while images flowed)."""
        while self.data and (
            len(self.data) >= MAX_VIEWER_BACKLOG
            or self.data_bytes + len(frame) > MAX_VIEWER_BACKLOG_BYTES
        ):
            self._drop(channel_id)
        self.data.append((channel_id, frame))
        self.data_bytes += len(frame)
        self.wake.set()

    def _drop(self, channel_id: int) -> None:
        held_bytes: dict[int, int] = {}
        for held, f in self.data:
            held_bytes[held] = held_bytes.get(held, 0) + len(f)
        victim = (
            channel_id if channel_id in held_bytes else max(held_bytes, key=held_bytes.__getitem__)
        )
        at = next(i for i, (held, _f) in enumerate(self.data) if held == victim)
        self.data_bytes -= len(self.data[at][1])
        del self.data[at]
        self.dropped += 1

    def pop(self) -> str | bytes:
        """The next message to send: control first (advertisements before data)."""
        if self.control:
            return self.control.popleft()
        frame = self.data.popleft()[1]
        self.data_bytes -= len(frame)
        return frame


class ViewerServer:
    """The Foxglove WebSocket server of a run (see the module docstring)."""

    def __init__(
        self,
        *,
        name: str,
        host: str,
        port: int,
        token: str,
        origins: Iterable[str],
        parameters: ParameterHandler,
        log: logging.Logger | None = None,
        connections: Connections | None = None,
    ) -> None:
        """``connections``: the door's table (the declared limits when None; a test gives
        smaller ones)."""
        self.name, self.host, self.token = name, host, token
        self._origins = origin_netlocs(origins)
        self._parameters = parameters
        self._log = log or logging.getLogger("umbra.foxglove")
        self._session = str(time.time_ns())
        self._channels: dict[int, protocol.ChannelInfo] = {}
        self._ids = itertools.count(1)
        self._viewers: set[_Viewer] = set()
        self._numbers = itertools.count(1)
        self._watched: dict[int, int] = {}  #: channel id -> viewers subscribed
        #: the door's connection table (shared rules: :mod:`umbra.connectors.access.door`) and
        #: every refusal, counted and said at most once a second
        self.connections = connections or Connections(Refusals(self._log, "foxglove"))
        self.refusals = self.connections.refusals
        self.passed = 0
        self.dropped = 0
        self.cut_off = 0  #: viewers closed over their message budget (rate, burst, malformed)
        self._loop = asyncio.new_event_loop()
        self._server = self._loop.run_until_complete(self._start(port))
        self.port = self._server.sockets[0].getsockname()[1]
        self._hosts = allowed_hosts(host, self.port)
        self._thread = threading.Thread(target=self._loop.run_forever, name="umbra-fox-server")
        self._thread.daemon = True
        self._thread.start()

    async def _start(self, port: int) -> DoorServer:
        """Listen on ``host``:``port`` behind the door (:mod:`umbra.runtime.live.door`)."""
        loop = asyncio.get_running_loop()
        table = self.connections
        logger = _Quiet(self._log.getChild("socket"), {})
        server = DoorServer(
            self._serve,
            process_request=self._check,
            server_header=None,
            # the door closes a request head late at table.head_s; this bounds the rest of the
            # handshake (an answer that cannot be sent)
            open_timeout=2 * table.head_s,
            logger=logger,
        )
        connection = connection_class(table)

        def factory() -> ServerConnection:
            # no extensions: JPEG and protobuf, deflate would cost CPU for little
            sans_io = ServerProtocol(
                subprotocols=[Subprotocol(name) for name in protocol.SUBPROTOCOLS],
                max_size=MAX_VIEWER_MESSAGE_BYTES,
                logger=logger,
            )
            # close_timeout: a viewer that does not answer the closing handshake is cut off
            return connection(sans_io, server, max_queue=4, close_timeout=2.0)

        sock = _listening_socket(self.host, port, table.backlog)
        try:
            server.wrap(await loop.create_server(factory, sock=sock, start_serving=False))
        except BaseException:
            sock.close()
            raise
        DoorListener(loop, sock, table, factory).start()
        return server

    @property
    def url(self) -> str:
        """The address a viewer opens: ``ws://HOST:PORT/?token=...``."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"ws://{host}:{self.port}/?{TOKEN_QUERY}={self.token}"

    # -- from any thread ---------------------------------------------------------------------
    def add_channel(
        self, topic: str, encoding: str, schema_name: str, schema_encoding: str, schema: bytes
    ) -> int:
        """Advertise a channel to every viewer (and to those that come); its id."""
        info = protocol.ChannelInfo(
            next(self._ids), topic, encoding, schema_name, schema_encoding, schema
        )
        self._channels[info.id] = info
        self._loop.call_soon_threadsafe(self._broadcast, protocol.advertise([info]))
        return info.id

    @property
    def refused(self) -> int:
        """Connections refused: over a limit, half-open, a broken handshake, or an upgrade the
        gate refused (token, Host, Origin, too many viewers)."""
        return self.refusals.total  # the connection table tells the same counts

    @property
    def viewers(self) -> int:
        """Viewers connected now."""
        return len(self._viewers)

    def watched(self, channel_id: int) -> bool:
        """Whether a viewer subscribes to the channel (a look-up: any thread, never waits)."""
        return self._watched.get(channel_id, 0) > 0

    def publish(self, channel_id: int, log_time_ns: int, payload: bytes) -> None:
        """Send ``payload`` on the channel to the viewers subscribed; never waits."""
        if self._watched.get(channel_id, 0) > 0:
            self._loop.call_soon_threadsafe(self._fan_out, channel_id, log_time_ns, payload)

    def close(self) -> None:
        """Close every viewer's socket, stop listening, end the thread."""

        async def stop() -> None:
            self._server.close()
            await self._server.wait_closed()

        with contextlib.suppress(Exception):
            asyncio.run_coroutine_threadsafe(stop(), self._loop).result(timeout=3.0)
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(timeout=2.0)

    # -- the server's loop --------------------------------------------------------------------
    def _check(self, conn: ServerConnection, request: Request) -> Response | None:
        hosts, origins = request.headers.get_all("Host"), request.headers.get_all("Origin")
        if len(hosts) != 1 or len(origins) > 1:
            why: tuple[int, str] | None = (400, "expected one Host and at most one Origin")
        elif len(self._viewers) >= MAX_VIEWERS:
            why = (503, f"already {MAX_VIEWERS} viewers")
        else:
            origin = origins[0] if origins else None
            hosts_ok, origins_ok = self._hosts, self._origins
            why = refusal(request.path, hosts[0], origin, self.token, hosts_ok, origins_ok)
        if why is None:
            return None
        client = peer_address(conn.transport)
        self.refusals.add(str(why[0]), f"a viewer from {client} ({why[0]}): {why[1]}")
        return conn.respond(why[0], why[1] + "\n")

    def _broadcast(self, text: str) -> None:
        for viewer in self._viewers:
            viewer.push_control(text)

    def _fan_out(self, channel_id: int, log_time_ns: int, payload: bytes) -> None:
        for viewer in self._viewers:
            sub = viewer.sub_of_channel.get(channel_id)
            if sub is not None:
                before = viewer.dropped
                viewer.push_data(channel_id, protocol.message_data(sub, log_time_ns, payload))
                self.dropped += viewer.dropped - before

    async def _serve(self, conn: ServerConnection) -> None:
        viewer = _Viewer(conn, next(self._numbers))
        with contextlib.suppress(AttributeError, OSError):  # the kernel's share of the backlog
            sock = conn.transport.get_extra_info("socket")
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, SOCKET_BUFFER)
        self._viewers.add(viewer)
        self.passed += 1
        self._log.info("foxglove: viewer connected: %s", viewer.label)
        viewer.push_control(protocol.server_info(self.name, self._session))
        viewer.push_control(protocol.advertise(list(self._channels.values())))
        sender = asyncio.create_task(self._send(viewer))
        try:
            async for message in conn:
                why = viewer.budget.spend(time.monotonic()) or self._handle(viewer, message)
                if why:
                    self.cut_off += 1
                    self._log.warning("foxglove: closed viewer %s: %s", viewer.label, why)
                    await conn.close(1008, why[:120])
                    break
                if len(viewer.control) > MAX_VIEWER_BACKLOG:  # asks, never reads the answers
                    await conn.close(1008, "too many answers waiting to be read")
                    break
        except ConnectionClosed:
            pass
        finally:
            sender.cancel()
            self._viewers.discard(viewer)
            for channel_id in viewer.sub_of_channel:
                self._watched[channel_id] -= 1
            self._log.info("foxglove: viewer left: %s", viewer.label)

    async def _send(self, viewer: _Viewer) -> None:
        with contextlib.suppress(ConnectionClosed):
            while True:
                await viewer.wake.wait()
                viewer.wake.clear()
                while viewer.control or viewer.data:
                    await viewer.conn.send(viewer.pop())

    def _handle(self, viewer: _Viewer, message: str | bytes) -> str:
        """Answer one message; "" or why the viewer's socket must close (too many malformed)."""
        try:
            if isinstance(message, bytes):
                raise ValueError("expected a JSON text message (this server takes no data)")
            request = protocol.read_request(message)
            self._answer(viewer, request)
        except ValueError as exc:
            why = viewer.budget.spoiled()
            if not why:
                viewer.push_control(protocol.status(protocol.ERROR, str(exc)))
            return why
        return ""

    def _answer(self, viewer: _Viewer, request: dict[str, Any]) -> None:
        op = request["op"]
        if op == "subscribe":
            wrong = []
            for sub, channel_id in protocol.subscriptions(request):
                if channel_id not in self._channels or channel_id in viewer.sub_of_channel:
                    wrong.append(channel_id)  # the others of the request still count
                    continue
                viewer.sub_of_channel[channel_id] = sub
                self._watched[channel_id] = self._watched.get(channel_id, 0) + 1
            if wrong:
                raise ValueError(f"no channel {wrong} to subscribe to, or subscribed already")
        elif op == "unsubscribe":
            gone = set(protocol.subscription_ids(request))
            for channel_id, sub in list(viewer.sub_of_channel.items()):
                if sub in gone:
                    del viewer.sub_of_channel[channel_id]
                    self._watched[channel_id] -= 1
        elif op == "getParameters":
            found = self._parameters.get(protocol.parameter_names(request))
            viewer.push_control(protocol.parameter_values(found, protocol.request_id(request)))
        elif op == "setParameters":
            changes = protocol.parameter_changes(request)
            answer, refusals = self._parameters.set(f"foxglove viewer {viewer.label}", changes)
            for why in refusals:
                viewer.push_control(protocol.status(protocol.ERROR, why))
            viewer.push_control(protocol.parameter_values(answer, protocol.request_id(request)))
        else:
            raise ValueError(f"`{op}` is not served here (read only: subscribe, parameters)")
