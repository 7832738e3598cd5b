"""``zenoh-ros2-sdk`` set up offline: its shared session a zenoh **client** of the ROS 2 router
(multicast and gossip scouting off, as every zenoh configuration of the project), its message
registry reading the ``.msg`` files of :mod:`.msg_files`.

A client, not rmw_zenoh's default peer: without gossip, a router routes between a client and
anyone, but not between two peers it takes to be meshed, so two sdk peers (the robot and a
test's subscriber) would see each other's tokens and none of each other's data."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from examples.ros2_robot.msg_files import write_msg_files

#: ``ZENOH_CONFIG_OVERRIDE`` of the sdk's session.
OVERRIDE = 'mode="client";scouting/multicast/enabled=false;scouting/gossip/enabled=false'


def router_address(endpoint: str) -> tuple[str, int]:
    """``(host, port)`` of a ``tcp/HOST:PORT`` endpoint (the sdk connects over TCP only);
    ValueError otherwise."""
    protocol, _, rest = endpoint.partition("/")
    host, _, port = rest.rpartition(":")
    if protocol != "tcp" or not host or not port.isdigit():
        raise ValueError(f"expected a router endpoint tcp/HOST:PORT, found {endpoint!r}")
    return host.strip("[]"), int(port)


def open_sdk(endpoint: str, msgs: Path) -> tuple[Any, int]:
    """The sdk module with its session connected to the router at ``endpoint`` and its registry
    on ``.msg`` files written into ``msgs``; the router's port (the sdk's entities take it)."""
    import zenoh_ros2_sdk
    from zenoh_ros2_sdk import message_registry
    from zenoh_ros2_sdk.session import ZenohSession

    host, port = router_address(endpoint)
    write_msg_files(msgs)
    os.environ["ZENOH_SESSION_CONFIG_URI"] = ""
    os.environ["ZENOH_CONFIG_OVERRIDE"] = OVERRIDE
    ZenohSession._instance = None
    ZenohSession.get_instance(host, port)
    message_registry._registry = message_registry.MessageRegistry(str(msgs))
    return zenoh_ros2_sdk, port
