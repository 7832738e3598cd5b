"""One web server per ``umbra`` process, shared by every module that serves a page.

The console starts it; another module of the same process (the Active Sketch page, say) adds
its own routes to the same server, so the operator has one address. The server is a FastAPI
app served by uvicorn in its own thread (the scheduler owns the main thread); a module's
``step`` never talks to it directly, only through :mod:`modules.operator.mailbox` objects.

Example, in another module of the same process::

    from fastapi.responses import HTMLResponse
    from modules.operator.web_server import acquire_server, release_server

    class SketchPage(Module):
        def start(self) -> None:
            self._server = acquire_server(self.context)          # host/port of the console
            self._server.app.add_api_route("/sketch", self._page, methods=["GET"])
            self._server.add_link("/sketch", "Active Sketch")    # shown on the console

        async def _page(self) -> HTMLResponse:                   # runs in the web thread
            return HTMLResponse("<h1>sketch</h1>")

        def stop(self) -> None:
            release_server(self._server)

Routes added after the server started are served at once. Every route, page and websocket
alike, is behind the access-token gate (:mod:`modules.operator.access`), which also gives each
browser its viewer cookie. The server holds the control table of all its pages
(``server.control``, a :class:`~modules.operator.control.ControlArbiter`): the operator who
holds control on one page holds it on every page of the server, and commands from everyone
else are refused. The server stops when the last module holding it releases it.
"""

from __future__ import annotations

import asyncio
import logging
import socket
import threading
from typing import Any

import uvicorn
from fastapi import FastAPI

from connectors.errors import UserError
from modules.operator.access import (
    TOKEN_COOKIE,
    TOKEN_QUERY,
    VIEWER_COOKIE,
    VIEWER_SCOPE,
    is_loopback,
    new_viewer_id,
    token_matches,
    viewer_key,
)
from modules.operator.control import ControlArbiter

_LOG = logging.getLogger("umbra.operator")


class _TokenGate:
    """ASGI middleware in front of every route: refuses another site's websocket or
    state-changing request (POST...), and HTTP requests and websockets without the access token;
    gives each browser its viewer cookie (one browser, one operator) and, when the token came in
    the address, the token cookie; leaves the request's viewer key in the scope
    (``scope[VIEWER_SCOPE]``, "" when the request carried no viewer cookie)."""

    def __init__(self, app: Any, server: WebServer) -> None:
        self.app = app
        self.server = server

    async def __call__(self, scope: dict, receive: Any, send: Any) -> None:
        kind = scope["type"]
        if kind not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        if kind == "websocket" and not _same_origin(scope):
            self.server.refused_requests += 1
            _LOG.warning(
                "console: refused a websocket from another site's page (Origin %s, expected "
                "this server's own address)",
                _header(scope, b"origin"),
            )
            await send({"type": "websocket.close", "code": 4403})
            return
        if kind == "http" and scope.get("method") not in _SAFE_METHODS and not _same_origin(scope):
            self.server.refused_requests += 1
            _LOG.warning(
                "console: refused %s %s from another site's page (Origin %s, expected this "
                "server's own address)",
                scope.get("method"),
                scope.get("path", ""),
                _header(scope, b"origin"),
            )
            await _forbidden(send, b"403 forbidden: a request from another site's page\n")
            return
        query, cookie = _query_token(scope), _cookie(scope, TOKEN_COOKIE)
        given = query or cookie
        if self.server.token and not token_matches(self.server.token, given):
            self.server.refused_requests += 1
            client = scope.get("client") or ("?", 0)
            _LOG.warning(
                "console: refused %s %s from %s: expected the access token (?%s=...), found %s",
                kind,
                scope.get("path", ""),
                client[0],
                TOKEN_QUERY,
                "a wrong one" if given else "none",
            )
            if kind == "websocket":
                await send({"type": "websocket.close", "code": 4401})
                return
            await _forbidden(
                send,
                b"403 forbidden: this console needs its access token: open the address printed "
                b"at start (it ends in ?token=...)\n",
            )
            return
        scope[VIEWER_SCOPE] = viewer_key(_cookie(scope, VIEWER_COOKIE))
        cookies: list[tuple[str, str]] = []
        if kind == "http":
            if not scope[VIEWER_SCOPE]:
                cookies.append((VIEWER_COOKIE, f"{VIEWER_COOKIE}={new_viewer_id()}; {_COOKIE_LAX}"))
            if self.server.token and query and cookie != self.server.token:
                cookies.append(
                    (TOKEN_COOKIE, f"{TOKEN_COOKIE}={self.server.token}; {_COOKIE_STRICT}")
                )
        await self.app(scope, receive, _setting_cookies(send, cookies) if cookies else send)


