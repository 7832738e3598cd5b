"""Two processes started by hand (``--process``), as on two hosts: liveliness and foreign samples.

One run serves three tests: while the producer streams, a foreign publisher puts garbage on the
link's key — first as itself (refused: not the producer's session), then claiming the producer's
session id (nothing authenticates sessions here, so it gets as far as the decoder, which refuses
it); then the producer is killed with SIGKILL and the consumer must see it gone.
"""

from __future__ import annotations

import json
import os
import signal
import time
from collections.abc import Iterator
from dataclasses import dataclass

import msgspec
import numpy as np
import pytest
import zenoh

from connectors.codec import Codec
from connectors.messages import Scalar, Text
from runtime.links.config import Endpoints, build_config, free_loopback_ports
from tests.links.conftest import Running, start_umbra, stop_all, watched_counter_graph

GRAPH = watched_counter_graph("byhand")
KEY = "umbra/byhand/counter/count"


def garbage() -> list[bytes]:
    """Payloads that are not Scalar samples of this build: each must be dropped and counted."""
    codec = Codec()
    good = codec.encode(Scalar(value=1.0, seq=10**6))
    enc = msgspec.msgpack.Encoder()
    return [
        b"",
        b"hello, world",
        bytes(np.random.default_rng(0).integers(0, 256, 300, dtype=np.uint8)),
        good[: len(good) // 2],  # truncated
        good.replace(b"\xa5umbra\x01", b"\xa5umbra\x02"),  # another encoding version
        codec.encode(Text(text="not a scalar", seq=10**6)),  # another type
        enc.encode(["umbra", 1, "Scalar", {"value": "NaN?", "seq": 10**6}]),  # bad field
        enc.encode(["umbra", 1, "Vector", {"values": msgspec.msgpack.Ext(1, b"\x03|O8\x01")}]),
    ]


@dataclass
class Scene:
    consumer: Running
    summary: dict
    killed_at: float
    garbage_sent: int


@pytest.fixture(scope="module")
def scene(plugin_env: dict[str, str], tmp_path_factory: pytest.TempPathFactory) -> Iterator[Scene]:
    cwd = tmp_path_factory.mktemp("byhand")
    (cwd / "byhand.yaml").write_text(GRAPH)
    port, producer_port = free_loopback_ports(2)
    endpoint = f"tcp/127.0.0.1:{port}"
    producer_endpoint = f"tcp/127.0.0.1:{producer_port}"  # open too: the spy overhears there
    runs: list[Running] = []
    try:
        # the consumer takes its endpoint from a zenoh configuration file, as a deployment would
        (cwd / "smart.json5").write_text(f'{{ listen: {{ endpoints: ["{endpoint}"] }} }}')
        consumer = start_umbra(
            plugin_env,
            cwd,
            "run",
            "byhand.yaml",
            "--process",
            "smart",
            "--zenoh-config",
            "smart.json5",
            "--out",
            "out",
            "--duration",
            "60",
        )
        runs.append(consumer)
        producer = start_umbra(
            plugin_env,
            cwd,
            "run",
            "byhand.yaml",
            "--process",
            "umbra",
            "--connect",
            endpoint,
            "--listen",
            producer_endpoint,
            "--out",
            "out",
            "--duration",
            "60",
        )
        runs.append(producer)
        consumer.wait_for("link up")
        payloads = garbage()
        session = zenoh.open(build_config(Endpoints(connect=[endpoint, producer_endpoint])))
        try:
            pub = session.declare_publisher(KEY, congestion_control=zenoh.CongestionControl.BLOCK)
            deadline = time.monotonic() + 10
            while not pub.matching_status.matching and time.monotonic() < deadline:
                time.sleep(0.01)
            for payload in payloads:
                pub.put(payload)  # as itself: not the producer
            consumer.wait_for("refused a sample", timeout=10)
            overheard: list[zenoh.Sample] = []
            spy = session.declare_subscriber(KEY, overheard.append)
            while not overheard and time.monotonic() < deadline + 10:
                time.sleep(0.01)
            spy.undeclare()
            forged = overheard[0].source_info  # copied from a genuine sample
            for payload in payloads:
                pub.put(payload, source_info=forged)  # claiming the producer's session id
            consumer.wait_for("does not decode", timeout=10)
        finally:
            session.close()
        time.sleep(0.3)  # the producer keeps streaming after the garbage
        killed_at = time.monotonic()
        os.kill(producer.popen.pid, signal.SIGKILL)
        consumer.wait_for("watchdog fired")
        consumer.popen.send_signal(signal.SIGINT)
        assert consumer.finish() == 130, consumer.text
        summary = json.loads((cwd / "out" / "summary-smart.json").read_text())
        yield Scene(consumer, summary, killed_at, len(payloads))
    finally:
        stop_all(runs)


def _watch(summary: dict) -> dict:
    return next(m for m in summary["modules"] if m["module"] == "watch")


def test_garbage_on_a_link_key_is_dropped_counted_and_logged(scene: Scene) -> None:
    (sub,) = scene.summary["links"]["subscribe"]
    assert sub["foreign"] == scene.garbage_sent  # as itself: refused before decoding
    assert sub["decode_errors"] == scene.garbage_sent  # claiming the producer's session id
    assert sub["stale_dropped"] == 0 and sub["missing"] == 0
    # kept running after it; a sample that beat the producer's liveliness token is dropped too
    assert sub["received"] + sub["unattributed"] == _watch(scene.summary)["last_seq"] > 30
    logged = [line for line in scene.consumer.stderr if "does not decode" in line]
    assert len(logged) == 1  # one line, then rate-limited
    assert KEY in logged[0]


def test_killed_producer_is_seen_by_the_consumer_within_half_a_second(scene: Scene) -> None:
    watch = _watch(scene.summary)
    assert 0 < watch["last_dead"] - scene.killed_at < 0.5
    assert watch["fired"] >= 1


def test_consumer_summary_names_the_interrupt(scene: Scene) -> None:
    assert scene.summary["exit_code"] == 130
    assert "interrupted by SIGINT" in scene.summary["reason"]
