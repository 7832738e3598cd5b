"""uvicorn's protocols with the door's connection rules, below HTTP and websockets.

- A connection limit per server (:data:`~umbra.connectors.limits.MAX_PAGE_CONNECTIONS`) and per
  client address (:data:`~umbra.connectors.limits.MAX_PAGE_CONNECTIONS_PER_CLIENT`), held for a
  connection's whole life whatever it becomes (a request, keep-alive, a websocket): one over is
  closed at once, before it costs a parser or a task. uvicorn's own ``limit_concurrency`` answers
  503 to HTTP requests only; a websocket upgrade passes it.
- A request head must arrive whole within :data:`~umbra.connectors.limits.MAX_PAGE_REQUEST_S`: a
  half-open request (slowloris) is closed. uvicorn's ``timeout_keep_alive`` closes a connection
  idle between requests, ``h11_max_incomplete_event_size`` bounds the head, ``ws_max_size`` a
  websocket message; :func:`uvicorn_options` sets them from the same limits.
- A websocket the server closed (an abuser over its budget) reads nothing more: the connection is
  closed at its next byte (stops reading, still sends the close frame), where uvicorn would parse
  what a flooder keeps sending for 10 s more.

:func:`protocols` makes the two protocol classes of one server, bound to its
:class:`Connections` table.
"""

from __future__ import annotations

from collections import Counter
from typing import Any

from uvicorn.protocols.http.h11_impl import H11Protocol
from uvicorn.protocols.websockets.websockets_sansio_impl import WebSocketsSansIOProtocol

from umbra.connectors.limits import (
    MAX_PAGE_CONNECTIONS,
    MAX_PAGE_CONNECTIONS_PER_CLIENT,
    MAX_PAGE_HEAD_BYTES,
    MAX_PAGE_MESSAGE_BYTES,
    MAX_PAGE_REQUEST_S,
)


class Connections:
    """Open connections of one server by transport, and per client address (event loop only)."""

    def __init__(
        self,
        limit: int = MAX_PAGE_CONNECTIONS,
        per_client: int = MAX_PAGE_CONNECTIONS_PER_CLIENT,
    ) -> None:
        self.limit = limit
        self.per_client = per_client
        self.open: dict[int, str] = {}  #: id(transport) -> client address
        self.by_client: Counter[str] = Counter()
        self.refused = 0  #: connections closed at once, over a limit
        self.half_open = 0  #: connections closed for a request head that never completed
        self.most = 0  #: most connections open at once

    def admit(self, transport: Any) -> bool:
        """Count a new connection; False (and counted) when it is over a limit."""
        peer = transport.get_extra_info("peername")
        client = str(peer[0]) if peer else "?"
        if len(self.open) >= self.limit or self.by_client[client] >= self.per_client:
            self.refused += 1
            return False
        self.open[id(transport)] = client
        self.by_client[client] += 1
        self.most = max(self.most, len(self.open))
        return True

    def release(self, transport: Any) -> None:
        """A connection ended (idempotent)."""
        client = self.open.pop(id(transport), None)
        if client is not None:
            self.by_client[client] -= 1
            if self.by_client[client] <= 0:
                del self.by_client[client]


def protocols(table: Connections) -> tuple[type, type]:
    """The HTTP and websocket protocol classes of a server counted in ``table``."""

    class DoorHttp(H11Protocol):
        def connection_made(self, transport: Any) -> None:  # type: ignore[override]
            if not table.admit(transport):
                transport.abort()
                return
            super().connection_made(transport)
            self._head_timer = self.loop.call_later(MAX_PAGE_REQUEST_S, self._head_late)

        def _head_late(self) -> None:
            if self.cycle is None and not self.transport.is_closing():  # no whole head yet
                table.half_open += 1
                self.transport.close()

        def connection_lost(self, exc: Exception | None) -> None:
            table.release(self.transport)
            timer = getattr(self, "_head_timer", None)
            if timer is not None:
                timer.cancel()
            if self.transport is not None:
                super().connection_lost(exc)

        def handle_websocket_upgrade(self, event: Any) -> None:
            self._head_timer.cancel()
            super().handle_websocket_upgrade(event)

    class DoorWebSocket(WebSocketsSansIOProtocol):
        def data_received(self, data: bytes) -> None:
            if self.close_sent:  # the server closed it (an abuser, or stopping): read no more
                self.transport.close()  # stops reading, sends what is buffered (the close frame)
                return
            super().data_received(data)

        def connection_lost(self, exc: Exception | None) -> None:
            table.release(self.transport)
            super().connection_lost(exc)

    return DoorHttp, DoorWebSocket


def uvicorn_options(table: Connections) -> dict[str, Any]:
    """uvicorn.Config options of a page server counted in ``table``."""
    http, ws = protocols(table)
    return {
        "http": http,
        "ws": ws,
        "ws_max_size": MAX_PAGE_MESSAGE_BYTES,
        "ws_max_queue": 16,
        "ws_per_message_deflate": False,  # no compressed messages to inflate
        "h11_max_incomplete_event_size": MAX_PAGE_HEAD_BYTES,
        "timeout_keep_alive": MAX_PAGE_REQUEST_S,
        "limit_concurrency": table.limit + 1,  # uvicorn counts the request itself
        "backlog": 4 * table.limit,
    }