_SAFE_METHODS = ("GET", "HEAD", "OPTIONS")
_COOKIE_LAX = "Path=/; HttpOnly; SameSite=Lax"
_COOKIE_STRICT = "Path=/; HttpOnly; SameSite=Strict"


def _setting_cookies(send: Any, cookies: list[tuple[str, str]]) -> Any:
    """``send`` that adds ``cookies`` (name, Set-Cookie value) to the response's headers,
    unless the route set a cookie of that name itself."""

    async def wrapped(message: dict) -> None:
        if message["type"] == "http.response.start":
            headers = list(message.get("headers", []))
            present = {
                value.split(b"=", 1)[0].strip() for key, value in headers if key == b"set-cookie"
            }
            for name, value in cookies:
                if name.encode() not in present:
                    headers.append((b"set-cookie", value.encode("latin-1")))
            message = {**message, "headers": headers}
        await send(message)

    return wrapped


async def _forbidden(send: Any, body: bytes) -> None:
    await send(
        {
            "type": "http.response.start",
            "status": 403,
            "headers": [(b"content-type", b"text/plain; charset=utf-8")],
        }
    )
    await send({"type": "http.response.body", "body": body})


def _header(scope: dict, name: bytes) -> str | None:
    for key, value in scope.get("headers", []):
        if key == name:
            return value.decode("latin-1")
    return None


def _same_origin(scope: dict) -> bool:
    """A browser names the page that opens a websocket (Origin); only this server's own pages
    may (another site open in the operator's browser must not drive the arm). Clients that are
    not browsers send no Origin."""
    origin = _header(scope, b"origin")
    if origin is None:
        return True
    from urllib.parse import urlsplit

    return urlsplit(origin).netloc == (_header(scope, b"host") or "")


def _query_token(scope: dict) -> str | None:
    from urllib.parse import parse_qs

    values = parse_qs(scope.get("query_string", b"").decode("latin-1")).get(TOKEN_QUERY)
    return values[0] if values else None


def _cookie(scope: dict, wanted: str) -> str | None:
    for name, value in scope.get("headers", []):
        if name == b"cookie":
            for part in value.decode("latin-1").split(";"):
                key, _, val = part.strip().partition("=")
                if key == wanted:
                    return val
    return None


