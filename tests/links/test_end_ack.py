"""A process that ends keeps its links open until its consumers have read its ends of stream
(``umbra.runtime.links.end_ack``), with real zenoh sessions on loopback."""

from __future__ import annotations

import threading

import pytest
import zenoh

from tests.links.pairs import Pair, ready_pair
from tests.poll import wait_for
from umbra.connectors.messages import Message, Scalar
from umbra.runtime.graph.plan import GraphPlan
from umbra.runtime.links.config import Endpoints, build_config, free_loopback_ports
from umbra.runtime.links.end_ack import ended_key, ended_proof
from umbra.runtime.links.identity import NO_PROOF
from umbra.runtime.links.transport import ZenohTransport

#: the run's key for the tokens' proofs in the test of forged words (hex, as credentials give it)
TOKEN_KEY = "ab" * 32


def test_a_producer_closes_only_once_its_consumer_says_it_read_the_ends(
    counter_plan: GraphPlan, pair: Pair, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The consumer is slow to say it read the ends (a starved process): the producer's close
    waits for its word, and goes on as soon as it comes."""
    link = counter_plan.links[0]
    got: list[Message] = []
    release = threading.Event()
    said = pair.consumer.end_acks.acknowledge

    def slow(producer: str, session: str) -> None:
        release.wait(30)
        said(producer, session)

    monkeypatch.setattr(pair.consumer.end_acks, "acknowledge", slow)
    send = ready_pair(pair, [link], got)
    for i in range(1, 51):
        send(Scalar(value=float(i), seq=i, stamp=float(i)))
    closing = threading.Thread(target=pair.producer.close)
    closing.start()
    wait_for(
        lambda: pair.producer.end_acks.waiting == {"smart"} and pair.consumer.inputs_ended(),
        10,
        lambda: (
            f"the close to wait (alive {pair.producer.alive_processes()}, heard "
            f"{pair.producer.end_acks.heard()}, closing {closing.is_alive()})"
        ),
    )
    assert closing.is_alive() and pair.producer.end_acks.heard() == set()
    assert [m.seq for m in got] == list(range(1, 51))  # every sample came before the end
    release.set()
    closing.join(10)
    assert not closing.is_alive() and pair.producer.end_acks.heard() == {"smart"}
    assert pair.consumer.stats()["subscribe"][0]["ended"] == 1


def test_a_consumer_that_never_reads_holds_the_close_at_most_the_bound(
    counter_plan: GraphPlan, pair: Pair
) -> None:
    ready_pair(pair, [counter_plan.links[0]], [])
    wait_for(lambda: "smart" in pair.producer.alive_processes(), 10, "the consumer up")
    # nothing ended, so the consumer says nothing: the wait gives up, naming it
    silent = pair.producer.end_acks.wait({"smart"}, pair.producer.alive_processes, 0.2)
    assert silent == {"smart"} and pair.producer.end_acks.waiting == frozenset()


def test_a_consumer_that_is_gone_is_not_waited_for(counter_plan: GraphPlan, pair: Pair) -> None:
    ready_pair(pair, [counter_plan.links[0]], [])
    wait_for(lambda: "smart" in pair.producer.alive_processes(), 10, "the consumer up")
    pair.consumer.close()
    wait_for(lambda: "smart" not in pair.producer.alive_processes(), 10, "the consumer gone")
    assert pair.producer.end_acks.wait({"smart"}, pair.producer.alive_processes, 30) == set()
    assert pair.producer.end_acks.heard() == set()


def test_only_a_word_for_this_session_with_its_proof_counts(counter_plan: GraphPlan) -> None:
    """Words naming another session of the producer, or without the run's proof, count for
    nothing; the true one does."""
    (port,) = free_loopback_ports(1)
    endpoint = f"tcp/127.0.0.1:{port}"
    producer_session = zenoh.open(build_config(Endpoints([endpoint], [])))
    producer = ZenohTransport(producer_session, counter_plan, "umbra", token_key=TOKEN_KEY)
    other = zenoh.open(build_config(Endpoints([], [endpoint])))
    tokens = []
    try:
        me = str(producer_session.zid())
        prefix = counter_plan.key_prefix
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
    counter_plan: GraphPlan, pair: Pair
) -> None:
    """``finish`` skips the streams of mutual peers, but not those of the process whose end
    caused it: they end, and what it sent last comes first (``links.process``)."""
    ready_pair(pair, [counter_plan.links[0]], [])
    wait_for(lambda: "umbra" in pair.consumer.alive_processes(), 10, "the producer up")
    peer = frozenset({"umbra"})
    assert pair.consumer.inputs_ended(besides=peer)
    assert not pair.consumer.inputs_ended(besides=peer, closed=peer)
    pair.producer.close()
    assert pair.consumer.inputs_ended(besides=peer, closed=peer)  # read before the close ended
