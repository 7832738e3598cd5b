"""Only the producer's live session drives a link (real zenoh sessions on loopback).

An attacker session is connected to both processes (an open port), overhears genuine samples and
copies their source id — the strongest claim a peer can make without credentials. Without
authentication that claim is accepted while the producer lives (what closes it is the launcher's
per-run credentials and access-control rules, see ``test_attacks``); these tests pin down the rest:
a gone producer stays gone, sequence numbers cannot be jammed, sizes are bounded, a second token
does not take over, a restarted producer starts a new count; with the run's token key, a token
without its proof makes nobody appear.
"""

from __future__ import annotations

import json
import secrets
import threading
import time
from collections.abc import Callable

import pytest
import zenoh

from tests.links.conftest import REPO
from tests.links.pairs import Pair, open_pair, ready_pair
from tests.links.test_transport import IMAGE_GRAPH, Camera, Viewer
from tests.matching import wait_subscriptions_reached
from tests.poll import wait_for
from umbra.connectors.codec import Codec
from umbra.connectors.messages import Image, Message, Scalar, Twist
from umbra.runtime.graph.check import check_spec, load_graph
from umbra.runtime.graph.parse import parse_graph_text
from umbra.runtime.graph.plan import GraphPlan, LinkPlan
from umbra.runtime.links import trust
from umbra.runtime.links.bounds import ENVELOPE_BYTES, max_sample_bytes
from umbra.runtime.links.config import Endpoints, build_config, free_loopback_ports
from umbra.runtime.links.identity import alive_key, parse_alive_key, sign
from umbra.runtime.links.transport import ZenohTransport
from umbra.runtime.registry import Registry


class Attacker:
    """A foreign session connected to both processes of a pair."""

    def __init__(self, pair: Pair, key: str) -> None:
        producer_endpoint = pair.producer_endpoint
        self.session = zenoh.open(
            build_config(Endpoints(connect=[pair.consumer_endpoint, producer_endpoint]))
        )
        self.overheard: list[zenoh.Sample] = []
        self.spy = self.session.declare_subscriber(key, self.overheard.append)
        self.pub = self.session.declare_publisher(
            key, congestion_control=zenoh.CongestionControl.BLOCK
        )
        self.codec = Codec()
        wait_for(lambda: len(list(self.session.info.peers_zid())) == 2, 5.0, "two peers")
        wait_subscriptions_reached(
            self.session, pair.producer._session, 5.0, "the spy's subscription at the producer"
        )

    def wait_matching(self) -> None:
        wait_for(lambda: self.pub.matching_status.matching, 5.0, "the publisher to match")

    def copied_source(self) -> zenoh.SourceInfo:
        wait_for(lambda: bool(self.overheard), 5.0, "an overheard sample")
        return self.overheard[-1].source_info

    def put(self, msg: Message | bytes, source: zenoh.SourceInfo | None) -> None:
        data = msg if isinstance(msg, bytes) else self.codec.encode(msg)
        self.pub.put(data, source_info=source)

    def close(self) -> None:
        self.session.close()


def _sub(pair: Pair) -> dict:
    (sub,) = pair.consumer.stats()["subscribe"]
    return sub


def test_a_gone_producer_stays_gone_whatever_arrives_in_its_name(
    counter_plan: GraphPlan, pair: Pair
) -> None:
    link = counter_plan.links[0]
    got: list[Message] = []
    send = ready_pair(pair, [link], got)
    attacker = Attacker(pair, link.key)
    try:
        send(Scalar(value=1.0, seq=1))
        source = attacker.copied_source()
        wait_for(lambda: len(got) == 1, 5.0, "the first sample")
        pair.producer._session.close()  # dies without ending its streams (as kill -9 would)
        wait_for(lambda: not pair.consumer.producer_alive(link), 5.0, "the producer gone")
        attacker.wait_matching()
        deadline = time.monotonic() + 0.4  # four times the old revive delay
        seq = 2
        while time.monotonic() < deadline:
            attacker.put(Scalar(value=99.0, seq=seq), source)
            seq += 1
            time.sleep(0.002)
        wait_for(
            lambda: _sub(pair)["after_gone"] >= seq - 2, 5.0, "the samples after its end counted"
        )
        assert not pair.consumer.producer_alive(link)
        assert [m.value for m in got] == [1.0]  # nothing injected was delivered
        assert pair.consumer.stats()["liveliness_flaps"] == 0
    finally:
        attacker.close()


