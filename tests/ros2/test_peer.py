"""Our ROS 2 node against an independent implementation (zenoh-ros2-sdk) on the other end of a
real zenoh router session: it decodes what we publish, lists our publishers, and publishes what we
decode."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
import zenoh

from tests.poll import wait_for
from umbra.connectors.messages import Image, JointState
from umbra.runtime.ros2.bridge import Ros2Bridge
from umbra.runtime.ros2.discovery import query_graph
from umbra.runtime.ros2.mapping import Ros2Mapping
from umbra.runtime.ros2.qos import SENSOR_DATA
from umbra.runtime.ros2.router import session_config
from umbra.runtime.ros2.stamps import relate

NAMES = ("shoulder", "elbow", "wrist")


def _bridge(port: int, *mappings: Ros2Mapping, domain: int = 0) -> Ros2Bridge:
    """Our ROS 2 node, a zenoh client of the router on ``port``."""
    return Ros2Bridge(session_config(f"tcp/127.0.0.1:{port}"), domain, "umbra", list(mappings))


def test_the_peer_decodes_our_joint_states_and_lists_our_publisher(router_port, sdk):
    got = []
    sub = sdk.ROS2Subscriber(
        "/joint_states",
        "sensor_msgs/msg/JointState",
        got.append,
        router_port=router_port,
        domain_id=0,
    )
    js = Ros2Mapping("/joint_states", "sensor_msgs/msg/JointState", "JointState", "out")
    with _bridge(router_port, js) as bridge:
        origin = time.monotonic() - 0.040  # data captured 40 ms ago
        sample = JointState(
            names=NAMES,
            position=np.array([0.1, -0.5, 1.25]),
            velocity=np.array([0.0, 0.2, -0.3]),
            origin=origin,
        )
        wait_for(
            lambda: got,
            10.0,
            "the joint state",
            interval_s=0.02,
            step=lambda: bridge.publish("/joint_states", sample),
        )
        msg = got[0]
        assert list(msg.name) == list(NAMES)
        np.testing.assert_array_equal(msg.position, [0.1, -0.5, 1.25])
        np.testing.assert_array_equal(msg.velocity, [0.0, 0.2, -0.3])
        stamp_wall = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        rel = relate()
        assert stamp_wall == pytest.approx(origin + rel.offset_ns * 1e-9, abs=1e-3)
        topics = dict(
            sdk.get_topic_names_and_types(domain_id=0, router_port=router_port, timeout=1.0)
        )
        assert topics["/joint_states"] == ["sensor_msgs/msg/JointState"]
        info = sdk.get_topic_info(
            "/joint_states", domain_id=0, router_port=router_port, timeout=1.0, verbose=True
        )
        assert info.publisher_count == 1
        (pub,) = info.publishers
        assert (pub.node_name, pub.node_namespace, pub.qos) == ("umbra", "/", "::,10:,:,:,,")
        assert pub.type_hash == sub.type_hash  # the hash it computed from the .msg files
        ours = {t.name: t for t in query_graph(bridge.session, 0).topics()}
        assert ours["/joint_states"].publishers == ("/umbra",)
        assert len(ours["/joint_states"].subscribers) == 1
        assert bridge.stats["/joint_states"].sent >= 1
    sub.close()


def test_another_domain_sees_nothing(router_port, sdk):
    js = Ros2Mapping("/joint_states", "sensor_msgs/msg/JointState", "JointState", "out")
    with _bridge(router_port, js, domain=7) as bridge:
        wait_for(
            lambda: query_graph(bridge.session, 7).nodes() == ["/umbra"],
            10.0,
            "the graph to show /umbra",
        )
        topics = dict(
            sdk.get_topic_names_and_types(domain_id=0, router_port=router_port, timeout=0.5)
        )
        assert "/joint_states" not in topics
        assert "/joint_states" in dict(
            sdk.get_topic_names_and_types(domain_id=7, router_port=router_port, timeout=1.0)
        )


def test_we_decode_the_peers_image(router_port, sdk):
    cam = Ros2Mapping(
        "/wrist_camera/image_raw", "sensor_msgs/msg/Image", "Image", "in", clock_error_s=0.005
    )
    got: list[Image] = []
    with _bridge(router_port, cam) as bridge:
        bridge.subscribe("/wrist_camera/image_raw", got.append)
        pub = sdk.ROS2Publisher(
            "/wrist_camera/image_raw", "sensor_msgs/msg/Image", router_port=router_port, domain_id=0
        )
        types = pub.session_mgr.store.types
        rgb = np.zeros((72, 128, 3), np.uint8)
        rgb[:, :64] = (255, 0, 0)  # left half red
        now_ns = time.time_ns() - 30_000_000  # exposed 30 ms ago
        header = types["std_msgs/msg/Header"](
            stamp=types["builtin_interfaces/msg/Time"](sec=now_ns // 10**9, nanosec=now_ns % 10**9),
            frame_id="wrist_camera",
        )

        def send() -> None:
            pub.publish(
                header=header,
                height=72,
                width=128,
                encoding="rgb8",
                is_bigendian=0,
                step=384,
                data=rgb.reshape(-1),
            )

        wait_for(lambda: got, 10.0, "the image", interval_s=0.02, step=send)
        image = got[0]
        assert image.pixels.shape == (72, 128, 3)
        np.testing.assert_array_equal(image.pixels[0, 0], [0, 0, 255])  # red, in BGR
        np.testing.assert_array_equal(image.pixels[0, 100], [0, 0, 0])
        assert image.frame == "wrist_camera"
        rel = relate()
        age = rel.run_s - image.origin
        assert 0.030 + 0.005 <= age < 0.030 + 0.005 + 2.0  # at least the true age plus the bound
        assert math.isfinite(image.origin)
        ours = {t.name: t for t in query_graph(bridge.session, 0).topics()}
        assert ours["/wrist_camera/image_raw"].subscribers == ("/umbra",)
        pub.close()


def test_a_best_effort_profile_publishes_best_effort(router_port, sdk):
    """A mapping whose QoS is best effort (``sensor_data``) asks zenoh for best effort, as
    rmw_zenoh does; rclcpp's default stays reliable. Both are what the peer reads from our
    tokens, and both still reach it over the router's TCP."""
    got: dict[str, list] = {"/camera/image_raw": [], "/joint_states": []}
    subs = [
        sdk.ROS2Subscriber(topic, ros_type, got[topic].append, router_port=router_port, domain_id=0)
        for topic, ros_type in (
            ("/camera/image_raw", "sensor_msgs/msg/Image"),
            ("/joint_states", "sensor_msgs/msg/JointState"),
        )
    ]
    image = Ros2Mapping(
        "/camera/image_raw", "sensor_msgs/msg/Image", "Image", "out", qos=SENSOR_DATA
    )
    js = Ros2Mapping("/joint_states", "sensor_msgs/msg/JointState", "JointState", "out")
    frame = Image(pixels=np.zeros((4, 6, 3), dtype=np.uint8), origin=time.monotonic())
    state = JointState(names=NAMES, position=np.zeros(3), origin=time.monotonic())
    with _bridge(router_port, image, js) as bridge:
        reliability = {t: out.publisher.reliability for t, out in bridge._outs.items()}
        assert reliability == {
            "/camera/image_raw": zenoh.Reliability.BEST_EFFORT,
            "/joint_states": zenoh.Reliability.RELIABLE,
        }
        wait_for(
            lambda: all(got.values()),
            10.0,
            "both topics at the peer",
            interval_s=0.02,
            step=lambda: (
                bridge.publish("/camera/image_raw", frame),
                bridge.publish("/joint_states", state),
            ),
        )
        qos = {
            topic: sdk.get_topic_info(
                topic, domain_id=0, router_port=router_port, timeout=1.0, verbose=True
            )
            .publishers[0]
            .qos
            for topic in got
        }
        assert qos == {"/camera/image_raw": "2::,5:,:,:,,", "/joint_states": "::,10:,:,:,,"}
    for sub in subs:
        sub.close()
