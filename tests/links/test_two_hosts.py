"""Two processes on two "hosts" — network namespaces joined by a veth pair — and a link cut.

The consumer's watchdog must fire when the link goes down, the producer must be declared gone
after the zenoh lease, and when the link comes back the samples flow again with nothing
restarted. Needs root and iproute2 (``apt-get install iproute2``); skipped with the reason
otherwise.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.links.conftest import Running, watched_counter_graph

pytestmark = pytest.mark.netns

GRAPH = watched_counter_graph("twohosts")


def _ip(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["ip", *args], capture_output=True, text=True, timeout=10)


def _why_not() -> str | None:
    if shutil.which("ip") is None:
        return "iproute2 is not installed (`ip` missing): apt-get install iproute2"
    if os.geteuid() != 0:
        return "network namespaces need root"
    probe = f"umbra-probe-{os.getpid()}"
    done = _ip("netns", "add", probe)
    if done.returncode != 0:
        return f"network namespaces are not permitted here: {done.stderr.strip()}"
    _ip("netns", "del", probe)
    return None


@dataclass
class Hosts:
    a: str  # producer's namespace
    b: str  # consumer's namespace
    veth_a: str
    address_b: str


@pytest.fixture
def hosts() -> Iterator[Hosts]:
    reason = _why_not()
    if reason:
        pytest.skip(reason)
    tag = os.getpid() % 100000
    h = Hosts(f"umbra-a-{tag}", f"umbra-b-{tag}", f"ua{tag}", "10.231.0.2")
    veth_b = f"ub{tag}"
    steps = [
        ("netns", "add", h.a),
        ("netns", "add", h.b),
        ("link", "add", h.veth_a, "type", "veth", "peer", "name", veth_b),
        ("link", "set", h.veth_a, "netns", h.a),
        ("link", "set", veth_b, "netns", h.b),
        ("-n", h.a, "addr", "add", "10.231.0.1/24", "dev", h.veth_a),
        ("-n", h.b, "addr", "add", f"{h.address_b}/24", "dev", veth_b),
        ("-n", h.a, "link", "set", "lo", "up"),
        ("-n", h.b, "link", "set", "lo", "up"),
        ("-n", h.a, "link", "set", h.veth_a, "up"),
        ("-n", h.b, "link", "set", veth_b, "up"),
    ]
    try:
        for step in steps:
            done = _ip(*step)
            if done.returncode != 0:
                pytest.skip(
                    f"cannot build the two-host network (ip {' '.join(step)}): "
                    f"{done.stderr.strip()}"
                )
        yield h
    finally:
        _ip("netns", "del", h.a)
        _ip("netns", "del", h.b)


def test_link_down_fires_the_watchdog_and_data_flows_again_when_it_returns(
    hosts: Hosts, umbra: Callable[..., Running], tmp_path: Path
) -> None:
    (tmp_path / "g.yaml").write_text(GRAPH)
    endpoint = f"tcp/{hosts.address_b}:7447"
    consumer = umbra(
        "run",
        "g.yaml",
        "--process",
        "smart",
        "--listen",
        endpoint,
        "--insecure",  # plain TCP between the two hosts: this test is about a cut link
        "--out",
        "out",
        "--duration",
        "60",
        prefix=("ip", "netns", "exec", hosts.b),
    )
    producer = umbra(
        "run",
        "g.yaml",
        "--process",
        "umbra",
        "--connect",
        endpoint,
        "--insecure",
        "--out",
        "out",
        "--duration",
        "60",
        prefix=("ip", "netns", "exec", hosts.a),
    )
    consumer.wait_for("link up")
    time.sleep(0.3)
    assert _ip("-n", hosts.a, "link", "set", hosts.veth_a, "down").returncode == 0
    consumer.wait_for("watchdog fired", timeout=5)
    # after the zenoh lease; the two "hosts" are network namespaces of one machine, sharing its
    # /dev/shm and pids, so the consumer sees that `umbra`'s process lives: late, not gone
    # (``umbra.runtime.links.late``; a peer on another machine is declared gone here)
    consumer.wait_for("process `umbra` is late", timeout=10)
    assert _ip("-n", hosts.a, "link", "set", hosts.veth_a, "up").returncode == 0
    consumer.wait_for("link healthy again", timeout=20)
    time.sleep(0.3)  # a window: nothing restarts the producer
    assert producer.popen.poll() is None  # nothing was restarted
    for run in (consumer, producer):
        run.popen.send_signal(signal.SIGINT)
    assert consumer.finish() == 130, consumer.text
    assert producer.finish() == 130, producer.text
    summary = json.loads((tmp_path / "out" / "summary-smart.json").read_text())
    watch = next(m for m in summary["modules"] if m["module"] == "watch")
    assert watch["fired"] >= 1 and watch["revived"] >= 1
    assert watch["last_seq"] > watch["seq_at_revival"] > 0  # samples after the link came back
    (sub,) = summary["links"]["subscribe"]
    assert sub["restarts"] == 0 and sub["decode_errors"] == 0
    assert sub["missing"] > 0  # what was published while the link was down never came
