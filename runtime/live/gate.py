"""The live server's door: the per-run token, ``Host`` and ``Origin``, checked before the SDK.

Foxglove's SDK server has no hook to look at a connecting client's request (``foxglove-sdk``
0.30: ``start_server`` takes no authenticator and its listener hears of a client only once it is
in). So the address the run prints is this small proxy's: it reads the WebSocket upgrade request
(at most ``MAX_HEAD_BYTES``, within ``HEAD_TIMEOUT`` s), and only when

- the address carries the run's token (``?token=...``, compared in constant time),
- ``Host`` names this server (``127.0.0.1:PORT``, ``localhost:PORT``... as the operator's pages
  answer to: DNS rebinding gets nothing), and
- ``Origin`` is absent (a client that is not a browser) or one of the viewer pages allowed
  (``https://app.foxglove.dev`` and the ``--foxglove-origin`` ones),

does it open a connection to the SDK's private loopback port and pass bytes both ways; else it
answers ``421`` (Host) or ``403`` and closes. The rules are the operator pages' own
(``modules.webdoor.secret`` and ``hosts``), not a second copy.

What the SDK would need for the proxy to go: a callback with the request's path and headers that
can refuse the upgrade. Until then its private port is open on loopback to whoever finds it there
(it serves what the run's observers may see, and takes no command).

Subprotocol: the SDK (0.30) names the protocol ``foxglove.sdk.v1``; viewers and clients older than
that name (Lichtblick before 1.22, ``@foxglove/ws-protocol`` by default) ask for
``foxglove.websocket.v1``, the same protocol under its first name (Foxglove's stance: identical).
The gate asks the SDK for the one it speaks and answers the client with the name it asked for.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import threading
from collections.abc import Iterable
from urllib.parse import parse_qs, urlsplit

from modules.webdoor.hosts import allowed_hosts, host_allowed, origin_allowed
from modules.webdoor.secret import TOKEN_QUERY, token_matches

#: The longest upgrade request head read [bytes].
MAX_HEAD_BYTES = 16 * 1024
#: Seconds a client has to send its whole request head.
HEAD_TIMEOUT = 5.0
#: Connections open at once through the gate.
MAX_CONNECTIONS = 16
#: Viewer pages allowed by default (Foxglove's web app).
DEFAULT_ORIGINS = ("https://app.foxglove.dev",)
#: The subprotocol the SDK speaks, and the first name of the same protocol.
SDK_PROTOCOL = "foxglove.sdk.v1"
FIRST_PROTOCOL = "foxglove.websocket.v1"
_PROTOCOL_HEADER = b"sec-websocket-protocol"


def with_protocol(head: bytes, protocol: str) -> bytes:
    """``head`` (a request or response head) with its ``Sec-WebSocket-Protocol`` set to
    ``protocol`` (the other headers as they were)."""
    out = []
    for line in head.split(b"\r\n"):
        name, sep, _value = line.partition(b":")
        if sep and name.strip().lower() == _PROTOCOL_HEADER:
            line = name + b": " + protocol.encode()
        out.append(line)
    return b"\r\n".join(out)


def requested_protocols(headers: dict[str, str]) -> list[str]:
    """The subprotocols a WebSocket request asks for, in its order."""
    return [p.strip() for p in headers.get("sec-websocket-protocol", "").split(",") if p.strip()]


def origin_netlocs(origins: Iterable[str]) -> frozenset[str]:
    """``host[:port]`` of each allowed viewer page origin (``scheme://host[:port]``)."""
    return frozenset(urlsplit(o.strip()).netloc.lower() for o in origins if o.strip())


def parse_head(head: bytes) -> tuple[str, dict[str, str]]:
    """Request target and headers (lower-case names) of an HTTP/1.1 request head."""
    lines = head.decode("latin-1").split("\r\n")
    parts = lines[0].split(" ")
    if len(parts) != 3 or not parts[2].startswith("HTTP/1."):
        raise ValueError(f"not an HTTP/1.1 request line: {lines[0][:80]!r}")
    headers: dict[str, str] = {}
    for line in lines[1:]:
        if not line:
            continue
        name, sep, value = line.partition(":")
        if not sep:
            raise ValueError(f"malformed header line {line[:80]!r}")
        key = name.strip().lower()
        if key in headers and key in ("host", "origin"):
            raise ValueError(f"`{key}` given twice")
        headers[key] = value.strip()
    return parts[1], headers


def refusal(
    target: str,
    headers: dict[str, str],
    token: str,
    hosts: frozenset[str],
    origins: frozenset[str],
) -> tuple[int, str] | None:
    """``(status, why)`` when the request may not pass, else None."""
    if not host_allowed(headers.get("host"), hosts):
        return 421, f"Host {headers.get('host')!r} is not this server"
    if not origin_allowed(headers.get("origin"), origins | hosts):
        return 403, f"Origin {headers.get('origin')!r} is not an allowed viewer page"
    given = parse_qs(urlsplit(target).query).get(TOKEN_QUERY, [None])[0]
    if not token_matches(token, given):
        return 403, "the address's token is missing or wrong"
    return None


class Gate:
    """The proxy (see the module docstring), served by a thread of its own."""

    def __init__(
        self,
        *,
        host: str,
        port: int,
        inner_port: int,
        token: str,
        origins: Iterable[str] = DEFAULT_ORIGINS,
        log: logging.Logger | None = None,
    ) -> None:
        self.host, self.inner_port, self.token = host, inner_port, token
        self._origins = origin_netlocs(origins)
        self._log = log or logging.getLogger("umbra.foxglove")
        self.refused = 0
        self.passed = 0
        self._open = 0
        self._loop = asyncio.new_event_loop()
        self._server = self._loop.run_until_complete(
            asyncio.start_server(self._client, host, port, limit=MAX_HEAD_BYTES)
        )
        self.port = self._server.sockets[0].getsockname()[1]
        self._hosts = allowed_hosts(host, self.port)
        self._thread = threading.Thread(target=self._loop.run_forever, name="umbra-fox-gate")
        self._thread.daemon = True
        self._thread.start()

    @property
    def url(self) -> str:
        """The address a viewer opens: ``ws://HOST:PORT/?token=...``."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"ws://{host}:{self.port}/?{TOKEN_QUERY}={self.token}"

    async def _client(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        if self._open >= MAX_CONNECTIONS:
            await self._refuse(writer, 503, "too many viewers")
            return
        self._open += 1
        try:
            await self._serve(reader, writer)
        finally:
            self._open -= 1
            with contextlib.suppress(Exception):
                writer.close()

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        try:
            head = await asyncio.wait_for(reader.readuntil(b"\r\n\r\n"), HEAD_TIMEOUT)
            target, headers = parse_head(head)
        except (asyncio.TimeoutError, asyncio.IncompleteReadError, asyncio.LimitOverrunError):
            await self._refuse(writer, 400, "no complete request head")
            return
        except ValueError as exc:
            await self._refuse(writer, 400, str(exc))
            return
        why = refusal(target, headers, self.token, self._hosts, self._origins)
        if why is not None:
            await self._refuse(writer, *why)
            return
        try:
            inner_reader, inner_writer = await asyncio.open_connection("127.0.0.1", self.inner_port)
        except OSError as exc:
            await self._refuse(writer, 502, f"the live server is not there: {exc}")
            return
        self.passed += 1
        peer = writer.get_extra_info("peername")
        self._log.info("foxglove: viewer connected from %s", peer[0] if peer else "?")
        asked = requested_protocols(headers)
        renamed = SDK_PROTOCOL not in asked and FIRST_PROTOCOL in asked
        inner_writer.write(with_protocol(head, SDK_PROTOCOL) if renamed else head)
        if renamed:  # answer with the name the client asked for
            try:
                answer = await asyncio.wait_for(inner_reader.readuntil(b"\r\n\r\n"), HEAD_TIMEOUT)
            except (asyncio.TimeoutError, asyncio.IncompleteReadError, asyncio.LimitOverrunError):
                inner_writer.close()
                return
            writer.write(with_protocol(answer, FIRST_PROTOCOL))
        await asyncio.gather(self._pump(reader, inner_writer), self._pump(inner_reader, writer))

    @staticmethod
    async def _pump(src: asyncio.StreamReader, dst: asyncio.StreamWriter) -> None:
        try:
            while data := await src.read(256 * 1024):
                dst.write(data)
                await dst.drain()  # a slow viewer holds this pump, not the run
        except (ConnectionError, OSError):
            pass
        finally:
            with contextlib.suppress(Exception):
                dst.close()

    async def _refuse(self, writer: asyncio.StreamWriter, status: int, why: str) -> None:
        self.refused += 1
        self._log.warning("foxglove: connection refused (%d): %s", status, why)
        reason = {400: "Bad Request", 403: "Forbidden", 421: "Misdirected Request"}.get(
            status, "Error"
        )
        body = why.encode()
        writer.write(
            f"HTTP/1.1 {status} {reason}\r\nContent-Type: text/plain\r\n"
            f"Content-Length: {len(body)}\r\nConnection: close\r\n\r\n".encode()
            + body
        )
        with contextlib.suppress(Exception):
            await writer.drain()
            writer.close()

    def close(self) -> None:
        """Stop accepting and end the thread."""

        async def stop() -> None:
            self._server.close()
            await self._server.wait_closed()

        with contextlib.suppress(Exception):
            asyncio.run_coroutine_threadsafe(stop(), self._loop).result(timeout=2.0)
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(timeout=2.0)
