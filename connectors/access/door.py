"""The door's connection rules: one declaration for every web server of a run.

The operator pages' servers (uvicorn: :mod:`umbra.modules.webdoor.transport`, from asyncio's
``connection_made``) and the live server (websockets: :mod:`umbra.runtime.live.door`, as it
accepts) take each TCP connection through a :class:`Connections` table of their own, before a
byte is parsed, a task started or a token looked at.

- At most :data:`~umbra.connectors.limits.MAX_PAGE_CONNECTIONS` connections open to one server
  and :data:`~umbra.connectors.limits.MAX_PAGE_CONNECTIONS_PER_CLIENT` from one client address,
  held for a connection's whole life whatever it becomes (a request, keep-alive, a websocket).
  One over is closed at once with a reset (:meth:`Connections.admit`,
  :meth:`Connections.admit_socket`): it costs no parser, no task, no handshake. The listening
  socket queues and accepts at once at most
  :data:`~umbra.connectors.limits.MAX_PAGE_ACCEPT_BACKLOG` (:attr:`Connections.backlog`).
- A request head (an HTTP request, a websocket upgrade) must arrive whole within
  :data:`~umbra.connectors.limits.MAX_PAGE_REQUEST_S` of the connection (:meth:`Connections.late`
  closes a half-open one: slowloris, or a connection that never sends a byte), and in at most
  :data:`~umbra.connectors.limits.MAX_PAGE_HEAD_BYTES`.
- Every refusal is counted by kind (:class:`Refusals`), and the log says each kind at most once a
  second, in one line and never with a traceback: a flood of refusals is not a flood of log
  lines, nor of work for the process that serves.

Bookkeeping on the server's event loop; the transports and sockets are asyncio's.
"""

from __future__ import annotations

import contextlib
import logging
import socket
import struct
import time
from collections import Counter
from collections.abc import Callable, Hashable
from typing import Any

from umbra.connectors.limits import (
    MAX_PAGE_ACCEPT_BACKLOG,
    MAX_PAGE_CONNECTIONS,
    MAX_PAGE_CONNECTIONS_PER_CLIENT,
    MAX_PAGE_HEAD_BYTES,
    MAX_PAGE_REQUEST_S,
)

#: How often the log may say one kind of refusal [s].
LOG_PERIOD_S = 1.0
#: ``SO_LINGER`` on, 0 s: ``close`` resets the connection and frees its descriptor at once.
_RESET = struct.pack("ii", 1, 0)


class Refusals:
    """Refusals by kind; the log (``log``, each line starting with ``label``) says each kind at
    most once per ``period`` [s], with how many more like it were refused meanwhile."""

    def __init__(
        self,
        log: logging.Logger | None = None,
        label: str = "page server",
        period: float = LOG_PERIOD_S,
    ) -> None:
        self.counts: Counter[str] = Counter()
        self.period = period
        self._log = log or logging.getLogger("umbra.webdoor")
        self._label = label
        self._logged: dict[str, tuple[float, int]] = {}

    @property
    def total(self) -> int:
        return sum(self.counts.values())

    def add(self, reason: str, detail: str | Callable[[], str]) -> None:
        """Count one refusal of kind ``reason``; ``detail`` says what was refused and why (a
        function making the text: called only when the line is logged)."""
        self.counts[reason] += 1
        now = time.monotonic()
        last, count = self._logged.get(reason, (-float("inf"), 0))
        if now - last >= self.period:
            more = self.counts[reason] - count - 1
            self._log.warning(
                "%s: refused %s%s",
                self._label,
                detail if isinstance(detail, str) else detail(),
                f" (and {more} more like it)" if more > 0 else "",
            )
            self._logged[reason] = (now, self.counts[reason])


def peer_address(transport: Any) -> str:
    """The client address of an asyncio transport ("?" when the socket has none)."""
    try:
        peer = transport.get_extra_info("peername")
    except (AttributeError, OSError):
        return "?"
    return str(peer[0]) if peer else "?"


def _socket_key(sock: Any) -> tuple[str, int]:
    """The table's key of an open socket (its descriptor's number)."""
    return ("socket", sock.fileno())


class Connections:
    """Open connections of one server by transport, and per client address (the server's event
    loop only); its refusals are told to ``refusals``."""

    def __init__(
        self,
        refusals: Refusals | None = None,
        limit: int = MAX_PAGE_CONNECTIONS,
        per_client: int = MAX_PAGE_CONNECTIONS_PER_CLIENT,
        head_s: float = MAX_PAGE_REQUEST_S,
        head_bytes: int = MAX_PAGE_HEAD_BYTES,
        backlog: int = MAX_PAGE_ACCEPT_BACKLOG,
    ) -> None:
        self.refusals = refusals if refusals is not None else Refusals()
        self.limit = limit
        self.per_client = per_client
        self.head_s = head_s  #: deadline of a connection's request head [s]
        self.head_bytes = head_bytes  #: largest request head [bytes]
        self.backlog = backlog  #: the listening socket's queue, and accepts at once
        self.open: dict[Hashable, str] = {}  #: a connection's key -> its client address
        self.by_client: Counter[str] = Counter()
        self.refused = 0  #: connections aborted at once, over a limit
        self.half_open = 0  #: connections closed for a request head that never completed
        self.most = 0  #: most connections open at once

    def admit(self, transport: Any) -> bool:
        """Count a new connection (an asyncio transport); over a limit: abort it at once, count
        it, False."""
        if self._enter(id(transport), peer_address(transport)):
            return True
        transport.abort()
        return False

    def admit_socket(self, sock: socket.socket, client: str) -> bool:
        """Count a socket just accepted from ``client``; over a limit: close it at once with a
        reset (its descriptor freed before the next is accepted), count it, False."""
        if self._enter(_socket_key(sock), client):
            return True
        with contextlib.suppress(OSError):
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, _RESET)
        sock.close()
        return False

    def release(self, transport: Any) -> None:
        """A connection ended (idempotent)."""
        self._leave(id(transport))

    def release_socket(self, sock: Any) -> None:
        """A connection counted by :meth:`admit_socket` ended (idempotent; ``sock`` the socket
        or asyncio's wrapper of it, still open)."""
        self._leave(_socket_key(sock))

    def _enter(self, key: Hashable, client: str) -> bool:
        found, theirs = len(self.open), self.by_client[client]
        if found >= self.limit or theirs >= self.per_client:
            self.refused += 1
            self.refusals.add(
                "connections",
                lambda: (
                    f"a connection from {client}: expected at most {self.limit} connections "
                    f"open to this server and {self.per_client} from one address, found {found} "
                    f"({theirs} from {client})"
                ),
            )
            return False
        self.open[key] = client
        self.by_client[client] += 1
        self.most = max(self.most, len(self.open))
        return True

    def _leave(self, key: Hashable) -> None:
        client = self.open.pop(key, None)
        if client is not None:
            self.by_client[client] -= 1
            if self.by_client[client] <= 0:
                del self.by_client[client]

    def late(self, transport: Any) -> None:
        """A connection's request head did not arrive whole within :attr:`head_s`: close it
        (what it was sent meanwhile still goes out), count it."""
        if transport is None or transport.is_closing():
            return
        self.half_open += 1
        client = peer_address(transport)
        self.refusals.add(
            "half-open",
            f"a connection from {client}: expected a whole request head within "
            f"{self.head_s:g} s, found none",
        )
        transport.close()

    @property
    def total(self) -> int:
        """Connections refused or closed by these rules."""
        return self.refused + self.half_open
