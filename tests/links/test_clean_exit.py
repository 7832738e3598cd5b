"""A process stopped while strangers hold connections to its zenoh listener still exits, at once,
with its summary written.

Real parts: ``umbra run --process smart --insecure`` listening on loopback (no credentials: anyone
may connect), a stranger holding raw TCP connections open on its port, some saying nothing and
some junk. zenoh's session close waits for the handshakes under way; they are bounded
(``runtime/links/config.py``: ``ACCEPT_TIMEOUT_MS``) and so is the wait for the close
(``runtime/links/session.py``: ``close_session``). Before, such a process stayed in its close for
as long as zenoh's 10 s handshake timeout, longer under load.
"""

from __future__ import annotations

import json
import signal
import socket
import time
from pathlib import Path

import pytest

from tests.links.conftest import Running, start_umbra, stop_all
from umbra.runtime.links.config import ACCEPT_TIMEOUT_MS, free_loopback_ports
from umbra.runtime.links.session import CLOSE_WAIT_S

pytestmark = [pytest.mark.slow, pytest.mark.untimed]

GRAPH = """
graph: cleanexit
clock: real
processes: {umbra: {}, smart: {}}
modules:
  counter: {type: Counter, process: umbra, rate: 100}
  double: {type: Gain, process: smart, params: {gain: 2.0}}
connections:
  - counter.count -> double.input
"""
#: Connections the stranger holds: half say nothing, half send junk.
STRANGERS = 24


def test_a_process_stopped_while_strangers_hold_connections_exits_with_its_summary(
    plugin_env: dict[str, str], tmp_path: Path
) -> None:
    (tmp_path / "g.yaml").write_text(GRAPH)
    (port,) = free_loopback_ports(1)
    runs: list[Running] = []
    held: list[socket.socket] = []
    try:
        smart = start_umbra(
            plugin_env, tmp_path, "run", "g.yaml", "--process", "smart", "--insecure",
            "--listen", f"tcp/127.0.0.1:{port}", "--out", "out",
        )  # fmt: skip
        runs.append(smart)
        smart.wait_for("links ready, running", timeout=60)
        for i in range(STRANGERS):
            conn = socket.create_connection(("127.0.0.1", port), timeout=5.0)
            if i % 2:
                conn.sendall(b"\x00\x01not a zenoh handshake" * 8)
            held.append(conn)
        smart.popen.send_signal(signal.SIGINT)
        started = time.monotonic()
        # a bound on the exit, not a speed measured: the handshakes' deadline, the close's wait
        # and the summary, with room for a loaded machine
        code = smart.finish(timeout=CLOSE_WAIT_S + 30.0)
        took = time.monotonic() - started
    finally:
        for conn in held:
            conn.close()
        stop_all(runs)
    assert code == 130, smart.text
    assert "Traceback" not in smart.text
    assert json.loads((tmp_path / "out" / "summary-smart.json").read_text())["modules"]
    # zenoh's own handshake deadline (10 s) would have held the close for longer than the
    # bounded handshake (2 s) and close (3 s) take together with a loaded machine's margin
    assert took < ACCEPT_TIMEOUT_MS / 1e3 + CLOSE_WAIT_S + 4.0, took


def test_ctrl_c_pressed_again_and_again_still_leaves_the_summary(
    plugin_env: dict[str, str], tmp_path: Path
) -> None:
    """An impatient operator: SIGINT every 2 ms from the moment the links are ready until the
    process has gone. Each one lands in some phase (the loop, the safe stop, the links' close,
    the summary); none may turn into an interrupt that skips the summary."""
    (tmp_path / "g.yaml").write_text(GRAPH)
    runs: list[Running] = []
    sent = 0
    try:
        smart = start_umbra(
            plugin_env, tmp_path, "run", "g.yaml", "--process", "smart", "--insecure",
            "--listen", "tcp/127.0.0.1:0", "--out", "out",
        )  # fmt: skip
        runs.append(smart)
        smart.wait_for("links ready, running", timeout=60)
        while smart.popen.poll() is None and sent < 500:
            smart.popen.send_signal(signal.SIGINT)
            sent += 1
            time.sleep(0.002)  # pacing: a repeated Ctrl-C, faster than a person
        code = smart.finish(timeout=CLOSE_WAIT_S + 30.0)
    finally:
        stop_all(runs)
    assert sent >= 2, sent  # it did not leave at the first one before a second could come
    assert code == 130, smart.text
    assert "Traceback" not in smart.text
    assert json.loads((tmp_path / "out" / "summary-smart.json").read_text())["modules"]
