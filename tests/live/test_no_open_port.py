"""Nothing of a run is served without the token: every TCP port the run's processes listen on
(read from ``/proc``, not from what the server says) is tried by a raw Foxglove viewer with and
without the token; only the printed address, with its token, gives data."""

from __future__ import annotations

import concurrent.futures
import os
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.live.graphs import TOKEN, small_viewer_server
from tests.live.helpers import REPO, LiveRun, wait_joined
from tests.live.ports import descendants, listening_ports, viewer_gets
from umbra.connectors.messages import Scalar
from umbra.runtime.live.server import LiveServer
from umbra.runtime.live.viewer_server import ViewerServer


@pytest.fixture
def served() -> Iterator[tuple[ViewerServer, set[int]]]:
    """A live server publishing a scalar at 50 Hz; the ports this process listens on that it
    added."""
    before = listening_ports(os.getpid())
    door = small_viewer_server()
    server = LiveServer(socket=door, clock_offset=0.0)
    server.declare("/servo/error", Scalar)
    added = listening_ports(os.getpid()) - before
    stop = threading.Event()

    def feed() -> None:
        n = 0
        while not stop.wait(0.02):
            n += 1
            server.offer("/servo/error", Scalar(value=0.5, stamp=n * 0.02, seq=n), n * 0.02)

    thread = threading.Thread(target=feed, daemon=True)
    thread.start()
    yield door, added
    stop.set()
    thread.join()
    server.close()
    door.close()


def test_the_live_server_listens_on_one_port_that_serves_only_with_the_token(
    served: tuple[ViewerServer, set[int]],
) -> None:
    door, added = served
    assert added == {door.port}  # no second, private port (Foxglove's SDK had one)
    assert viewer_gets(door.port, "", "/servo/error") == "refused"
    assert viewer_gets(door.port, "?token=guess-0123456789abcdef", "/servo/error") == "refused"
    assert viewer_gets(door.port, f"?token={TOKEN}", "/servo/error") == "data"


@pytest.mark.slow
def test_no_port_of_a_split_run_serves_a_viewer_without_the_token(tmp_path: Path) -> None:
    graph = str(REPO / "graphs" / "tool_pickup.yaml")
    # the pick-up's verdict must not end the run while the ports are tried (up to 20 s each)
    run = LiveRun(graph, tmp_path / "run", "--duration", "90", "--set", "world.end_run=false")
    try:
        wait_joined(run)  # the processes up and linked, their samples reaching the live server
        token = run.url.split("?token=", 1)[1]
        printed = int(run.url.split(":")[2].split("/")[0])
        ports = {port: pid for pid in descendants(run.proc.pid) for port in listening_ports(pid)}
        assert printed in ports and ports[printed] == run.proc.pid
        assert len(ports) > 1  # zenoh's listeners, the console's page server
        # every port at once (a zenoh listener holds a viewer's handshake until its timeout);
        # with the token, data within 20 s on a loaded machine
        with concurrent.futures.ThreadPoolExecutor(2 * len(ports)) as pool:
            tries = {
                (port, query): pool.submit(viewer_gets, port, query, "/joints/joint_state", 20.0)
                for port in ports
                for query in ("", f"?token={token}")
            }
            without = {port: tries[port, ""].result() for port in ports}
            with_token = {port: tries[port, f"?token={token}"].result() for port in ports}
    finally:
        run.stop()
    assert set(without.values()) == {"refused"}, without
    assert with_token[printed] == "data"
    assert {p for p, got in with_token.items() if got != "refused"} == {printed}, with_token


def test_a_viewer_that_stops_reading_gets_fresh_data_when_it_reads_again() -> None:
    """The server holds a bounded backlog per viewer (messages and bytes): a viewer that paused
    for 1.5 s is a few frames behind when it reads again, the rest dropped and counted."""
    import json
    import socket
    import struct

    import websockets.sync.client as ws_client

    door = small_viewer_server()
    channel = door.add_channel("/camera/image", "protobuf", "x.Image", "protobuf", b"")
    rare = door.add_channel("/tf_static", "protobuf", "x.Frames", "protobuf", b"")
    stop = threading.Event()
    frame = bytes(60_000)  # a 640 x 480 JPEG's size

    def feed() -> None:
        while not stop.wait(0.02):  # 50 Hz, 3 MB/s
            door.publish(channel, time.time_ns(), frame)

    sock = socket.socket()
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 64 * 1024)
    sock.connect(("127.0.0.1", door.port))
    thread = threading.Thread(target=feed, daemon=True)
    try:
        with ws_client.connect(
            f"ws://127.0.0.1:{door.port}/?token={TOKEN}",
            sock=sock,
            subprotocols=["foxglove.websocket.v1"],
            max_size=None,
            max_queue=1,
        ) as conn:
            conn.recv(timeout=5)  # serverInfo
            conn.recv(timeout=5)  # advertise
            subs = [{"id": 7, "channelId": channel}, {"id": 8, "channelId": rare}]
            sub = {"op": "subscribe", "subscriptions": subs}
            conn.send(json.dumps(sub))
            thread.start()
            conn.recv(timeout=5)
            time.sleep(0.5)  # stalled: the server keeps publishing
            door.publish(rare, time.time_ns(), b"once")  # a message sent once, mid-pause
            time.sleep(1.0)  # still stalled: more frames pile up for it
            stale, got_rare = 0, False  # frames held for the viewer since the pause
            while True:
                message = conn.recv(timeout=5)
                assert isinstance(message, bytes)
                _op, sub_id, log_ns = struct.unpack_from("<BIQ", message)
                if sub_id == 8:
                    got_rare = True  # the video replaced its own frames, not this one
                    continue
                if time.time_ns() - log_ns < 0.5e9:  # published after the pause
                    break
                stale += 1
            assert got_rare
            # 64 frames (the message bound alone) would be 3.8 MB; the byte bound holds ~9,
            # the sockets' buffers a few more
            assert stale <= 25, stale
            assert door.dropped > 20  # of the ~75 frames published meanwhile
    finally:
        stop.set()
        if thread.is_alive():
            thread.join()
        door.close()
