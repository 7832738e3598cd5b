"""The door of the operator's pages against real clients on a real server (the console's, which
the Active Sketch page shares): DNS rebinding (a foreign Host), another site's Origin, POSTs
without the cookie or the page's Origin, bodies and heads past their limits, half-open requests,
connection floods, socket messages past their size, and a client run as another OS user."""

from __future__ import annotations

import json
import os
import select
import shutil
import socket
import subprocess
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import httpx
import pytest
from websockets.exceptions import ConnectionClosed

from tests.operator.helpers import Page
from tests.poll import wait_for
from tests.security.console_rig import T_TOOL_CAMERA
from umbra.connectors.limits import (
    MAX_PAGE_BODY_BYTES,
    MAX_PAGE_CONNECTIONS_PER_CLIENT,
    MAX_PAGE_MESSAGE_BYTES,
    MAX_PAGE_REQUEST_S,
)
from umbra.modules.operator.console import OperatorConsole
from umbra.runtime.harness import ModuleHarness

PROBE = Path(__file__).resolve().parent / "probe.py"


@contextmanager
def _console() -> Iterator[tuple[ModuleHarness, str, str, int]]:
    """The console's server: (harness, root address, token, port)."""
    with ModuleHarness(OperatorConsole, {}, frames={"tool->camera": T_TOOL_CAMERA}) as h:
        root, _, query = h.module.url.partition("/?")
        yield h, root, query.removeprefix("token="), h.module._server.port


def _raw(port: int, data: bytes, timeout: float = 5.0) -> bytes:
    """Send ``data`` on a fresh connection; everything the server answers until it closes."""
    with socket.create_connection(("127.0.0.1", port), timeout=timeout) as s:
        s.sendall(data)
        out = b""
        while True:
            try:
                chunk = s.recv(65536)
            except TimeoutError:
                return out
            if not chunk:
                return out
            out += chunk


def _handshake(port: int, host: str, target: str) -> bytes:
    """The status line of a websocket handshake naming ``host`` (and its origin)."""
    return _raw(
        port,
        (
            f"GET {target} HTTP/1.1\r\nHost: {host}\r\nOrigin: http://{host}\r\n"
            "Upgrade: websocket\r\nConnection: Upgrade\r\n"
            "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n"
        ).encode(),
        timeout=1.0,
    )


def test_a_rebinding_request_with_a_foreign_host_gets_nothing() -> None:
    with _console() as (h, root, token, port):
        for host in (f"attacker.example:{port}", "attacker.example", f"127.0.0.1:{port + 1}"):
            # with the token even (a rebinding page does not have it, but the Host is enough)
            reply = httpx.get(
                f"{root}/?token={token}", headers={"Host": host, "Origin": f"http://{host}"}
            )
            assert reply.status_code == 421, (host, reply.status_code)
            assert b"expected a Host this server was started for" in reply.content
            assert _handshake(port, host, f"/ws?token={token}").startswith(b"HTTP/1.1 403")
        assert _handshake(port, f"localhost:{port}", f"/ws?token={token}").startswith(
            b"HTTP/1.1 101"
        )
        # the token's redirect stays on this server, whatever the path says
        swap = httpx.get(
            f"{root}//evil.example/x?token={token}&a=1", headers={"Host": f"localhost:{port}"}
        )
        assert swap.status_code == 303 and swap.headers["location"] == "/evil.example/x?a=1"
        # the names it was started for
        for host in (f"127.0.0.1:{port}", f"localhost:{port}", f"[::1]:{port}"):
            reply = httpx.get(f"{root}/", headers={"Host": host}, cookies={"umbra_token": token})
            assert reply.status_code == 200, host
        assert h.module._server.gate.refusals.counts["host"] == 6  # (3 requests, 3 sockets)
        assert h.module.summary()["refused_requests"] == 6


def test_another_sites_origin_and_forged_posts_are_refused() -> None:
    with _console() as (_h, root, token, port):
        cookies = {"umbra_token": token}
        for origin in ("http://evil.example", "null", f"http://127.0.0.1:{port + 1}"):
            reply = httpx.get(f"{root}/", headers={"Origin": origin}, cookies=cookies)
            assert reply.status_code == 403 and b"another site" in reply.content, origin
        # a POST: the token in the address is not enough; the cookie without the page's Origin
        # (or the CSRF header) is not either
        assert httpx.post(f"{root}/?token={token}").status_code == 403
        assert httpx.post(f"{root}/", cookies=cookies).status_code == 403
        mine = {"Origin": root}
        assert httpx.post(f"{root}/", cookies=cookies, headers=mine).status_code == 405
        csrf = {"x-umbra-csrf": "1"}
        assert httpx.post(f"{root}/", cookies=cookies, headers=csrf).status_code == 405


