"""Two processes started by hand (``--process``), as an operator would on one host: credentials,
liveliness and foreign peers.

Two runs of the same graph, each serving several tests:

* by default (no flag): both processes derive their credentials from this user's secret
  (``umbra.runtime.links.host_auth``; the tests' ``XDG_RUNTIME_DIR`` is a private temporary folder).
  A foreign zenoh peer without credentials connects to both endpoints, once as itself and once
  claiming the producer's zenoh id (so every sample it puts carries the producer's session id as
  its source): it is let in by neither, overhears nothing and delivers nothing;
* with ``--insecure`` (today's open links): the same peer gets in, overhears the producer, and
  what it puts is refused by the link's own checks — as itself (not the producer's session),
  then with a copied source id (it gets as far as the decoder, which refuses it).

In both runs the producer is then killed with SIGKILL and the consumer must see it gone.
"""

from __future__ import annotations

import json
import os
import re
import signal
import stat
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import msgspec
import numpy as np
import pytest
import zenoh

from tests.links.conftest import Running, start_umbra, stop_all, watched_counter_graph
from umbra.connectors.codec import Codec
from umbra.connectors.messages import Scalar, Text
from umbra.runtime.links.config import Endpoints, build_config, free_loopback_ports

GRAPH = watched_counter_graph("byhand")
PREFIX = "umbra/byhand"
KEY = f"{PREFIX}/counter/count"
#: Seconds a foreign peer is given to get in and overhear (the producer sends 100 samples/s).
LISTEN_S = 1.5


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


def commands() -> list[bytes]:
    """Well-formed samples a peer would inject: plausible and jamming sequence numbers."""
    codec = Codec()
    return [codec.encode(Scalar(value=-1.0, seq=s)) for s in (10**3, 10**4, 2**20, 2**40)]


@dataclass
class Peer:
    """What a foreign peer achieved: sessions it was let into, samples and tokens it heard."""

    peers: list[str] = field(default_factory=list)
    overheard: int = 0
    tokens: int = 0
    sent: int = 0


@dataclass
class Scene:
    cwd: Path
    consumer: Running
    summary: dict
    killed_at: float
    garbage_sent: int
    producer_zid: str
    stranger: Peer
    impostor: Peer


def _peer(endpoints: list[str], zid: str | None, payloads: list[bytes], copy: bool) -> Peer:
    """Open a plain zenoh session (no credentials; scouting off, loopback endpoints) connected to
    ``endpoints``, with zenoh id ``zid`` when given; listen on the graph's keys for a while, then
    put ``payloads`` on the link's key: as itself, and (``copy``) with the source of an
    overheard sample."""
    cfg = build_config(Endpoints(connect=endpoints))
    if zid is not None:
        cfg.insert_json5("id", json.dumps(zid))
    session = zenoh.open(cfg)
    got = Peer()
    try:
        heard: list[zenoh.Sample] = []
        spy = session.declare_subscriber(f"{PREFIX}/**", heard.append)
        pub = session.declare_publisher(KEY, congestion_control=zenoh.CongestionControl.BLOCK)
        deadline = time.monotonic() + LISTEN_S
        while time.monotonic() < deadline and not (copy and heard and pub.matching_status.matching):
            time.sleep(0.01)
        got.peers = [str(z) for z in session.info.peers_zid()]
        got.tokens = len(list(session.liveliness().get(f"{PREFIX}/_alive/**", timeout=0.5)))
        spy.undeclare()  # (it would hear its own samples from now on)
        got.overheard = len(heard)
        for payload in payloads:
            pub.put(payload)  # as itself (with ``zid``: in the producer's name)
            got.sent += 1
        if copy and heard:
            forged = heard[0].source_info  # copied from a genuine sample
            for payload in payloads:
                pub.put(payload, source_info=forged)
                got.sent += 1
        time.sleep(0.3)
    finally:
        session.close()
    return got


def _run(env: dict[str, str], cwd: Path, insecure: bool) -> Iterator[Scene]:
    (cwd / "byhand.yaml").write_text(GRAPH)
    port, producer_port = free_loopback_ports(2)
    endpoint = f"tcp/127.0.0.1:{port}"
    producer_endpoint = f"tcp/127.0.0.1:{producer_port}"  # the spy tries there too
    flags = ("--insecure",) if insecure else ()
    common = ("--out", "out", "--duration", "60", *flags)
    runs: list[Running] = []
    try:
        # the consumer takes its endpoint from a zenoh configuration file, as a deployment
        # would; the file sets up no authentication, so the derived credentials still apply
        (cwd / "smart.json5").write_text(f'{{ listen: {{ endpoints: ["{endpoint}"] }} }}')
        consumer = start_umbra(
            env, cwd, "run", "byhand.yaml", "--process", "smart", "--zenoh-config",
            "smart.json5", *common,
        )  # fmt: skip
        runs.append(consumer)
        producer = start_umbra(
            env, cwd, "run", "byhand.yaml", "--process", "umbra", "--connect", endpoint,
            "--listen", producer_endpoint, *common,
        )  # fmt: skip
        runs.append(producer)
        consumer.wait_for("link up")
        up = consumer.wait_for("process `umbra` is up")
        producer_zid = re.search(r"session ([0-9a-f]+)", up).group(1)  # type: ignore[union-attr]
        payloads = garbage()
        both = [endpoint, producer_endpoint]
        if insecure:
            stranger = _peer(both, None, payloads, copy=True)
            consumer.wait_for("refused a sample", timeout=10)
            consumer.wait_for("does not decode", timeout=10)
            impostor = Peer()
        else:
            stranger = _peer(both, None, payloads + commands(), copy=True)
            impostor = _peer(both, producer_zid, payloads + commands(), copy=True)
        time.sleep(0.3)  # the producer keeps streaming after the foreign peers
        killed_at = time.monotonic()
        os.kill(producer.popen.pid, signal.SIGKILL)
        consumer.wait_for("watchdog fired")
        consumer.popen.send_signal(signal.SIGINT)
        assert consumer.finish() == 130, consumer.text
        summary = json.loads((cwd / "out" / "summary-smart.json").read_text())
        yield Scene(
            cwd, consumer, summary, killed_at, len(payloads), producer_zid, stranger, impostor
        )
    finally:
        stop_all(runs)


