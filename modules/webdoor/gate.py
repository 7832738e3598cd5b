"""The ASGI middleware in front of every route and socket of a page server.

In this order, for HTTP requests and websockets alike:

1. ``Host`` must name this server (:mod:`umbra.connectors.access.hosts`), else 421: a DNS-rebinding
   page sends its own name.
2. ``Origin``, when present, must be one of this server's own pages, else 403: another site open
   in the operator's browser gets nothing.
3. The access token: in the cookie, or in the address (``?token=``). A GET whose address carries
   it is answered with the cookie (HttpOnly, SameSite=Strict) and a redirect to the same address
   without it, so it leaves the address bar and the history. State-changing requests (POST...)
   need the cookie *and* either the page's own ``Origin`` or the :data:`CSRF_HEADER` (a header
   another site's page cannot send without a CORS grant, which this server never gives).
4. A request body is refused past :data:`~umbra.connectors.limits.MAX_PAGE_BODY_BYTES` before it is
   read (``Content-Length``, then counting a streamed body), and must arrive whole within
   :data:`~umbra.connectors.limits.MAX_PAGE_REQUEST_S`; the route then gets it from memory.

It also gives each browser its viewer cookie (:mod:`umbra.modules.webdoor.viewer`) and leaves the
request's viewer key in ``scope[VIEWER_SCOPE]``. Refusals are counted; the log says each kind
at most once a second (the door's :class:`~umbra.connectors.access.door.Refusals`: a flood of
refusals is not a flood of log lines).
"""

from __future__ import annotations

import asyncio
import time
from typing import Any
from urllib.parse import parse_qsl, urlencode

from umbra.connectors.access.door import Refusals
from umbra.connectors.access.hosts import host_allowed, origin_allowed
from umbra.connectors.access.secret import CSRF_HEADER, TOKEN_COOKIE, TOKEN_QUERY, token_matches
from umbra.connectors.limits import MAX_PAGE_BODY_BYTES, MAX_PAGE_REQUEST_S
from umbra.modules.webdoor.viewer import VIEWER_COOKIE, VIEWER_SCOPE, new_viewer_id, viewer_key

__all__ = ["Gate", "Refusals"]

_SAFE_METHODS = ("GET", "HEAD", "OPTIONS")
_COOKIE = "Path=/; HttpOnly; SameSite=Strict"


