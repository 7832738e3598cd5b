"""Live samples of every message type, put by the link publisher on real zenoh sessions, read by
a plain zenoh subscriber with the decoder written from the spec (``spec_decoder``)."""

from __future__ import annotations

import threading
from types import SimpleNamespace

import numpy as np
import zenoh

from tests.matching import wait_subscriptions_reached
from tests.poll import wait_for
from tests.wire import spec_decoder
from tests.wire.samples import every_type, example, same
from umbra.connectors.messages import Image
from umbra.runtime.graph.plan import LinkPlan
from umbra.runtime.links.config import Endpoints, build_config, free_loopback_ports
from umbra.runtime.links.transport import ZenohTransport
from umbra.runtime.links.wire_spec import DOC

PREFIX = "wiretest"


def _plan(types: dict[str, type]) -> SimpleNamespace:
    """A graph plan of one link per type, from process `producer` to process `consumer`."""
    modules, links = {}, []
    for name, cls in types.items():
        modules[f"src{name}"] = SimpleNamespace(process="producer", params={})
        modules[f"dst{name}"] = SimpleNamespace(process="consumer", params={})
        connection = SimpleNamespace(
            src=SimpleNamespace(module=f"src{name}", port="out"),
            dst=SimpleNamespace(module=f"dst{name}", port="in"),
        )
        key = f"{PREFIX}/src{name}/out"
        links.append(LinkPlan(connection, key, cls, reliable=cls is not Image))  # type: ignore[arg-type]
    return SimpleNamespace(key_prefix=PREFIX, links=links, modules=modules)


def _session(listen: list[str], connect: list[str]) -> zenoh.Session:
    return zenoh.open(build_config(Endpoints(listen, connect)))


def test_a_plain_zenoh_subscriber_decodes_every_type_from_the_spec() -> None:
    types = every_type()
    plan = _plan(types)
    (port,) = free_loopback_ports(1)
    producer = ZenohTransport(_session([f"tcp/127.0.0.1:{port}"], []), plan, "producer")
    foreign = _session([], [f"tcp/127.0.0.1:{port}"])  # a zenoh client nobody here wrote
    got: list[tuple[str, str, bytes, str]] = []
    lock = threading.Lock()

    def on_sample(sample: zenoh.Sample) -> None:
        with lock:
            got.append(
                (
                    str(sample.key_expr),
                    str(sample.encoding),
                    sample.payload.to_bytes(),
                    str(sample.kind),
                )
            )

    sub = foreign.declare_subscriber(f"{PREFIX}/**", on_sample)
    try:
        sinks = {link.msg_type.__name__: producer.publisher(link) for link in plan.links}
        producer.announce()
        for link in plan.links:  # the subscription has reached the producer
            pub = producer._pubs[link.key][0]
            wait_for(lambda pub=pub: pub.matching_status.matching, 10.0, "the publisher to match")
        sent = {name: example(cls) for name, cls in types.items()}
        for name, msg in sent.items():
            sinks[name](msg, 0.0)
        wait_for(lambda: len(got) >= len(types), 10.0, "one sample of each type")
        producer.close()  # the end of every stream: a DELETE per key
        wait_for(lambda: len(got) >= 2 * len(types), 10.0, "two samples of each type")
    finally:
        sub.undeclare()
        foreign.close()
        producer.close()
    layouts = spec_decoder.layouts(DOC.read_text())
    puts = [g for g in got if g[3] == "SampleKind.PUT"]
    deletes = {g[0] for g in got if g[3] == "SampleKind.DELETE"}
    assert len(puts) == len(types) and deletes == {link.key for link in plan.links}
    versions = {}
    for key, encoding, payload, _kind in puts:
        media, params = spec_decoder.encoding_fields(encoding)
        name, version, fields = spec_decoder.decode(payload, layouts)
        assert key == f"{PREFIX}/src{name}/out"
        assert (media, params) == ("application/x-umbra", {"v": str(version), "type": name})
        assert same(fields, sent[name]) == [], name
        versions[name] = version
    assert versions["Image"] == versions["StereoSnapshot"] == 2
    assert versions["Twist"] == versions["SceneObjects"] == 3
    assert set(versions) == set(types)


FRAMES = np.random.default_rng(3).integers(0, 256, (8, 480, 640, 3), dtype=np.uint8)


def test_a_foreign_subscriber_gets_image_bytes_never_a_pool_descriptor() -> None:
    plan = _plan({"Image": Image})
    (link,) = plan.links
    port_a, port_b = free_loopback_ports(2)
    producer = ZenohTransport(_session([f"tcp/127.0.0.1:{port_a}"], []), plan, "producer")
    consumer = ZenohTransport(
        _session([f"tcp/127.0.0.1:{port_b}"], [f"tcp/127.0.0.1:{port_a}"]), plan, "consumer"
    )
    received: list[Image] = []
    foreign_got: list[tuple[str, bytes]] = []
    foreign = None
    try:
        send = producer.publisher(link)
        consumer.subscribe(link, received.append)
        producer.announce()
        consumer.announce()
        assert producer.wait_ready(threading.Event(), timeout=10)
        # it proved it shares /dev/shm
        wait_for(lambda: "consumer" in producer._peer_pid, 10.0, "the consumer's pid")

        def stats() -> dict:
            return producer.stats()["publish"][0]

        send(Image(pixels=FRAMES[0], seq=1), 0.0)  # only the graph's processes: the pool
        wait_for(lambda: len(received) == 1, 10.0, "the first sample")
        assert stats()["pool_samples"] == 1
        foreign = _session([], [f"tcp/127.0.0.1:{port_a}"])
        sub = foreign.declare_subscriber(
            link.key,
            lambda s: foreign_got.append((str(s.encoding), s.payload.to_bytes())),
        )
        wait_for(
            lambda: len(list(producer._session.info.transports())) == 2, 10.0, "two transports"
        )
        wait_subscriptions_reached(
            foreign, producer._session, 10.0, "the foreign subscription at the producer"
        )
        for i in range(2, 6):
            send(Image(pixels=FRAMES[i], seq=i), 0.0)
            wait_for(lambda i=i: len(received) == i, 10.0, f"{i} samples")
        wait_for(lambda: len(foreign_got) == 4, 10.0, "4 foreign samples")
        assert stats()["pool_samples"] == 1 and stats()["pool_declined"] == 4
        layouts = spec_decoder.layouts(DOC.read_text())
        for (encoding, payload), i in zip(foreign_got, range(2, 6), strict=True):
            assert encoding == "application/x-umbra;v=2;type=Image"
            name, version, fields = spec_decoder.decode(payload, layouts)
            assert (name, version, fields["seq"]) == ("Image", 2, i)
            np.testing.assert_array_equal(fields["pixels"], FRAMES[i])
        for msg, i in zip(received[1:], range(2, 6), strict=True):
            np.testing.assert_array_equal(msg.pixels, FRAMES[i])  # the consumer still gets all
        sub.undeclare()
        foreign.close()
        foreign = None  # gone: the pool again
        wait_for(
            lambda: len(list(producer._session.info.transports())) == 1, 10.0, "one transport left"
        )
        send(Image(pixels=FRAMES[7], seq=7), 0.0)
        wait_for(lambda: len(received) == 6, 10.0, "6 samples")
        assert stats()["pool_samples"] == 2
    finally:
        if foreign is not None:
            foreign.close()
        consumer.close()
        producer.close()
