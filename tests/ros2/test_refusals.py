"""What a stranger on the router can and cannot make our ROS 2 inputs take: samples without
rmw_zenoh's attachment, payloads that are not the type's CDR, sequence numbers that do not
advance, are counted and refused with the reason; only the mapped key is heard."""

from __future__ import annotations

import itertools
import time

import numpy as np
import zenoh

from tests.poll import wait_for
from umbra.runtime.ros2.attachment import Attachment
from umbra.runtime.ros2.bridge import Ros2Bridge
from umbra.runtime.ros2.keys import data_key
from umbra.runtime.ros2.mapping import Ros2Mapping
from umbra.runtime.ros2.msgtypes import message_class, to_cdr, type_hash
from umbra.runtime.ros2.router import session_config

JS = "sensor_msgs/msg/JointState"


def _joint_state_cdr(position: float) -> bytes:
    now = time.time_ns()
    header = message_class("std_msgs/msg/Header")(
        stamp=message_class("builtin_interfaces/msg/Time")(sec=now // 10**9, nanosec=now % 10**9),
        frame_id="",
    )
    msg = message_class(JS)(
        header=header,
        name=["j1"],
        position=np.array([position]),
        velocity=np.zeros(0),
        effort=np.zeros(0),
    )
    return to_cdr(msg, JS)


def test_strangers_samples_are_refused_with_reasons(router_port):
    mapping = Ros2Mapping("/joint_states", JS, "JointState", "in")
    stranger = zenoh.open(session_config(f"tcp/127.0.0.1:{router_port}"))
    got = []
    with Ros2Bridge(
        session_config(f"tcp/127.0.0.1:{router_port}"), 0, "umbra", [mapping]
    ) as bridge:
        bridge.subscribe("/joint_states", got.append)
        key = data_key(0, "/joint_states", JS, type_hash(JS))
        gid = bytes(range(16))
        stats = bridge.stats["/joint_states"]

        def refused_with(why: str, payload: bytes, attachment: bytes | None) -> None:
            before = stats.refused
            wait_for(
                lambda: stats.refused > before,
                10.0,
                f"the refusal {why!r}",
                interval_s=0.02,
                step=lambda: stranger.put(key, payload, attachment=attachment),
            )
            assert why in stats.last_refusal

        refused_with("found none", _joint_state_cdr(1.0), None)
        refused_with("33-byte", _joint_state_cdr(1.0), bytes(20))
        refused_with("not a CDR", b"\x00\x01\x00\x00garbage", Attachment(1, 0, gid).encode())
        wait_for(
            lambda: got,
            10.0,
            "the sample",
            interval_s=0.02,
            step=lambda: stranger.put(
                key, _joint_state_cdr(2.0), attachment=Attachment(5, 0, gid).encode()
            ),
        )
        assert got[-1].position.tolist() == [2.0]
        refused_with(
            "sequence number 5 after 5", _joint_state_cdr(3.0), Attachment(5, 0, gid).encode()
        )
        # another type on the same topic name travels on another key: never heard
        other = data_key(
            0, "/joint_states", "sensor_msgs/msg/Image", type_hash("sensor_msgs/msg/Image")
        )
        refused = stats.refused
        stranger.put(other, b"\x00\x01\x00\x00", attachment=Attachment(9, 0, gid).encode())
        seqs = itertools.count(6)
        n = len(got)
        wait_for(
            lambda: len(got) > n,
            10.0,
            "one more sample",
            interval_s=0.02,
            step=lambda: stranger.put(
                key, _joint_state_cdr(4.0), attachment=Attachment(next(seqs), 0, gid).encode()
            ),
        )
        assert stats.refused == refused  # what came after it was taken; it was never heard
        assert all(s.position.tolist() != [3.0] for s in got)
    stranger.close()
