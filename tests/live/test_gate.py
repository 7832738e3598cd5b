"""The live server's door, with real sockets: the token, Host and Origin are checked before a
byte of the run is sent; a client gets nothing it could command the run with."""

from __future__ import annotations

import base64
import contextlib
import json
import os
import socket
import time
from collections.abc import Iterator

import pytest
import websockets.sync.client as ws_client
from websockets.exceptions import ConnectionClosed

from tests.live.graphs import small_plan
from tests.poll import wait_for
from umbra.connectors.limits import (
    MAX_PAGE_BAD_MESSAGES,
)
from umbra.connectors.limits import (
    MAX_PAGE_MESSAGE_BURST as BURST,
)
from umbra.connectors.limits import (
    MAX_PAGE_MESSAGES_PER_S as RATE,
)
from umbra.connectors.messages import Scalar
from umbra.runtime.live.parameters import ParameterTable
from umbra.runtime.live.server import LiveServer
from umbra.runtime.live.viewer_server import ViewerServer

TOKEN = "t0ken-of-this-run-0123456789"
VIEWER = "http://127.0.0.1:8080"


@pytest.fixture
def gate() -> Iterator[ViewerServer]:
    door = ViewerServer(
        name="test",
        host="127.0.0.1",
        port=0,
        token=TOKEN,
        origins=[VIEWER],
        parameters=ParameterTable(small_plan()),
    )
    server = LiveServer(socket=door, clock_offset=0.0)
    server.declare("/servo/error", Scalar)
    yield door
    server.close()
    door.close()


def _upgrade(port: int, target: str, host: str, origin: str | None, protocol: str) -> bytes:
    """What comes back to a raw WebSocket upgrade request (status line and headers)."""
    key = base64.b64encode(os.urandom(16)).decode()
    head = (
        f"GET {target} HTTP/1.1\r\nHost: {host}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
        f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n"
        f"Sec-WebSocket-Protocol: {protocol}\r\n"
        + (f"Origin: {origin}\r\n" if origin else "")
        + "\r\n"
    )
    with socket.create_connection(("127.0.0.1", port), timeout=5) as sock:
        sock.sendall(head.encode())
        got = b""
        while b"\r\n\r\n" not in got:
            chunk = sock.recv(4096)
            if not chunk:
                break
            got += chunk
    return got


def test_only_the_address_with_the_token_from_this_host_and_an_allowed_page_gets_in(
    gate: ViewerServer,
) -> None:
    port, good = gate.port, f"/?token={TOKEN}"
    here = f"127.0.0.1:{port}"
    v1 = "foxglove.websocket.v1"
    assert b" 101 " in _upgrade(port, good, here, None, v1).split(b"\r\n")[0]
    assert b" 101 " in _upgrade(port, good, f"localhost:{port}", VIEWER, v1)[:20]
    refused = [
        (_upgrade(port, "/", here, None, v1), b"403"),  # no token
        (_upgrade(port, "/?token=guess", here, None, v1), b"403"),  # a wrong one
        (_upgrade(port, good, f"evil.example:{port}", None, v1), b"421"),  # DNS rebinding
        (_upgrade(port, good, here, "http://evil.example", v1), b"403"),  # another site's page
        (_upgrade(port, good, here, "null", v1), b"403"),
    ]
    for answer, status in refused:
        assert answer.split(b"\r\n")[0].split(b" ")[1] == status, answer[:200]
    assert gate.refused == len(refused) and gate.passed == 2


def test_a_client_asking_for_either_name_of_the_protocol_gets_the_one_it_asked_for(
    gate: ViewerServer,
) -> None:
    for protocol in ("foxglove.websocket.v1", "foxglove.sdk.v1"):
        answer = _upgrade(gate.port, f"/?token={TOKEN}", f"127.0.0.1:{gate.port}", None, protocol)
        headers = answer.decode("latin-1").lower()
        assert f"sec-websocket-protocol: {protocol}" in headers, headers


def test_a_client_is_offered_nothing_that_acts_on_the_run(gate: ViewerServer) -> None:
    with ws_client.connect(
        gate.url, subprotocols=["foxglove.websocket.v1"], open_timeout=5
    ) as conn:
        info = json.loads(conn.recv(timeout=5))
        assert info["op"] == "serverInfo"
        assert set(info["capabilities"]) <= {"parameters", "parametersSubscribe", "time"}
        advertise = json.loads(conn.recv(timeout=5))
        assert advertise["op"] == "advertise"
        assert [c["topic"] for c in advertise["channels"]] == ["/servo/error"]
        set_request = {"op": "setParameters", "parameters": [{"name": "servo.gain", "value": 9}]}
        conn.send(json.dumps({**set_request, "id": "x"}))
        conn.send(json.dumps({"op": "getParameters", "parameterNames": [], "id": "y"}))
        values, said = {}, []
        while "y" not in values:
            msg = json.loads(conn.recv(timeout=5))
            if msg.get("op") == "parameterValues":
                values[msg.get("id")] = {p["name"]: p["value"] for p in msg["parameters"]}
            elif msg.get("op") == "status":
                said.append(msg["message"])
        # no process takes changes here (nothing runs the graph): refused, said, unchanged
        assert values["x"] == {"servo.gain": 0.5}
        assert values["y"]["servo.gain"] == 0.5 and values["y"]["guard.timeout"] == 0.2
        assert len(said) == 1 and "servo.gain" in said[0] and "does not reach" in said[0]
        for bad in ('{"op": "advertise", "channels": []}', "not json", '{"op": 3}'):
            conn.send(bad)  # client publishing is not served, nor malformed requests
            status = json.loads(conn.recv(timeout=5))
            assert status["op"] == "status" and status["level"] == 2, status


