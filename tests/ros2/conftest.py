"""A zenoh router on a loopback port standing in for ``rmw_zenohd``, and ``zenoh-ros2-sdk`` (an
independent ROS 2-over-zenoh implementation) connected to it, offline: its message registry reads
``.msg`` files of the ROS 2 interface definitions (``examples/ros2_robot/msg_files.py``; it
computes the RIHS01 hashes from them itself), and its session has multicast and gossip scouting
off."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from examples.ros2_robot.msg_files import write_msg_files
from umbra.runtime.links.config import free_loopback_ports
from umbra.runtime.ros2.router import open_router


@pytest.fixture
def router_port() -> Iterator[int]:
    """The port of a zenoh router listening on 127.0.0.1."""
    port = free_loopback_ports(1)[0]
    router = open_router(f"tcp/127.0.0.1:{port}")
    yield port
    router.close()


@pytest.fixture
def sdk(router_port: int, tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    """The zenoh-ros2-sdk package, its shared session connected to the router."""
    sdk = pytest.importorskip("zenoh_ros2_sdk")
    from zenoh_ros2_sdk import message_registry
    from zenoh_ros2_sdk.session import ZenohSession

    write_msg_files(tmp_path / "msgs")
    monkeypatch.setenv("ZENOH_SESSION_CONFIG_URI", "")
    monkeypatch.setenv(
        "ZENOH_CONFIG_OVERRIDE",
        'scouting/multicast/enabled=false;scouting/gossip/enabled=false;listen/endpoints=["tcp/127.0.0.1:0"]',
    )
    monkeypatch.setattr(ZenohSession, "_instance", None)
    session = ZenohSession.get_instance("127.0.0.1", router_port)
    monkeypatch.setattr(
        message_registry, "_registry", message_registry.MessageRegistry(str(tmp_path / "msgs"))
    )
    yield sdk
    session.close()