def test_bodies_are_refused_past_their_limit_before_they_are_read() -> None:
    with _console() as (_h, root, token, port):
        cookie = f"Cookie: umbra_token={token}\r\nOrigin: {root}\r\n"
        head = f"POST /sketch/command HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n{cookie}"
        # 512 MiB declared, nothing sent: refused at once, from the header
        t0 = time.monotonic()
        out = _raw(port, (head + f"Content-Length: {512 << 20}\r\n\r\n").encode())
        assert out.startswith(b"HTTP/1.1 413") and time.monotonic() - t0 < 2.0
        assert f"at most {MAX_PAGE_BODY_BYTES} bytes".encode() in out
        # streamed (chunked, no length): refused once the count passes the limit, and closed
        with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
            s.sendall((head + "Transfer-Encoding: chunked\r\n\r\n").encode())
            chunk = b"%x\r\n%s\r\n" % (4096, b"a" * 4096)
            try:
                for _ in range(2 * MAX_PAGE_BODY_BYTES // 4096):
                    s.sendall(chunk)
            except (BrokenPipeError, ConnectionResetError):
                pass  # refused and closed while these were still going: the answer is read next
            try:
                answer = s.recv(65536)
            except ConnectionResetError:  # the kernel's reset (data still coming) beat the answer
                answer = b"reset"
            assert answer.startswith(b"HTTP/1.1 413") or answer == b"reset", answer[:200]
            sent, refused = 0, False
            try:  # the server reads no more: the connection is gone long before 64 MiB
                while sent < 64 << 20:
                    s.sendall(chunk)
                    sent += len(chunk)
            except OSError:
                refused = True
        assert refused and sent < 16 << 20, sent
        # a head past its limit
        big = head + "X-Junk: " + "j" * (64 << 10) + "\r\n\r\n"
        try:
            answer = _raw(port, big.encode())
        except ConnectionResetError:  # closed on the head's unread rest: the reset beat the answer
            answer = b"reset"
        assert answer.startswith(b"HTTP/1.1 4") or answer == b"reset", answer[:200]


def test_half_open_requests_are_closed_and_connections_are_bounded() -> None:
    with _console() as (h, _root, _token, port):
        # a request head that never ends is closed after MAX_PAGE_REQUEST_S
        with socket.create_connection(("127.0.0.1", port), timeout=3 * MAX_PAGE_REQUEST_S) as s:
            s.sendall(f"GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nX-Slow: ".encode())
            t0 = time.monotonic()
            assert s.recv(100) == b""
            waited = time.monotonic() - t0
        assert MAX_PAGE_REQUEST_S - 0.5 <= waited <= MAX_PAGE_REQUEST_S + 2.0, waited
        assert h.module._server.connections.half_open == 1
        # one client address holds at most MAX_PAGE_CONNECTIONS_PER_CLIENT connections
        held = []
        for _ in range(MAX_PAGE_CONNECTIONS_PER_CLIENT + 10):
            s = socket.create_connection(("127.0.0.1", port), timeout=2)
            s.sendall(f"GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n".encode())
            held.append(s)
        # the ten over the limit closed by the server (readable: an end or a reset; the rest
        # sent half a request head and hear nothing until MAX_PAGE_REQUEST_S)
        wait_for(
            lambda: len(select.select(held, [], [], 0)[0]) >= 10, 10.0, "10 connections closed"
        )
        closed = 0
        for s in held:
            s.settimeout(0.05)
            try:
                closed += s.recv(10) == b""
            except TimeoutError:
                pass
            except OSError:
                closed += 1
        assert closed == 10
        assert h.module._server.connections.refused == 10
        for s in held:
            s.close()
        # once they are gone, the operator gets in
        connections = h.module._server.connections
        wait_for(lambda: not connections.open, 10.0, "the held connections released")
        page = Page(h.module.url)
        page.close()


def test_socket_messages_past_their_size_are_refused_by_the_protocol(
    caplog: pytest.LogCaptureFixture,
) -> None:
    with _console() as (h, _root, _token, _port):
        page = Page(h.module.url)
        try:
            page.raw("x" * (MAX_PAGE_MESSAGE_BYTES + 1))
            with pytest.raises(ConnectionClosed):
                page.recv_text("never", timeout=5)
            wait_for(
                lambda: h.module.summary()["oversize"] == 1, 5.0, "the oversize message counted"
            )
        finally:
            page.close()
        # a flood of well-formed messages past the budget is closed (1008, with the reason)
        page = Page(h.module.url)
        try:
            with pytest.raises(ConnectionClosed):  # (its close frame may be lost: a flooder's
                for _ in range(2000):  # unread bytes make the close a reset)
                    page.send("hello", name="x")
                page.recv_text("never", timeout=5)
        finally:
            page.close()
        wait_for(lambda: h.module.summary()["closed_abusers"] == 1, 5.0, "the abuser closed")
        assert "messages per second" in caplog.text


def _as_nobody() -> list[str] | None:
    if os.geteuid() != 0:
        return None
    if shutil.which("setpriv"):
        return ["setpriv", "--reuid=nobody", "--regid=nogroup", "--clear-groups", "--"]
    if shutil.which("runuser"):
        return ["runuser", "-u", "nobody", "--"]
    return None


@pytest.mark.skipif(_as_nobody() is None, reason="needs root and setpriv or runuser")
def test_another_local_user_without_the_token_gets_nothing() -> None:
    """A client run as user ``nobody`` (stdlib Python, no token): every route and the socket
    refused, and it finds the token nowhere it can read."""
    with _console() as (h, _root, token, port):
        proc = subprocess.run(
            [*(_as_nobody() or []), "/usr/bin/python3", str(PROBE), str(port), str(os.getpid())],
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert proc.returncode == 0, proc.stderr
        report = json.loads(proc.stdout)
        assert report["uid"] != 0
        assert report["statuses"] == {"GET /": 403, "GET /console.js": 403, "POST /": 403}
        assert report["websocket"].startswith("HTTP/1.1 403")
        assert token not in report["readable"], "the token is readable by another user"
        assert not h.module.arbiter.sessions and h.module.arbiter.holder is None