def test_one_huge_sequence_number_does_not_make_genuine_samples_old(
    counter_plan: GraphPlan, pair: Pair
) -> None:
    link = counter_plan.links[0]
    got: list[Message] = []
    send = ready_pair(pair, [link], got)
    send(Scalar(value=1.0, seq=1))
    send(Scalar(value=2.0, seq=2**62))  # beyond any plausible count
    send(Scalar(value=3.0, seq=2 + 2**21))  # a jump further than any plausible loss
    send(Scalar(value=4.0, seq=2))
    send(Scalar(value=5.0, seq=3))
    wait_for(lambda: len(got) == 3, 5.0, "3 samples")
    time.sleep(0.05)  # a window: the dropped samples stay dropped
    assert [m.value for m in got] == [1.0, 4.0, 5.0]
    sub = _sub(pair)
    assert sub["implausible"] == 2 and sub["stale_dropped"] == 0 and sub["last_seq"] == 3


def test_samples_larger_than_the_type_allows_are_dropped_before_decoding(
    counter_plan: GraphPlan, pair: Pair
) -> None:
    link = counter_plan.links[0]
    bound = max_sample_bytes(Scalar)
    assert bound == ENVELOPE_BYTES  # a Scalar holds no array
    got: list[Message] = []
    send = ready_pair(pair, [link], got)
    attacker = Attacker(pair, link.key)
    try:
        send(Scalar(value=1.0, seq=1))
        source = attacker.copied_source()  # attributed: only the size stops it
        attacker.wait_matching()
        for size in (bound + 1, 1 << 20, 64 << 20):
            attacker.put(b"\x00" * size, source)
        send(Scalar(value=2.0, seq=2))
        wait_for(
            lambda: len(got) == 2 and _sub(pair)["oversize"] == 3, 20, "2 samples and 3 oversize"
        )
    finally:
        attacker.close()
    sub = _sub(pair)
    assert sub["decode_errors"] == 0 and sub["max_bytes"] == bound
    assert [m.value for m in got] == [1.0, 2.0]


def test_a_second_token_of_a_live_process_does_not_take_over(
    counter_plan: GraphPlan, pair: Pair
) -> None:
    link = counter_plan.links[0]
    got: list[Message] = []
    send = ready_pair(pair, [link], got)
    attacker = Attacker(pair, link.key)
    try:
        send(Scalar(value=1.0, seq=1))
        wait_for(lambda: len(got) == 1, 5.0, "the first sample")
        own = str(attacker.session.zid())
        token = attacker.session.liveliness().declare_token(
            alive_key(counter_plan.key_prefix, "umbra", "none", own)
        )
        wait_for(lambda: pair.consumer.stats()["token_conflicts"] == 1, 5.0, "the token conflict")
        attacker.wait_matching()
        attacker.put(Scalar(value=66.0, seq=2), None)
        pair.producer._session.close()  # the genuine producer dies; the impostor's token stays
        wait_for(lambda: not pair.consumer.producer_alive(link), 5.0, "the producer gone")
        attacker.put(Scalar(value=77.0, seq=3), None)
        time.sleep(0.1)  # a window: the impostor's sample is not delivered
        assert not pair.consumer.producer_alive(link)
        assert [m.value for m in got] == [1.0]
        token.undeclare()
    finally:
        attacker.close()


