"""The zenoh transport between two sessions in this process (real zenoh on loopback)."""

from __future__ import annotations

import threading
import time

import numpy as np
import zenoh

from tests.links.pairs import Pair, open_pair, ready_pair
from tests.poll import wait_for
from umbra.connectors import Module, Output
from umbra.connectors.messages import Image, Message, Scalar
from umbra.runtime.graph.check import check_spec
from umbra.runtime.graph.parse import parse_graph_text
from umbra.runtime.graph.plan import GraphPlan, LinkPlan
from umbra.runtime.links.config import Endpoints, build_config, free_loopback_ports
from umbra.runtime.links.transport import ZenohTransport
from umbra.runtime.registry import Registry


class Camera(Module):
    """Test source of images."""

    image = Output(Image, doc="frames")


class Viewer(Module):
    from umbra.connectors import Input

    image = Input(Image, trigger=True, doc="frames")


IMAGE_GRAPH = """
graph: video
processes: {umbra: {}, smart: {}}
modules:
  cam: {type: Camera, process: umbra, rate: 30}
  view: {type: Viewer, process: smart}
connections:
  - cam.image -> view.image
"""


def test_samples_arrive_in_order_once_per_output(counter_plan: GraphPlan, pair: Pair) -> None:
    links = counter_plan.links[:2]  # counter.count -> double.input and -> record.count
    assert links[0].key == links[1].key == "umbra/counter_split/counter/count"
    got: list[Message] = []
    send = ready_pair(pair, links, got)
    for i in range(1, 301):
        send(Scalar(value=i * 0.5, seq=i, stamp=100.0 + i))
    wait_for(lambda: len(got) >= 600, 5.0, "600 samples")
    time.sleep(0.05)  # a window: no sample comes twice
    assert len(got) == 600  # one publication per output, delivered to both inputs
    assert [m.seq for m in got[::2]] == list(range(1, 301))
    assert [m.value for m in got[1::2]] == [i * 0.5 for i in range(1, 301)]
    assert got[-1].stamp == 400.0
    (pub,) = pair.producer.stats()["publish"]
    (sub,) = pair.consumer.stats()["subscribe"]
    assert pub["sent"] == 300 and sub["received"] == 300 and sub["missing"] == 0
    assert pair.consumer.producer_alive(links[0])
    assert pair.consumer.link_age(links[0]) < 5.0


def test_foreign_and_old_samples_are_dropped_and_counted(
    counter_plan: GraphPlan, pair: Pair
) -> None:
    link = counter_plan.links[0]
    got: list[Message] = []
    send = ready_pair(pair, [link], got)
    foreign = zenoh.open(build_config(Endpoints(connect=[pair.consumer_endpoint])))
    try:
        raw = foreign.declare_publisher(link.key, congestion_control=zenoh.CongestionControl.BLOCK)
        wait_for(lambda: raw.matching_status.matching, 5.0, "the raw publisher to match")
        send(Scalar(value=1.0, seq=5))
        raw.put(b"\x00\x01garbage")
        send(Scalar(value=2.0, seq=6))
        send(Scalar(value=3.0, seq=4))  # older than one already delivered
        send(Scalar(value=4.0, seq=9))  # 7 and 8 never came
        wait_for(
            lambda: pair.consumer.stats()["subscribe"][0]["received"] == 3,
            5.0,
            "3 samples received",
        )
        time.sleep(0.05)  # a window: nothing else is delivered
    finally:
        foreign.close()
    assert [m.value for m in got] == [1.0, 2.0, 4.0]
    (sub,) = pair.consumer.stats()["subscribe"]
    assert (sub["foreign"], sub["stale_dropped"], sub["missing"]) == (1, 1, 2)
    assert sub["decode_errors"] == 0  # refused before decoding: not from the producer


def test_clean_end_and_death_of_the_producer(counter_plan: GraphPlan) -> None:
    link = counter_plan.links[0]
    pair = open_pair(counter_plan)
    try:
        ready_pair(pair, [link], [])
        wait_for(lambda: pair.consumer.producer_alive(link), 5.0, "the producer alive")
        assert not pair.consumer.inputs_ended()
        pair.producer.close()  # end of stream, token withdrawn, session closed
        wait_for(lambda: not pair.consumer.producer_alive(link), 5.0, "the producer gone")
        assert pair.consumer.inputs_ended()
        assert pair.consumer.stats()["subscribe"][0]["ended"] == 1
    finally:
        pair.producer.close()
        pair.consumer.close()


def _image_pair(frame_pool: bool) -> tuple[Pair, LinkPlan]:
    registry = Registry()
    registry.add(Camera)
    registry.add(Viewer)
    plan = check_spec(parse_graph_text(IMAGE_GRAPH, "video.yaml"), registry)
    (link,) = plan.links
    assert not link.reliable  # video may drop old frames
    return open_pair(plan, frame_pool), link


FRAMES = np.random.default_rng(1).integers(0, 256, (20, 480, 640, 3), dtype=np.uint8)


