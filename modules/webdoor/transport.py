"""uvicorn's protocols with the door's connection rules, below HTTP and websockets.

- The door's connection table (:class:`~umbra.connectors.access.door.Connections`, shared with
  the live server): a limit per server and per client address, taken in ``connection_made``
  before anything else; one over is aborted at once, before it costs a parser or a task.
  uvicorn's own ``limit_concurrency`` answers 503 to HTTP requests only; a websocket upgrade
  passes it.
- A request head must arrive whole within the table's deadline
  (:data:`~umbra.connectors.limits.MAX_PAGE_REQUEST_S`): a half-open request (slowloris) is
  closed. uvicorn's ``timeout_keep_alive`` closes a connection idle between requests,
  ``h11_max_incomplete_event_size`` bounds the head, ``ws_max_size`` a websocket message;
  :func:`uvicorn_options` sets them from the same limits.
- A websocket the server closed (an abuser over its budget) reads nothing more: the connection is
  closed at its next byte (stops reading, still sends the close frame), where uvicorn would parse
  what a flooder keeps sending for 10 s more.

:func:`protocols` makes the two protocol classes of one server, bound to its
:class:`~umbra.connectors.access.door.Connections` table.
"""

from __future__ import annotations

from typing import Any

from uvicorn.protocols.http.h11_impl import H11Protocol
from uvicorn.protocols.websockets.websockets_sansio_impl import WebSocketsSansIOProtocol

from umbra.connectors.access.door import Connections
from umbra.connectors.limits import MAX_PAGE_MESSAGE_BYTES

__all__ = ["Connections", "protocols", "uvicorn_options"]


def protocols(table: Connections) -> tuple[type, type]:
    """The HTTP and websocket protocol classes of a server counted in ``table``."""

    class DoorHttp(H11Protocol):
        def connection_made(self, transport: Any) -> None:
            if not table.admit(transport):  # aborted, over a limit
                return
            super().connection_made(transport)
            self._head_timer = self.loop.call_later(table.head_s, self._head_late)

        def _head_late(self) -> None:
            if self.cycle is None:  # no whole head yet
                table.late(self.transport)

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
        "h11_max_incomplete_event_size": table.head_bytes,
        "timeout_keep_alive": table.head_s,
        "limit_concurrency": table.limit + 1,  # uvicorn counts the request itself
        "backlog": table.backlog,
    }