def test_a_restarted_producer_starts_a_new_count(counter_plan: GraphPlan, pair: Pair) -> None:
    link = counter_plan.links[0]
    got: list[Message] = []
    send = ready_pair(pair, [link], got)
    for i in range(1, 51):
        send(Scalar(value=float(i), seq=i))
    wait_for(lambda: len(got) == 50, 5.0, "50 samples")
    producer_endpoint = pair.producer_endpoint
    pair.producer.close()
    wait_for(lambda: not pair.consumer.producer_alive(link), 5.0, "the producer gone")
    session = zenoh.open(build_config(Endpoints(listen=[producer_endpoint])))
    again = ZenohTransport(session, counter_plan, "umbra")
    try:
        sink = again.publisher(link)
        again.announce()
        assert again.wait_ready(threading.Event(), timeout=10)
        wait_for(
            lambda: "umbra" in pair.consumer.alive_processes(), 5.0, "the producer alive again"
        )
        for i in range(1, 11):
            sink(Scalar(value=100.0 + i, seq=i), 0.0)
        wait_for(lambda: len(got) == 60, 5.0, "60 samples")
    finally:
        again.close()
    sub = _sub(pair)
    assert [m.seq for m in got[50:]] == list(range(1, 11))
    assert sub["restarts"] == 1 and sub["stale_dropped"] == 0


def test_a_process_accepts_no_zenoh_message_larger_than_its_links_need() -> None:
    from umbra.runtime.links.bounds import MIN_INBOUND_BYTES, inbound_limit

    plan = load_graph(str(REPO / "graphs" / "tool_pickup.yaml"))
    # the servo side receives twists, statuses and commands: zenoh's own floor
    assert inbound_limit(plan, "smart") == MIN_INBOUND_BYTES
    registry = Registry()
    registry.add(Camera)
    registry.add(Viewer)
    video = check_spec(parse_graph_text(IMAGE_GRAPH, "video.yaml"), registry)
    (link,) = video.links
    assert inbound_limit(video, "smart") == max_sample_bytes(Image) + ENVELOPE_BYTES
    assert max_sample_bytes(Image) == 4096 * 3072 * 4 + 64 * 1024  # no declared size
    assert inbound_limit(video, "umbra") == MIN_INBOUND_BYTES  # it consumes nothing
    assert link.key == "umbra/video/cam/image"


def test_an_images_bound_comes_from_its_producers_declared_size() -> None:
    plan = load_graph(str(REPO / "graphs" / "tool_pickup.yaml"))
    camera = plan.modules["camera"].params
    assert (camera.width, camera.height) == (1280, 720)
    assert max_sample_bytes(Image, camera) == 1280 * 720 * 4 + 64 * 1024
    assert max_sample_bytes(Twist) == 6 * 8 + ENVELOPE_BYTES


def test_a_key_prefix_holding_an_alive_chunk_still_names_its_processes() -> None:
    assert parse_alive_key("umbra/_alive/_alive/smart/m1/abc/p") == ("smart", "m1", "abc", "p")
    assert parse_alive_key("umbra/g/_alive/_alive/none/abc/p") == ("_alive", "none", "abc", "p")
    assert parse_alive_key("umbra/g/_alive/smart/none/abc") is None
    assert parse_alive_key("umbra/g/smart/none/abc/p") is None
    plan = load_graph(str(REPO / "graphs" / "counter_split.yaml"), prefix="umbra/_alive")
    (link,) = {link.key: link for link in plan.links}.values()
    assert link.key == "umbra/_alive/counter/count"
    pair = open_pair(plan)
    try:
        got: list[Message] = []
        send = ready_pair(pair, [link], got)  # the producer sees its consumer come up
        send(Scalar(value=1.0, seq=1))
        wait_for(lambda: len(got) == 1, 5.0, "the first sample")
        assert pair.consumer.alive_processes() == {"umbra"}
    finally:
        pair.producer.close()
        pair.consumer.close()


