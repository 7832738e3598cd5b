"""One web server per ``umbra`` process, shared by every module that serves a page.

The console starts it; another module of the same process (the Active Sketch page, say) adds
its own routes to the same server, so the operator has one address. The server is a FastAPI
app served by uvicorn in its own thread (the scheduler owns the main thread); a module's
``step`` never talks to it directly, only through :mod:`umbra.modules.operator.mailbox` objects.

Example, in another module of the same process::

    from fastapi.responses import HTMLResponse
    from umbra.modules.operator.web_server import acquire_server, release_server

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
alike, is behind the door (:mod:`umbra.modules.webdoor`): the per-run access token, the Host names
the server was started for, its own pages' Origin, bounded bodies, messages and connections; the
gate also gives each browser its viewer cookie. The server holds the control table of all its pages
(``server.control``, a :class:`~umbra.modules.operator.control.ControlArbiter`): the operator who
holds control on one page holds it on every page of the server, and commands from everyone
else are refused. The server stops when the last module holding it releases it; a module whose
pages must still learn how the run ended releases it with ``linger_s``: the server then serves
on (no module owns it any more) until the process ends, at most that long
(:mod:`umbra.modules.webdoor.linger`), so a page that reconnects after the run's end still gets
its verdict.
"""

from __future__ import annotations

import asyncio
import socket
import threading
from typing import Any

import uvicorn
from fastapi import FastAPI

from umbra.connectors.access.hosts import allowed_hosts
from umbra.connectors.access.secret import TOKEN_QUERY
from umbra.connectors.errors import UserError
from umbra.modules.operator.control import ControlArbiter
from umbra.modules.webdoor.gate import Gate
from umbra.modules.webdoor.linger import linger
from umbra.modules.webdoor.transport import Connections, uvicorn_options


class WebServer:
    """A FastAPI app served by uvicorn in a daemon thread, on ``host``:``port`` (0: a free one),
    behind the door (:mod:`umbra.modules.webdoor`) with the access ``token`` (required, loopback
    too).
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 0, token: str = "") -> None:
        if not token:
            raise UserError(f"console: serving on {host} needs an access token, found none")
        self.host = host
        self.token = token
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
        self.connections = Connections()
        self.gate = Gate(self.app, token, allowed_hosts(host, self.port))
        config = uvicorn.Config(
            self.gate,
            log_level="warning",
            lifespan="off",
            timeout_graceful_shutdown=1,
            ws_ping_interval=None,
            **uvicorn_options(self.connections),
        )
        self._server = uvicorn.Server(config)
        self._thread: threading.Thread | None = None
        self.loop: asyncio.AbstractEventLoop | None = None
        self.users = 0

    @property
    def refused_requests(self) -> int:
        """Requests and sockets the door refused (bad Host, Origin, token, body, connections)."""
        return self.gate.refusals.total + self.connections.refused + self.connections.half_open

    @property
    def url(self) -> str:
        """The address to open on this machine, with the token (bound to every interface:
        the loopback one; the server answers to the names :mod:`umbra.connectors.access.hosts`
        says)."""
        host = {"0.0.0.0": "127.0.0.1", "::": "::1", "": "127.0.0.1"}.get(self.host, self.host)
        host = f"[{host}]" if ":" in host else host
        return f"http://{host}:{self.port}/?{TOKEN_QUERY}={self.token}"

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


def release_server(server: WebServer, linger_s: float = 0.0) -> None:
    """Give back a server from :func:`acquire_server`; the last user stops it, at once or, with
    ``linger_s`` [s], that much later in a thread of its own (the server leaves the registry at
    once: a later :func:`acquire_server` starts a new one; the process's end ends it sooner)."""
    with _REGISTRY.lock:
        server.users -= 1
        if server.users > 0:
            return
        for key, value in list(_REGISTRY.servers.items()):
            if value is server:
                del _REGISTRY.servers[key]
    linger(server.stop, linger_s, "umbra-web-linger")