class Gate:
    """ASGI middleware: ``app`` behind the door of a server with ``token`` answering to
    ``allowed`` hosts (see the module docstring)."""

    def __init__(
        self, app: Any, token: str, allowed: frozenset[str], cookie: str = TOKEN_COOKIE
    ) -> None:
        """``cookie``: the name of the token's cookie (a browser sends a cookie to every port
        of a host: a second server of the machine with a token of its own names its own)."""
        if not token:
            raise ValueError("a page server needs an access token")
        self.app = app
        self.token = token
        self.allowed = allowed
        self.cookie = cookie
        self.refusals = Refusals()

    async def __call__(self, scope: dict, receive: Any, send: Any) -> None:
        kind = scope["type"]
        if kind not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        refusal = self.check(scope)
        if refusal is not None:
            status, reason, text = refusal
            client = (scope.get("client") or ("?", 0))[0]
            self.refusals.add(reason, f"{kind} {scope.get('path', '')} from {client}: {text}")
            if kind == "http":
                await _drain_small_body(scope, receive)
            await _refuse(kind, send, status, text)
            return
        query = _query(scope)
        if kind == "http" and scope.get("method") == "GET" and TOKEN_QUERY in query:
            await self._exchange(scope, send, query)
            return
        scope[VIEWER_SCOPE] = viewer_key(_cookie(scope, VIEWER_COOKIE))
        if kind == "http":
            body = await self._body(scope, receive, send)
            if body is None:
                return
            receive = _replay(body, receive)
            if not scope[VIEWER_SCOPE]:
                send = _with_cookie(send, f"{VIEWER_COOKIE}={new_viewer_id()}; {_COOKIE}")
        await self.app(scope, receive, send)

    def check(self, scope: dict) -> tuple[int, str, str] | None:
        """(status, reason, text) of a refusal, or None to let the request in (``scope``: an
        ASGI scope's ``type``, ``method``, ``query_string`` and ``headers`` suffice)."""
        host = _header(scope, b"host")
        if not host_allowed(host, self.allowed):
            return (
                421,
                "host",
                f"expected a Host this server was started for ({', '.join(sorted(self.allowed))}),"
                f" found {host!r}",
            )
        origin = _header(scope, b"origin")
        if not origin_allowed(origin, self.allowed):
            return 403, "origin", f"a request from another site's page (Origin {origin!r})"
        cookie = _cookie(scope, self.cookie)
        if scope["type"] == "http" and scope.get("method") not in _SAFE_METHODS:
            if not token_matches(self.token, cookie):
                return 403, "token", "expected the access token's cookie on a POST, found none"
            if origin is None and _header(scope, CSRF_HEADER.encode()) is None:
                return (
                    403,
                    "csrf",
                    f"expected the page's own Origin or the {CSRF_HEADER} header on a POST, "
                    "found neither",
                )
            return None
        given = _query(scope).get(TOKEN_QUERY)
        if token_matches(self.token, cookie) or token_matches(self.token, given):
            return None
        return (
            403,
            "token",
            "this page needs its access token: open the address printed at start (it ends in "
            f"?{TOKEN_QUERY}=...); found {'a wrong one' if cookie or given else 'none'}",
        )

    async def _exchange(self, scope: dict, send: Any, query: dict[str, str]) -> None:
        """The token of the address for a cookie, and a redirect to the address without it."""
        headers = self.exchange_headers(scope, query)
        await send({"type": "http.response.start", "status": 303, "headers": headers})
        await send({"type": "http.response.body", "body": b""})

    def exchange_headers(self, scope: dict, query: dict[str, str]) -> list[tuple[bytes, bytes]]:
        """The headers of the 303 that trades the address's token (``query``) for the cookie:
        the address without it, and the cookies (token, viewer) the browser lacks."""
        rest = urlencode([(k, v) for k, v in query.items() if k != TOKEN_QUERY])
        path = (scope.get("raw_path") or scope.get("path", "/").encode()).decode("latin-1")
        path = "/" + path.lstrip("/\\")  # this server's path: never //another.host/
        headers = [
            (b"location", (path + (f"?{rest}" if rest else "")).encode("latin-1")),
            (b"cache-control", b"no-store"),
            (b"referrer-policy", b"no-referrer"),
        ]
        if token_matches(self.token, query.get(TOKEN_QUERY)):  # (else it came with the cookie)
            headers.append((b"set-cookie", f"{self.cookie}={self.token}; {_COOKIE}".encode()))
        if not viewer_key(_cookie(scope, VIEWER_COOKIE)):
            headers.append(
                (b"set-cookie", f"{VIEWER_COOKIE}={new_viewer_id()}; {_COOKIE}".encode())
            )
        return headers

    async def _body(self, scope: dict, receive: Any, send: Any) -> bytes | None:
        """The whole request body, or None once a refusal was sent (too large, too slow)."""
        length = _header(scope, b"content-length")
        if length is not None:
            if not length.strip().isdigit():
                await self._refuse_body(scope, send, 400, f"Content-Length {length!r}")
                return None
            if int(length) > MAX_PAGE_BODY_BYTES:
                await self._refuse_body(scope, send, 413, f"{int(length)} bytes")
                return None
        body, problem = await _read_body(receive, MAX_PAGE_REQUEST_S)
        if problem == "late":
            await self._refuse_body(scope, send, 408, f"more than {MAX_PAGE_REQUEST_S:g} s")
        elif problem:
            await self._refuse_body(scope, send, 413, f"{problem} (streamed)")
        return body

    async def _refuse_body(self, scope: dict, send: Any, status: int, found: str) -> None:
        text = (
            f"expected a request body of at most {MAX_PAGE_BODY_BYTES} bytes arriving within "
            f"{MAX_PAGE_REQUEST_S:g} s, found {found}"
        )
        client = (scope.get("client") or ("?", 0))[0]
        self.refusals.add(f"body{status}", f"{scope.get('path', '')} from {client}: {text}")
        await _refuse("http", send, status, text)