def test_tokens_of_processes_the_graph_does_not_have_are_ignored(
    counter_plan: GraphPlan, pair: Pair
) -> None:
    link = counter_plan.links[0]
    got: list[Message] = []
    send = ready_pair(pair, [link], got)
    attacker = Attacker(pair, link.key)
    try:
        own = str(attacker.session.zid())
        tokens = [
            attacker.session.liveliness().declare_token(
                alive_key(counter_plan.key_prefix, f"stranger{i}", "none", own)
            )
            for i in range(200)
        ]
        probe = attacker.session.liveliness().declare_token(
            alive_key(counter_plan.key_prefix, "smart", "none", own)  # a process of the graph
        )
        wait_for(lambda: pair.producer.stats()["token_conflicts"] == 1, 5.0, "the token conflict")
        send(Scalar(value=1.0, seq=1))
        wait_for(lambda: len(got) == 1, 5.0, "the first sample")
        assert pair.consumer.alive_processes() == {"umbra"}  # no stranger is tracked
        assert pair.consumer._sessions.current.keys() == {"umbra"}
        for token in [*tokens, probe]:
            token.undeclare()
    finally:
        attacker.close()


def _before_the_token(pair: Pair, link: LinkPlan, got: list[Message]) -> Callable[..., None]:
    """Wire ``link`` with the consumer up and the producer's publisher matched, but the
    producer's token not declared yet: its samples overtake the token."""
    sink = pair.producer.publisher(link)
    pair.consumer.subscribe(link, got.append)
    pair.consumer.announce()
    publisher = pair.producer._pubs[link.key][0]
    wait_for(lambda: publisher.matching_status.matching, 5.0, "the publisher to match")
    return lambda msg: sink(msg, 0.0)


