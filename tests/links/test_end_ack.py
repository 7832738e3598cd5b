"""A process that ends keeps its links open until its consumers have read its ends of stream
(``umbra.runtime.links.end_ack``), with real zenoh sessions on loopback."""

from __future__ import annotations

import threading
from collections.abc import Iterator

import pytest
import zenoh

from tests.links.conftest import REPO
from tests.links.test_transport import Pair, _pair, _ready
from tests.poll import wait_for
from umbra.connectors.messages import Message, Scalar
from umbra.runtime.graph.check import load_graph
from umbra.runtime.graph.plan import GraphPlan
from umbra.runtime.links.config import Endpoints, build_config, free_loopback_ports
from umbra.runtime.links.end_ack import ended_key, ended_proof
from umbra.runtime.links.identity import NO_PROOF
from umbra.runtime.links.transport import ZenohTransport

#: the run's key for the tokens' proofs in the test of forged words (hex, as credentials give it)
TOKEN_KEY = "ab" * 32


@pytest.fixture
def plan() -> GraphPlan:
    return load_graph(str(REPO / "graphs" / "counter_split.yaml"))


@pytest.fixture
def pair(plan: GraphPlan) -> Iterator[Pair]:
    p = _pair(plan)
    yield p
    p.producer.close()
    p.consumer.close()


def test_a_producer_closes_only_once_a_busy_consumer_has_read_its_last_sample(
    plan: GraphPlan, pair: Pair
) -> None:
    """The consumer's zenoh thread is held on the last sample (a starved process): the
    producer's close waits for it, and the last sample and the end both arrive."""
    link = plan.links[0]
    got: list[Message] = []
    held, release = threading.Event(), threading.Event()

    def slow(msg: Message) -> None:
        got.append(msg)
        if msg.seq == 50:
            held.set()
            release.wait(30)

    send = _ready(pair, [link], [])
    pair.consumer.subscribe(link, slow)  # a second connection of the same output
    for i in range(1, 51):
        send(Scalar(value=float(i), seq=i, stamp=float(i)))
    wait_for(held.is_set, 10, "the consumer to hold the last sample")
    closing = threading.Thread(target=pair.producer.close)
    closing.start()
    wait_for(lambda: pair.producer.end_acks.waiting == {"smart"}, 10, "the close to wait")
    assert closing.is_alive() and not pair.consumer.inputs_ended()
    release.set()
    closing.join(10)
    assert not closing.is_alive()
    assert [m.seq for m in got] == list(range(1, 51))
    assert pair.producer.end_acks.heard() == {"smart"}
    wait_for(pair.consumer.inputs_ended, 10, "the consumer to see the end")
    assert pair.consumer.stats()["subscribe"][0]["ended"] == 1


def test_a_consumer_that_never_reads_holds_the_close_at_most_the_bound(
    plan: GraphPlan, pair: Pair
) -> None:
    _ready(pair, [plan.links[0]], [])
    wait_for(lambda: "smart" in pair.producer.alive_processes(), 10, "the consumer up")
    # nothing ended, so the consumer says nothing: the wait gives up, naming it
    silent = pair.producer.end_acks.wait({"smart"}, pair.producer.alive_processes, 0.2)
    assert silent == {"smart"} and pair.producer.end_acks.waiting == frozenset()


def test_a_consumer_that_is_gone_is_not_waited_for(plan: GraphPlan, pair: Pair) -> None:
    _ready(pair, [plan.links[0]], [])
    wait_for(lambda: "smart" in pair.producer.alive_processes(), 10, "the consumer up")
    pair.consumer.close()
    wait_for(lambda: "smart" not in pair.producer.alive_processes(), 10, "the consumer gone")
    assert pair.producer.end_acks.wait({"smart"}, pair.producer.alive_processes, 30) == set()
    assert pair.producer.end_acks.heard() == set()


def test_only_a_word_for_this_session_with_its_proof_counts(plan: GraphPlan) -> None:
    """Words naming another session of the producer, or without the run's proof, count for
    nothing; the true one does."""
    (port,) = free_loopback_ports(1)
    endpoint = f"tcp/127.0.0.1:{port}"
    producer_session = zenoh.open(build_config(Endpoints([endpoint], [])))
    producer = ZenohTransport(producer_session, plan, "umbra", token_key=TOKEN_KEY)
    other = zenoh.open(build_config(Endpoints([], [endpoint])))
    tokens = []
    try:
        me = str(producer_session.zid())
        prefix = plan.key_prefix
        old_session = "0" * 32
        wrong = [  # another session of the producer; no proof; another run's proof
            (old_session, ended_proof(TOKEN_KEY, "smart", "umbra", old_session)),
            (me, NO_PROOF),
            (me, ended_proof("cd" * 32, "smart", "umbra", me)),
        ]
        for session, proof in wrong:
            key = ended_key(prefix, "smart", "umbra", session, proof)
            tokens.append(other.liveliness().declare_token(key))
        true = ended_key(prefix, "probe", "umbra", me, ended_proof(TOKEN_KEY, "probe", "umbra", me))
        tokens.append(other.liveliness().declare_token(true))  # after the wrong ones, in order
        wait_for(lambda: "probe" in producer.end_acks.heard(), 10, "the true word")
        assert producer.end_acks.heard() == {"probe"}
    finally:
        for token in tokens:
            token.undeclare()
        other.close()
        producer.close()


def test_a_finish_waits_for_the_ends_of_the_process_that_ended_even_a_mutual_peer(
    plan: GraphPlan, pair: Pair
) -> None:
    """``finish`` skips the streams of mutual peers, but not those of the process whose end
    caused it: they end, and what it sent last comes first (``links.process``)."""
    _ready(pair, [plan.links[0]], [])
    wait_for(lambda: "umbra" in pair.consumer.alive_processes(), 10, "the producer up")
    peer = frozenset({"umbra"})
    assert pair.consumer.inputs_ended(besides=peer)
    assert not pair.consumer.inputs_ended(besides=peer, closed=peer)
    pair.producer.close()
    assert pair.consumer.inputs_ended(besides=peer, closed=peer)  # read before the close ended