class WebServer:
    """A FastAPI app served by uvicorn in a daemon thread, on ``host``:``port`` (0: a free one).

    ``token`` non-empty: every request needs it (query ``?token=`` or the cookie). Listening
    beyond loopback without a token is refused.
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 0, token: str = "") -> None:
        if not is_loopback(host) and not token:
            raise UserError(
                f"console: listening on {host} (beyond loopback) needs an access token, found none"
            )
        self.host = host
        self.token = token
        self.refused_requests = 0
        self.links: dict[str, str] = {}  #: extra pages (path -> title) shown on the console
        #: who holds control, shared by every page of this server (touched only by the modules'
        #: ``step``, which the scheduler never runs at once)
        self.control = ControlArbiter()
        self.app = FastAPI(docs_url=None, redoc_url=None, openapi_url=None)
        self._sock = socket.socket(
            socket.AF_INET6 if ":" in host else socket.AF_INET, socket.SOCK_STREAM
        )
        self._sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            self._sock.bind((host, port))
        except OSError as exc:
            self._sock.close()
            raise UserError(
                f"console: expected to listen on {host}:{port}, found {exc.strerror or exc}"
            ) from None
        self.port = int(self._sock.getsockname()[1])
        config = uvicorn.Config(
            _TokenGate(self.app, self),
            log_level="warning",
            lifespan="off",
            timeout_graceful_shutdown=1,
            ws_ping_interval=None,
        )
        self._server = uvicorn.Server(config)
        self._thread: threading.Thread | None = None
        self.loop: asyncio.AbstractEventLoop | None = None
        self.users = 0

    @property
    def url(self) -> str:
        """The address to open (with the token when there is one)."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        suffix = f"/?{TOKEN_QUERY}={self.token}" if self.token else "/"
        return f"http://{host}:{self.port}{suffix}"

    def add_link(self, path: str, title: str) -> None:
        """List another page of this server on the console (a link in its header)."""
        self.links[path] = title

    def start(self, timeout: float = 10.0) -> None:
        """Serve in a daemon thread; returns once the socket accepts connections."""
        ready = threading.Event()

        def serve() -> None:
            loop = asyncio.new_event_loop()
            asyncio.set_event_loop(loop)
            self.loop = loop
            ready.set()
            try:
                loop.run_until_complete(self._server.serve(sockets=[self._sock]))
            finally:  # end the pages' tasks (frame pump, senders) before the loop goes
                pending = asyncio.all_tasks(loop)
                for task in pending:
                    task.cancel()
                loop.run_until_complete(asyncio.gather(*pending, return_exceptions=True))
                loop.close()

        self._thread = threading.Thread(target=serve, name="umbra-web", daemon=True)
        self._thread.start()
        ready.wait(timeout)
        waited = 0.0
        while not self._server.started and self._thread.is_alive() and waited < timeout:
            threading.Event().wait(0.01)
            waited += 0.01
        if not self._server.started:
            raise UserError(f"console: the web server did not start within {timeout:.0f} s")

    def stop(self, timeout: float = 3.0) -> None:
        """Close every connection and join the thread (forcing after ``timeout`` [s])."""
        self._server.should_exit = True
        if self._thread is not None:
            self._thread.join(timeout)
            if self._thread.is_alive():
                self._server.force_exit = True
                self._thread.join(timeout)
        self._sock.close()


class _Registry:
    """Servers of this process by (graph, process): the one deliberate process-wide table,
    so modules of one process share one address. Guarded by a lock."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.servers: dict[tuple[str, str], WebServer] = {}


_REGISTRY = _Registry()


def acquire_server(
    context: Any, host: str | None = None, port: int | None = None, token: str = ""
) -> WebServer:
    """The web server of ``context``'s graph and process, started by the first caller.

    The first caller's ``host`` (default 127.0.0.1), ``port`` (default 0: a free port) and
    ``token`` decide; a later caller naming a different host or port gets a UserError. Pair
    every call with :func:`release_server`.
    """
    key = (str(getattr(context, "graph", "graph")), str(getattr(context, "process", "main")))
    with _REGISTRY.lock:
        server = _REGISTRY.servers.get(key)
        if server is None:
            server = WebServer(host or "127.0.0.1", port or 0, token)
            server.start()
            _REGISTRY.servers[key] = server
        elif (host is not None and host != server.host) or (port and port != server.port):
            raise UserError(
                f"console: this process already serves on {server.host}:{server.port}, "
                f"a module asked for {host}:{port}"
            )
        server.users += 1
        return server


def release_server(server: WebServer) -> None:
    """Give back a server from :func:`acquire_server`; the last user stops it."""
    with _REGISTRY.lock:
        server.users -= 1
        if server.users > 0:
            return
        for key, value in list(_REGISTRY.servers.items()):
            if value is server:
                del _REGISTRY.servers[key]
    server.stop()