def test_samples_that_overtake_their_producers_token_wait_for_it(
    counter_plan: GraphPlan, pair: Pair, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(trust, "MAX_HOLD_S", 5.0)  # however slow this machine is
    link = counter_plan.links[0]
    got: list[Message] = []
    send = _before_the_token(pair, link, got)
    for i in range(1, 4):
        send(Scalar(value=float(i), seq=i))
    # held, counted as refused so far
    wait_for(lambda: _sub(pair)["unattributed"] == 3, 5.0, "3 unattributed samples")
    assert got == []
    pair.producer.announce()  # the token: they go through, in order, before any later one
    # else 4 is held too
    wait_for(lambda: "umbra" in pair.consumer.alive_processes(), 5.0, "the producer alive")
    send(Scalar(value=4.0, seq=4))
    wait_for(lambda: len(got) == 4, 5.0, "4 samples")
    assert [m.seq for m in got] == [1, 2, 3, 4]
    sub = _sub(pair)
    assert sub["held"] == 3 and sub["unattributed"] == 0 and sub["received"] == 4


def test_samples_whose_token_comes_too_late_or_names_another_session_are_dropped(
    counter_plan: GraphPlan, pair: Pair, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(trust, "MAX_HOLD_S", 0.2)
    link = counter_plan.links[0]
    got: list[Message] = []
    send = _before_the_token(pair, link, got)
    attacker = Attacker(pair, link.key)
    try:
        attacker.wait_matching()
        send(Scalar(value=1.0, seq=1))  # waits too long: the token comes after 0.5 s
        wait_for(lambda: _sub(pair)["unattributed"] == 1, 5.0, "1 unattributed sample")
        time.sleep(0.5)
        attacker.put(Scalar(value=66.0, seq=2), None)  # from another session: held, then
        # judged foreign
        wait_for(lambda: _sub(pair)["unattributed"] == 2, 5.0, "2 unattributed samples")
        pair.producer.announce()
        wait_for(lambda: _sub(pair)["foreign"] == 1, 5.0, "1 foreign sample")
        send(Scalar(value=3.0, seq=3))
        wait_for(lambda: len(got) == 1, 5.0, "the first sample")
    finally:
        attacker.close()
    assert [m.value for m in got] == [3.0]
    sub = _sub(pair)
    assert sub["unattributed"] == 1 and sub["held"] == 0 and sub["foreign"] == 1


def _session(listen: list[str], connect: list[str], zid: str | None = None) -> zenoh.Session:
    cfg = build_config(Endpoints(listen, connect))
    if zid is not None:
        cfg.insert_json5("id", json.dumps(zid))
    return zenoh.open(cfg)


def test_tokens_without_the_runs_proof_are_ignored_and_the_producer_returns_only_as_itself(
    counter_plan: GraphPlan,
) -> None:
    """As if a peer got past zenoh's checks (its sessions here are not authenticated at all):
    with the run's token key, a token it declares in the producer's name, with its own zenoh id
    or the producer's, makes nobody appear; the producer started again with the same zenoh id
    (as a process started by hand is: its id is derived from the user's secret) is let back in
    and starts a new count."""
    key, wrong = secrets.token_hex(32), secrets.token_hex(32)
    prefix, link = counter_plan.key_prefix, counter_plan.links[0]
    port_p, port_c = free_loopback_ports(2)
    producer_ep, consumer_ep = f"tcp/127.0.0.1:{port_p}", f"tcp/127.0.0.1:{port_c}"
    zid = format(secrets.randbits(127) | 1 << 126, "x")
    consumer = ZenohTransport(_session([consumer_ep], []), counter_plan, "smart", token_key=key)
    got: list[Message] = []
    consumer.subscribe(link, got.append)
    consumer.announce()
    attacker = _session([], [consumer_ep])
    started: list[ZenohTransport] = []

    def start() -> Callable[[Scalar], None]:
        session = _session([producer_ep], [consumer_ep], zid)
        producer = ZenohTransport(session, counter_plan, "umbra", token_key=key)
        started.append(producer)
        sink = producer.publisher(link)
        producer.announce()
        assert producer.wait_ready(threading.Event(), timeout=10)
        wait_for(lambda: consumer.producer_alive(link), 5.0, "the producer alive")
        return lambda msg: sink(msg, 0.0)

    def stop() -> None:
        started[-1]._session.close()  # dies without ending its streams (as kill -9 would)
        wait_for(lambda: not consumer.producer_alive(link), 5.0, "the producer gone")

    try:
        send = start()
        for i in range(1, 21):
            send(Scalar(value=float(i), seq=i))
        wait_for(lambda: len(got) == 20, 5.0, "20 samples")
        own = str(attacker.zid())
        liveliness = attacker.liveliness()
        tokens = [liveliness.declare_token(alive_key(prefix, "umbra", "none", own))]
        wait_for(lambda: consumer.forged_tokens == 1, 5.0, "1 forged token")
        assert consumer._sessions.conflicts == 0  # not even a rival: ignored outright
        stop()
        for proof in (sign(wrong, "umbra", "none", zid), "0" * 32):  # in the producer's id
            tokens.append(liveliness.declare_token(alive_key(prefix, "umbra", "none", zid, proof)))
        wait_for(lambda: consumer.forged_tokens == 3, 5.0, "3 forged tokens")
        pub = attacker.declare_publisher(link.key, congestion_control=zenoh.CongestionControl.BLOCK)
        wait_for(lambda: pub.matching_status.matching, 5.0, "the publisher to match")
        codec = Codec()
        for i in range(21, 31):
            pub.put(codec.encode(Scalar(value=-1.0, seq=i)))
        wait_for(lambda: _sub_of(consumer)["after_gone"] == 10, 5.0, "10 samples after its end")
        assert not consumer.producer_alive(link) and len(got) == 20
        send = start()  # the genuine producer again, same zenoh id, a new token
        for i in range(1, 6):
            send(Scalar(value=100.0 + i, seq=i))
        wait_for(lambda: len(got) == 25, 5.0, "25 samples")
        for token in tokens:
            token.undeclare()
    finally:
        attacker.close()
        for transport_ in [*started, consumer]:
            transport_.close()
    assert [m.seq for m in got] == [*range(1, 21), *range(1, 6)]
    sub = _sub_of(consumer)
    assert sub["restarts"] == 1 and sub["stale_dropped"] == 0
    # refused while the producer was gone, or (held for a token that came within 0.1 s)
    # judged again once it was back: not its session
    assert sub["after_gone"] + sub["foreign"] == 10
    assert consumer.stats()["forged_tokens"] == 3


def _sub_of(consumer: ZenohTransport) -> dict:
    (sub,) = consumer.stats()["subscribe"]
    return sub