def test_images_on_one_host_are_read_in_place_from_the_frame_pool() -> None:
    pair, link = _image_pair(frame_pool=True)
    try:
        got: list[Message] = []
        send = ready_pair(pair, [link], got)
        # same /dev/shm: same host
        wait_for(lambda: "smart" in pair.producer._peer_pid, 5.0, "the producer's pid")
        for i, pixels in enumerate(FRAMES[:3], 1):
            send(Image(pixels=pixels, seq=i))
            wait_for(lambda i=i: len(got) == i, 5.0, f"{i} samples")
        for frame, msg in zip(FRAMES, got, strict=False):
            np.testing.assert_array_equal(msg.pixels, frame)
            assert not msg.pixels.flags.writeable  # a read-only view on the shared slot
        pool = pair.producer._handoff.pools[link.key]
        assert pool.busy == 3  # the consumer still holds the three frames
        (pub,) = pair.producer.stats()["publish"]
        (sub,) = pair.consumer.stats()["subscribe"]
        assert pub["pool_samples"] == sub["pool_samples"] == 3 and pub["shm_samples"] == 0
        del msg
        got.clear()  # the consumer lets go of the frames: their slots are free again
        assert pool.busy == 0
        for i, pixels in enumerate(FRAMES, 4):  # hold 20 frames: more than the pool's 16 slots
            send(Image(pixels=pixels, seq=i))
            wait_for(lambda n=i - 3: len(got) == n, 5.0, f"{i - 3} samples")
        for frame, msg in zip(FRAMES, got, strict=True):
            np.testing.assert_array_equal(msg.pixels, frame)  # none overwritten
        (pub,) = pair.producer.stats()["publish"]
        assert pub["pool_samples"] == 3 + 16 and pub["pool_full"] == 4
        assert pub["shm_samples"] == 4  # the rest took zenoh's shared memory
    finally:
        pair.producer.close()
        pair.consumer.close()


def test_images_without_the_pool_travel_through_zenoh_shared_memory() -> None:
    pair, link = _image_pair(frame_pool=False)
    seen_shm: list[bool] = []
    try:
        spy = pair.consumer._session.declare_subscriber(
            link.key, lambda s: seen_shm.append(s.payload.as_shm() is not None)
        )
        got: list[Message] = []
        send = ready_pair(pair, [link], got)
        for i, pixels in enumerate(FRAMES[:3], 1):
            send(Image(pixels=pixels, seq=i))
            wait_for(lambda i=i: len(got) == i, 5.0, f"{i} samples")
        for frame, msg in zip(FRAMES, got, strict=False):
            np.testing.assert_array_equal(msg.pixels, frame)
            assert not msg.pixels.flags.writeable  # a view on the received bytes
        wait_for(lambda: len(seen_shm) == 3, 5.0, "3 samples over shm")
        assert seen_shm == [True, True, True]
        (pub,) = pair.producer.stats()["publish"]
        assert pub["shm_samples"] == 3 and pub["mode"] == "best-effort/drop"
        spy.undeclare()
    finally:
        pair.producer.close()
        pair.consumer.close()


class Relay(Module):
    """Passes each frame on unchanged (a republisher)."""

    from umbra.connectors import Input

    image_in = Input(Image, trigger=True, doc="frames")
    image_out = Output(Image, doc="the same frames")


RELAY_GRAPH = """
graph: relay
processes: {umbra: {}, smart: {}, ops: {}}
modules:
  cam: {type: Camera, process: umbra, rate: 30}
  relay: {type: Relay, process: smart}
  view: {type: Viewer, process: ops}
connections:
  - cam.image -> relay.image_in
  - relay.image_out -> view.image
"""


def test_a_relayed_frame_is_passed_on_in_place_without_a_copy() -> None:
    """umbra -> smart -> ops on one host: smart re-publishes the frame it received; the frame
    stays in umbra's pool slot, ops reads it there, and the slot is held until ops lets go."""
    registry = Registry()
    for cls in (Camera, Viewer, Relay):
        registry.add(cls)
    plan = check_spec(parse_graph_text(RELAY_GRAPH, "relay.yaml"), registry)
    first, second = sorted(plan.links, key=lambda link: link.key)
    assert first.key.endswith("cam/image") and second.key.endswith("relay/image_out")
    ports = free_loopback_ports(3)
    listen = [f"tcp/127.0.0.1:{p}" for p in ports]
    sessions = [zenoh.open(build_config(Endpoints([listen[i]], listen[:i]))) for i in range(3)]
    cam, relay, view = (
        ZenohTransport(s, plan, name)
        for s, name in zip(sessions, ("umbra", "smart", "ops"), strict=True)
    )
    try:
        relayed: list[Message] = []
        seen: list[Message] = []
        to_relay = cam.publisher(first)
        from_relay = relay.publisher(second)
        relay.subscribe(first, relayed.append)
        view.subscribe(second, seen.append)
        for t in (cam, relay, view):
            t.announce()
        for t in (cam, relay):
            assert t.wait_ready(threading.Event(), timeout=10)
        wait_for(lambda: {"smart", "ops"} <= set(cam._peer_pid), 5.0, "both peers' pids")
        wait_for(lambda: "ops" in relay._peer_pid, 5.0, "the ops pid at the relay")
        for i, pixels in enumerate(FRAMES[:3], 1):
            to_relay(Image(pixels=pixels, seq=i, stamp=float(i)), 0.0)
            wait_for(lambda i=i: len(relayed) == i, 5.0, f"{i} relayed samples")
            got = relayed[-1]
            from_relay(Image(pixels=got.pixels, seq=i, stamp=got.stamp, frame="wrist"), 0.0)
            wait_for(lambda i=i: len(seen) == i, 5.0, f"{i} samples")
        for i, (pixels, msg) in enumerate(zip(FRAMES, seen, strict=False), 1):
            np.testing.assert_array_equal(msg.pixels, pixels)
            assert (msg.seq, msg.stamp, msg.frame) == (i, float(i), "wrist")
        (relay_pub,) = relay.stats()["publish"]
        assert relay_pub["forwarded"] == 3 and relay_pub["bytes"] < 3 * 1000  # no pixels sent
        pool = cam._handoff.pools[first.key]
        del got
        relayed.clear()  # the relay lets go; ops still holds the three frames
        assert pool.busy == 3
        del msg
        seen.clear()
        wait_for(lambda: pool.busy == 0, 5.0, "the pool idle")
    finally:
        for t in (cam, relay, view):
            t.close()