@pytest.fixture(scope="module")
def authenticated(
    plugin_env: dict[str, str], tmp_path_factory: pytest.TempPathFactory
) -> Iterator[Scene]:
    yield from _run(plugin_env, tmp_path_factory.mktemp("byhand"), insecure=False)


@pytest.fixture(scope="module")
def insecure(
    plugin_env: dict[str, str], tmp_path_factory: pytest.TempPathFactory
) -> Iterator[Scene]:
    yield from _run(plugin_env, tmp_path_factory.mktemp("byhand_insecure"), insecure=True)


@pytest.fixture(params=["authenticated", "insecure"])
def scene(request: pytest.FixtureRequest) -> Scene:
    return request.getfixturevalue(request.param)


def _watch(summary: dict) -> dict:
    return next(m for m in summary["modules"] if m["module"] == "watch")


def test_processes_by_hand_link_with_credentials_derived_from_the_users_secret(
    authenticated: Scene, plugin_env: dict[str, str]
) -> None:
    (sub,) = authenticated.summary["links"]["subscribe"]
    # linked and delivered: every sample counted (one may beat the producer's token)
    assert sub["received"] + sub["unattributed"] == _watch(authenticated.summary)["last_seq"] > 30
    assert sub["missing"] == 0 and sub["stale_dropped"] == 0
    assert "links authenticated with this user's secret" in authenticated.consumer.text
    # the session id the producer stamps is the zenoh id derived for it from the secret
    assert len(authenticated.producer_zid) == 32
    folder = Path(plugin_env["XDG_RUNTIME_DIR"]) / "umbra"
    assert stat.S_IMODE(folder.stat().st_mode) == 0o700
    (secret,) = [p for p in folder.glob("links-byhand-*") if p.suffix != ".dict"]
    assert stat.S_IMODE(secret.stat().st_mode) == 0o600 and len(secret.read_text()) == 65


def test_a_peer_without_credentials_can_neither_join_nor_overhear_nor_deliver(
    authenticated: Scene,
) -> None:
    for peer in (authenticated.stranger, authenticated.impostor):
        assert peer.peers == []  # refused by both processes when it connected
        assert peer.overheard == 0 and peer.tokens == 0
        assert peer.sent == authenticated.garbage_sent + 4  # it tried, in vain
    (sub,) = authenticated.summary["links"]["subscribe"]
    # nothing reached the link: not even as far as its own checks
    for counter in ("foreign", "decode_errors", "implausible", "oversize", "after_gone"):
        assert sub[counter] == 0, (counter, sub)
    assert authenticated.summary["links"]["forged_tokens"] == 0
    assert "refused a sample" not in authenticated.consumer.text
    assert "does not decode" not in authenticated.consumer.text


def test_insecure_peers_get_in_and_the_links_own_checks_refuse_them(insecure: Scene) -> None:
    assert insecure.stranger.peers and insecure.stranger.overheard > 0  # the old, open links
    (sub,) = insecure.summary["links"]["subscribe"]
    assert sub["foreign"] == insecure.garbage_sent  # as itself: refused before decoding
    assert sub["decode_errors"] == insecure.garbage_sent  # claiming the producer's session id
    assert sub["stale_dropped"] == 0 and sub["missing"] == 0
    # kept running after it; a sample that beat the producer's liveliness token is dropped too
    assert sub["received"] + sub["unattributed"] == _watch(insecure.summary)["last_seq"] > 30
    logged = [line for line in insecure.consumer.stderr if "does not decode" in line]
    assert len(logged) == 1  # one line, then rate-limited
    assert KEY in logged[0]
    assert "links authenticated" not in insecure.consumer.text


def test_killed_producer_is_seen_by_the_consumer_within_half_a_second(scene: Scene) -> None:
    watch = _watch(scene.summary)
    assert 0 < watch["last_dead"] - scene.killed_at < 0.5
    assert watch["fired"] >= 1


def test_consumer_summary_names_the_interrupt(scene: Scene) -> None:
    assert scene.summary["exit_code"] == 130
    assert "interrupted by SIGINT" in scene.summary["reason"]
