"""A peer that the machine starves is late, not gone; one that dies is gone (``links.late``).

The peer is a real process with its own zenoh session and token; it is stopped with SIGSTOP
for longer than zenoh's lease (its link and token go) and less than the late bound."""

from __future__ import annotations

import logging
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator

import pytest
import zenoh

from tests.links.conftest import REPO
from tests.poll import wait_for
from umbra.runtime.graph.check import load_graph
from umbra.runtime.graph.plan import GraphPlan
from umbra.runtime.links.config import LEASE_MS, Endpoints, build_config, free_loopback_ports
from umbra.runtime.links.late import LATE_CHECK_S, LATE_MAX_S
from umbra.runtime.links.transport import ZenohTransport

pytestmark = pytest.mark.slow

GRAPH = str(REPO / "graphs" / "counter_split.yaml")

#: the peer: process `umbra` of the graph, its token declared, until its stdin closes
PEER = """
import sys, zenoh
from umbra.runtime.graph.check import load_graph
from umbra.runtime.links.config import Endpoints, build_config
from umbra.runtime.links.transport import ZenohTransport
session = zenoh.open(build_config(Endpoints([], [sys.argv[2]])))
transport = ZenohTransport(session, load_graph(sys.argv[1]), "umbra")
transport.announce()
print("announced", flush=True)
sys.stdin.read()
transport.close()
"""


class _Lines(logging.Handler):
    def __init__(self) -> None:
        super().__init__()
        self.lines: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.lines.append(record.getMessage())


@pytest.fixture
def watched() -> Iterator[tuple[ZenohTransport, subprocess.Popen[str], _Lines, GraphPlan]]:
    """This test is process `smart` (taking the peer's counter stream); the peer is `umbra`."""
    plan = load_graph(GRAPH)
    (port,) = free_loopback_ports(1)
    endpoint = f"tcp/127.0.0.1:{port}"
    lines = _Lines()
    log = logging.getLogger("umbra.test.starved")
    log.addHandler(lines)
    log.setLevel(logging.INFO)
    transport = ZenohTransport(
        zenoh.open(build_config(Endpoints([endpoint]))), plan, "smart", log=log
    )
    for link in plan.links:
        if plan.modules[link.connection.dst.module].process == "smart" and link.key.endswith(
            "counter/count"
        ):
            transport.subscribe(link, lambda _m: None)
    transport.announce()
    peer = subprocess.Popen(
        [sys.executable, "-c", PEER, GRAPH, endpoint],
        cwd=REPO,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert peer.stdout is not None and peer.stdout.readline().strip() == "announced"
        wait_for(lambda: "umbra" in transport.alive_processes(), 10.0, "the peer alive")
        yield transport, peer, lines, plan
    finally:
        if peer.poll() is None:
            os.kill(peer.pid, signal.SIGCONT)
            peer.kill()
        peer.wait(10)
        transport.close()
        log.removeHandler(lines)


def test_a_stopped_peer_is_late_not_gone_and_comes_back(watched) -> None:
    transport, peer, lines, _plan = watched
    os.kill(peer.pid, signal.SIGSTOP)
    stopped_at = time.monotonic()
    alive_throughout = True

    def late_for(seconds: float) -> bool:
        nonlocal alive_throughout
        alive_throughout &= "umbra" in transport.alive_processes()
        return transport.late_processes().get("umbra", 0.0) >= seconds

    # its lease runs out (its link and token go): it is late, and stays alive past the lease
    wait_for(lambda: late_for(1.5), LEASE_MS / 1e3 + 8.0, "the peer late for 1.5 s")
    silent_s = time.monotonic() - stopped_at
    assert LEASE_MS / 1e3 < silent_s < LATE_MAX_S
    assert alive_throughout
    assert not any("is gone" in line for line in lines.lines), lines.lines
    assert any("`umbra` is late" in line for line in lines.lines), lines.lines
    os.kill(peer.pid, signal.SIGCONT)
    # its token returns
    wait_for(lambda: "umbra" not in transport.late_processes(), 10.0, "the peer no longer late")
    assert alive_throughout and "umbra" in transport.alive_processes()
    stats = transport.stats()
    assert stats["late_held"] == 1 and stats["late_returned"] == 1
    assert any("`umbra` is back after" in line for line in lines.lines), lines.lines
    assert not any("is gone" in line for line in lines.lines), lines.lines


def test_a_late_peer_that_dies_is_gone_at_once(watched) -> None:
    transport, peer, lines, _plan = watched
    os.kill(peer.pid, signal.SIGSTOP)
    wait_for(lambda: "umbra" in transport.late_processes(), LEASE_MS / 1e3 + 8.0, "the peer late")
    peer.kill()
    killed_at = time.monotonic()
    peer.wait(5)  # reaped: the OS no longer has it
    wait_for(lambda: "umbra" not in transport.alive_processes(), 5.0, "the peer gone")
    gone_s = time.monotonic() - killed_at
    assert gone_s < 10 * LATE_CHECK_S + 0.5 < LATE_MAX_S  # by its death, not by the bound
    assert any("`umbra` is gone" in line for line in lines.lines), lines.lines
    assert transport.stats()["late_returned"] == 0


def test_a_killed_peer_is_gone_without_being_late(watched) -> None:
    transport, peer, lines, _plan = watched
    peer.kill()
    peer.wait(5)
    wait_for(lambda: "umbra" not in transport.alive_processes(), 5.0, "the peer gone")
    assert not transport.late_processes()
    assert any("`umbra` is gone" in line for line in lines.lines), lines.lines
