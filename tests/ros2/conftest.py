"""A zenoh router on a loopback port standing in for ``rmw_zenohd``, and ``zenoh-ros2-sdk`` (an
independent ROS 2-over-zenoh implementation) connected to it, offline: its message registry reads
``.msg`` files written here from the ROS 2 interface definitions (it computes the RIHS01 hashes
from them itself), and its session has multicast and gossip scouting off."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from umbra.runtime.links.config import free_loopback_ports
from umbra.runtime.ros2.router import open_router

#: The ROS 2 interface definitions the peer needs (comments and constants left out: they do not
#: enter a type hash).
MSG_FILES = {
    "builtin_interfaces/msg/Time": "int32 sec\nuint32 nanosec\n",
    "std_msgs/msg/Header": "builtin_interfaces/Time stamp\nstring frame_id\n",
    "sensor_msgs/msg/JointState": (
        "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\n"
        "float64[] effort\n"
    ),
    "sensor_msgs/msg/Image": (
        "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\n"
        "uint8 is_bigendian\nuint32 step\nuint8[] data\n"
    ),
}


def wait_for(
    condition: Callable[[], object], timeout_s: float = 10.0, step: Callable[[], None] | None = None
) -> object:
    """Wait until ``condition()`` is truthy (calling ``step`` between looks); its value, or
    AssertionError after ``timeout_s`` [s]."""
    deadline = time.monotonic() + timeout_s
    while True:
        value = condition()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"condition not met within {timeout_s} s")
        if step is not None:
            step()
        time.sleep(0.02)


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

    for name, text in MSG_FILES.items():
        path = tmp_path / "msgs" / f"{name}.msg"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
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
