"""The live server's socket behind the door's connection rules (``websockets``, asyncio).

The same rules as the operator pages' servers (:mod:`umbra.connectors.access.door`), applied
where they cost least, since the live server shares its process (and the GIL) with a run's
servo loop:

- :class:`DoorListener` accepts on the listening socket itself: each connection is admitted or
  refused by the server's :class:`~umbra.connectors.access.door.Connections` table (per server
  and per client address) as it is accepted, before a transport, a protocol, a task or a
  handshake exists. One over a limit is closed there with a reset (a few microseconds, its
  descriptor freed at once); only admitted ones are handed to ``websockets``.
- :func:`connection_class`: ``websockets``' connection of an admitted socket; an upgrade request
  that has not arrived whole within the table's deadline is closed (half-open), one longer than
  the table's head size or garbled is aborted at once, and a handshake a client gets wrong is
  counted and said at most once a second (``websockets`` would log each with a traceback). One
  the client breaks off is simply over.
- :class:`DoorServer`: ``websockets``' server (its documented ``Server`` and ``wrap``) fed by
  the listener rather than by asyncio's own accept.
"""

from __future__ import annotations

import asyncio
import contextlib
import socket
from collections.abc import Callable
from typing import Any

from websockets.asyncio.server import Server, ServerConnection
from websockets.exceptions import ConnectionClosed

from umbra.connectors.access.door import Connections, peer_address

#: Seconds the listener rests when the process is out of descriptors (or the like) for accepts.
ACCEPT_RETRY_S = 0.1
#: Seconds the listener rests after a full batch of accepts (a flood): what a flood may take of
#: the server's thread, and of the GIL it shares with the run, is bounded (the kernel's queue
#: holds the next ones meanwhile, and drops what does not fit).
ACCEPT_REST_S = 0.01


class DoorServer(Server):
    """``websockets``' server whose connections come from a :class:`DoorListener`: serving while
    its listener is open (asyncio's own server, made with ``start_serving=False``, never is)."""

    listening = True

    def is_serving(self) -> bool:
        return self.listening

    def close(self, *args: Any, **kwargs: Any) -> None:
        self.listening = False
        super().close(*args, **kwargs)


class DoorListener:
    """Accepts on ``sock`` (listening, non-blocking) on ``loop``: admitted connections go to
    ``factory``'s protocol (asyncio's ``connect_accepted_socket``), the others are closed as they
    are accepted. At most ``table.backlog`` accepts per turn of the loop, and after so many a rest
    of :data:`ACCEPT_REST_S`."""

    def __init__(
        self,
        loop: asyncio.AbstractEventLoop,
        sock: socket.socket,
        table: Connections,
        factory: Callable[[], asyncio.Protocol],
    ) -> None:
        self._loop, self._sock, self._table, self._factory = loop, sock, table, factory
        self._handing: set[asyncio.Task[None]] = set()

    def start(self) -> None:
        """Accept from now on (the loop's thread)."""
        if self._sock.fileno() >= 0:
            self._loop.add_reader(self._sock.fileno(), self._accept)

    def _accept(self) -> None:
        table = self._table
        for _ in range(table.backlog):
            try:
                conn, peer = self._sock.accept()
            except (BlockingIOError, InterruptedError):
                return
            except OSError as exc:  # out of descriptors, or the like: rest, then again
                table.refusals.add("accept", f"connections for now: cannot accept ({exc})")
                self._rest(ACCEPT_RETRY_S)
                return
            if table.admit_socket(conn, str(peer[0]) if peer else "?"):
                conn.setblocking(False)
                task = self._loop.create_task(self._hand_over(conn))
                self._handing.add(task)
                task.add_done_callback(self._handing.discard)
        self._rest(ACCEPT_REST_S)  # a full batch: more are waiting

    def _rest(self, seconds: float) -> None:
        """Stop accepting for ``seconds``."""
        self._loop.remove_reader(self._sock.fileno())
        self._loop.call_later(seconds, self.start)

    async def _hand_over(self, conn: socket.socket) -> None:
        try:
            await self._loop.connect_accepted_socket(self._factory, conn)
        except OSError:  # gone before it was served
            self._table.release_socket(conn)
            conn.close()


def connection_class(table: Connections) -> type[ServerConnection]:
    """``websockets``' connection class of a server whose sockets ``table`` admitted."""

    class DoorConnection(ServerConnection):
        _head_bytes = 0
        _head_timer: asyncio.TimerHandle | None = None

        def connection_made(self, transport: asyncio.BaseTransport) -> None:
            super().connection_made(transport)
            self._head_timer = self.loop.call_later(table.head_s, self._head_late)

        def _head_late(self) -> None:
            if self.request is None:  # no whole upgrade request yet
                table.late(self.transport)

        def process_event(self, event: Any) -> None:
            if self.request is None and self._head_timer is not None:
                self._head_timer.cancel()
            super().process_event(event)

        def data_received(self, data: bytes) -> None:
            if self.request is None:
                self._head_bytes += len(data)
                if self._head_bytes > table.head_bytes:
                    self._refuse(f"a request head of at most {table.head_bytes} bytes")
                    return
            super().data_received(data)
            if self.request is None and self.protocol.handshake_exc is not None:
                self._refuse("an HTTP request")  # garbled: the protocol reads no more of it

        def _refuse(self, expected: str) -> None:
            client, found = peer_address(self.transport), self._head_bytes
            table.refusals.add(
                "handshake",
                lambda: (
                    f"a handshake from {client}: expected {expected}, found {found} bytes "
                    "of something else"
                ),
            )
            self.transport.abort()

        def connection_lost(self, exc: Exception | None) -> None:
            with contextlib.suppress(AttributeError, OSError):
                table.release_socket(self.transport.get_extra_info("socket"))
            if self._head_timer is not None:
                self._head_timer.cancel()
            super().connection_lost(exc)

        async def handshake(self, *args: Any, **kwargs: Any) -> None:
            try:
                await super().handshake(*args, **kwargs)
            except Exception as exc:  # the client's doing: closed (the server sees it not open)
                if self.transport.is_closing() or isinstance(exc, ConnectionClosed):
                    return  # cut short by the client, or closed by the door (counted there)
                client, found = peer_address(self.transport), f"{type(exc).__name__}: {exc}"
                table.refusals.add(
                    "handshake",
                    f"a handshake from {client}: expected a WebSocket upgrade request, "
                    f"found {found}",
                )

    return DoorConnection