def test_a_client_that_asks_and_never_reads_is_closed(gate: ViewerServer) -> None:
    sock = socket.create_connection(("127.0.0.1", gate.port))
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    conn = ws_client.connect(
        gate.url, sock=sock, subprotocols=["foxglove.websocket.v1"], max_queue=1
    )
    try:
        ask = json.dumps({"op": "getParameters", "parameterNames": [], "id": "again"})
        for n in range(2000):  # each answer holds every parameter; none is read
            if not gate.viewers:
                break
            with contextlib.suppress(ConnectionClosed):
                conn.send(ask)
            if n >= BURST // 2:  # within the message budget: closed for its backlog
                time.sleep(2.0 / RATE)
        # closed by the server (1008), its answers dropped
        wait_for(lambda: gate.viewers == 0, 10, "the unread viewer closed", 0.05)
        assert gate.cut_off == 0  # for the answers it left unread, not for its rate
    finally:
        conn.close()


def _welcomed(url: str) -> ws_client.ClientConnection:
    """A viewer's connection, past its serverInfo and advertise."""
    conn = ws_client.connect(url, subprotocols=["foxglove.websocket.v1"], open_timeout=10)
    assert json.loads(conn.recv(timeout=10))["op"] == "serverInfo"
    assert json.loads(conn.recv(timeout=10))["op"] == "advertise"
    return conn


def _parameter_answer(conn: ws_client.ClientConnection, request_id: str) -> dict:
    conn.send(json.dumps({"op": "getParameters", "parameterNames": [], "id": request_id}))
    while True:
        msg = json.loads(conn.recv(timeout=10))
        if msg.get("op") == "parameterValues" and msg.get("id") == request_id:
            return {p["name"]: p["value"] for p in msg["parameters"]}


def test_a_flood_of_client_messages_is_cut_off_while_the_others_are_served(
    gate: ViewerServer,
) -> None:
    """A viewer sending as fast as it can (answer-less unsubscribes: nothing waits to be read) is
    closed for its rate, with the reason; another viewer connected meanwhile is still answered,
    and a new one still gets in. Load: the flood is 20 times the budget's burst sent in a loop;
    it stays above the budget's rate unless one send takes longer than 1/RATE s."""
    calm = _welcomed(gate.url)
    flood = _welcomed(gate.url)
    try:
        quiet = json.dumps({"op": "unsubscribe", "subscriptionIds": []})
        sent = 0
        with contextlib.suppress(ConnectionClosed):
            for sent in range(1, 20 * BURST + 1):  # noqa: B007 (counted for the assert)
                flood.send(quiet)
        with pytest.raises(ConnectionClosed) as closed:
            while True:
                flood.recv(timeout=10)
        assert closed.value.rcvd is not None and closed.value.rcvd.code == 1008
        assert "messages per second" in closed.value.rcvd.reason
        assert sent > BURST  # the budget's burst went through before the cut
        assert gate.cut_off == 1
        assert _parameter_answer(calm, "after")["servo.gain"] == 0.5
        with _welcomed(gate.url) as late:
            assert _parameter_answer(late, "late")["guard.timeout"] == 0.2
            # the calm one and the late one; the flood is gone
            wait_for(lambda: gate.viewers == 2, 10, "two viewers", 0.02)
    finally:
        calm.close()
        flood.close()


def test_malformed_messages_beyond_the_budget_close_the_viewer(gate: ViewerServer) -> None:
    with _welcomed(gate.url) as conn:
        for n in range(MAX_PAGE_BAD_MESSAGES):
            conn.send("not json")
            status = json.loads(conn.recv(timeout=10))
            assert status["op"] == "status" and status["level"] == 2, (n, status)
        conn.send("not json")
        with pytest.raises(ConnectionClosed) as closed:
            conn.recv(timeout=10)
        assert closed.value.rcvd is not None and closed.value.rcvd.code == 1008
        assert "malformed" in closed.value.rcvd.reason
        assert gate.cut_off == 1