#: Longest a refused request's small body is read for before the refusal closes the connection
#: [s]: a close with unread bytes resets it, and the client loses the refusal's text.
DRAIN_S = 0.5


async def _drain_small_body(scope: dict, receive: Any) -> None:
    """Read (and drop) a refused request's body when it declares one of at most
    ``MAX_PAGE_BODY_BYTES``, for at most ``DRAIN_S``: nothing larger or slower is waited for."""
    length = _header(scope, b"content-length")
    if length is not None and length.strip().isdigit() and int(length) <= MAX_PAGE_BODY_BYTES:
        await _read_body(receive, DRAIN_S)


async def _read_body(receive: Any, seconds: float) -> tuple[bytes | None, str]:
    """A request's body as it streams in, read for at most ``seconds`` and at most
    ``MAX_PAGE_BODY_BYTES``: ``(body, "")``, or ``(None, "late")`` / ``(None, "over N bytes")``.
    A client that disconnects leaves the body read so far (a route sees it empty or cut)."""
    chunks: list[bytes] = []
    size = 0
    deadline = time.monotonic() + seconds
    while True:
        try:
            message = await asyncio.wait_for(receive(), deadline - time.monotonic())
        except TimeoutError:
            return None, "late"
        if message["type"] != "http.request":
            return b"".join(chunks), ""  # disconnected
        chunk = message.get("body", b"")
        size += len(chunk)
        if size > MAX_PAGE_BODY_BYTES:
            return None, f"over {size} bytes"
        chunks.append(chunk)
        if not message.get("more_body", False):
            return b"".join(chunks), ""


async def _refuse(kind: str, send: Any, status: int, text: str) -> None:
    if kind == "websocket":  # before the handshake is accepted: the client gets HTTP 403
        await send({"type": "websocket.close", "code": 4000 + status, "reason": text[:120]})
        return
    await send(
        {
            "type": "http.response.start",
            "status": status,
            "headers": [
                (b"content-type", b"text/plain; charset=utf-8"),
                (b"connection", b"close"),
                (b"cache-control", b"no-store"),
            ],
        }
    )
    await send({"type": "http.response.body", "body": f"{status} refused: {text}\n".encode()})


def _replay(body: bytes, receive: Any) -> Any:
    """``receive`` that gives ``body`` whole once, then waits on the connection."""
    sent = False

    async def replay() -> dict:
        nonlocal sent
        if not sent:
            sent = True
            return {"type": "http.request", "body": body, "more_body": False}
        return await receive()

    return replay


def _with_cookie(send: Any, cookie: str) -> Any:
    """``send`` that adds a Set-Cookie header to the response."""

    async def wrapped(message: dict) -> None:
        if message["type"] == "http.response.start":
            headers = [*message.get("headers", []), (b"set-cookie", cookie.encode("latin-1"))]
            message = {**message, "headers": headers}
        await send(message)

    return wrapped


def _header(scope: dict, name: bytes) -> str | None:
    for key, value in scope.get("headers", []):
        if key == name:
            return value.decode("latin-1")
    return None


def _query(scope: dict) -> dict[str, str]:
    return dict(parse_qsl(scope.get("query_string", b"").decode("latin-1")))


def _cookie(scope: dict, wanted: str) -> str | None:
    for name, value in scope.get("headers", []):
        if name == b"cookie":
            for part in value.decode("latin-1").split(";"):
                key, _, val = part.strip().partition("=")
                if key == wanted:
                    return val
    return None
