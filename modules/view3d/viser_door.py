"""The door of the viser 3-D view: the operator pages' rules (:mod:`umbra.modules.webdoor`) on
viser's own server, which has no hook for them.

viser serves its page and its websocket from one ``websockets`` server. Before the first browser
can connect, :func:`guard_viser` puts :class:`ViserDoor` in front of that server's handshake
(its ``process_request``): the same :class:`~umbra.modules.webdoor.gate.Gate` checks as every other
page of a run (``Host`` named for this server, the page's own ``Origin``, the per-run token from
the address or its cookie), the address's token traded for an HttpOnly cookie by a redirect, and
everything else passed to viser. The cookie is named for the port (a browser sends a host's
cookies to all its ports, and the console next to it has a token of its own).
"""

from __future__ import annotations

import gc
import http
from typing import Any
from urllib.parse import parse_qsl

from websockets.asyncio.server import Server, ServerConnection
from websockets.datastructures import Headers
from websockets.http11 import Request, Response

from umbra.connectors.access.hosts import allowed_hosts
from umbra.connectors.access.secret import TOKEN_COOKIE, TOKEN_QUERY
from umbra.modules.webdoor.gate import Gate


class ViserDoor:
    """The handshake check of a viser server on ``host``:``port`` with the access ``token``;
    ``inner``: viser's own request handler (its page files), called for what passes."""

    def __init__(self, token: str, host: str, port: int, inner: Any) -> None:
        self.gate = Gate(None, token, allowed_hosts(host, port), f"{TOKEN_COOKIE}_{port}")
        self.inner = inner

    @property
    def refused(self) -> int:
        """Requests and sockets refused."""
        return self.gate.refusals.total

    def __call__(self, connection: ServerConnection, request: Request) -> Response | None:
        path, _, query = request.path.partition("?")
        websocket = request.headers.get("Upgrade", "").lower() == "websocket"
        scope = {
            "type": "websocket" if websocket else "http",
            "method": "GET",
            "path": path,
            "query_string": query.encode("latin-1"),
            "headers": [
                (k.lower().encode("latin-1"), v.encode("latin-1"))
                for k, v in request.headers.raw_items()
            ],
        }
        refusal = self.gate.check(scope)
        if refusal is not None:
            status, reason, text = refusal
            self.gate.refusals.add(reason, f"3-D view {path} from {_client(connection)}: {text}")
            return connection.respond(http.HTTPStatus(status), text + "\n")
        fields = dict(parse_qsl(query))
        if not websocket and TOKEN_QUERY in fields:
            headers = Headers(
                (k.decode("latin-1"), v.decode("latin-1"))
                for k, v in self.gate.exchange_headers(scope, fields)
            )
            return Response(303, "See Other", headers, b"")
        return None if self.inner is None else self.inner(connection, request)


def _client(connection: ServerConnection) -> str:
    try:
        return str(connection.remote_address[0])
    except (TypeError, IndexError, AttributeError):
        return "?"


def guard_viser(port: int, token: str, host: str) -> ViserDoor:
    """Put a :class:`ViserDoor` in front of the started viser server listening on ``port``
    (found among the live ``websockets`` servers of this process). Call it right after the
    ``ViserServer`` is made, before its address is given to anyone.

    The live objects are told apart by ``type()``, never ``isinstance``: that asks an object for
    its ``__class__``, and some objects of other libraries raise on any attribute (canopen's
    placeholder network does)."""
    for obj in gc.get_objects():
        if issubclass(type(obj), Server) and any(
            sock.getsockname()[1] == port for sock in obj.server.sockets or ()
        ):
            door = ViserDoor(token, host, port, obj.process_request)
            obj.process_request = door
            return door
    raise RuntimeError(f"no websockets server of viser listens on port {port}")
