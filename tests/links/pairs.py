"""Two zenoh transports of one graph in this process (real zenoh on loopback): the producer
``umbra`` and the consumer ``smart``, for the link tests (the fixtures ``counter_plan`` and
``pair`` in ``conftest.py``)."""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass

import zenoh

from tests.poll import wait_for
from umbra.connectors.messages import Message
from umbra.runtime.graph.plan import GraphPlan, LinkPlan
from umbra.runtime.links.config import Endpoints, build_config, free_loopback_ports
from umbra.runtime.links.transport import ZenohTransport


@dataclass
class Pair:
    """The two transports and the endpoints their sessions listen on."""

    producer: ZenohTransport
    consumer: ZenohTransport
    consumer_endpoint: str
    producer_endpoint: str = ""


def open_pair(plan: GraphPlan, frame_pool: bool = True) -> Pair:
    """Processes ``umbra`` (producer) and ``smart`` (consumer) of ``plan``, connected."""
    port_a, port_b = free_loopback_ports(2)
    a = zenoh.open(build_config(Endpoints(listen=[f"tcp/127.0.0.1:{port_a}"])))
    b = zenoh.open(
        build_config(Endpoints([f"tcp/127.0.0.1:{port_b}"], [f"tcp/127.0.0.1:{port_a}"]))
    )
    # peers do not route for each other: a foreign publisher must connect to the consumer
    return Pair(
        ZenohTransport(a, plan, "umbra", frame_pool=frame_pool),
        ZenohTransport(b, plan, "smart", frame_pool=frame_pool),
        f"tcp/127.0.0.1:{port_b}",
        f"tcp/127.0.0.1:{port_a}",
    )


def ready_pair(pair: Pair, links: list[LinkPlan], got: list[Message]) -> Callable[[Message], None]:
    """Publish ``links`` on the producer, collect them in ``got`` on the consumer, both tokens
    up and seen by the other side, and the producer ready; the sink that sends a sample on every
    link. (A sample that comes before the consumer has seen its producer's token waits for it at
    most ``trust.MAX_HOLD_S``: on a starved machine the first samples would be dropped.)"""
    sinks = [pair.producer.publisher(link) for link in links]
    for link in links:
        pair.consumer.subscribe(link, got.append)
    pair.producer.announce()
    pair.consumer.announce()
    assert pair.producer.wait_ready(threading.Event(), timeout=10)
    wait_for(
        lambda: pair.producer.process in pair.consumer.alive_processes(),
        10,
        "the consumer to see the producer's token",
    )

    def send(msg: Message) -> None:
        for sink in sinks:
            sink(msg, 0.0)

    return send
