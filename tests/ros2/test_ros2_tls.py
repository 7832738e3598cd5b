"""A TLS ROS 2 router endpoint with the graph's certificates, end to end: ``umbra keys GRAPH
--ros2 NAME`` makes a certificate per end (the router, our run, a ROS 2 host) from the graph's
CA; a zenoh router listens on ``tls/127.0.0.1:PORT`` and requires a client certificate of that CA
(mutual TLS); ``umbra run GRAPH --ros2-router tls/... --ros2-config ros2@umbra.json5`` publishes
its camera through it. A TLS subscriber of our own (its own certificate; the rmw_zenoh data key,
the CDR decoded by rosbags) and zenoh-ros2-sdk (TLS through its ``ZENOH_CONFIG_OVERRIDE``) receive
the frames; a peer with no certificate and one with a certificate of another CA reach nothing."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from examples.ros2_robot.msg_files import write_msg_files
from tests.poll import wait_for
from umbra.runtime.links.config import free_loopback_ports, read_user_config
from umbra.runtime.ros2.keys import data_key
from umbra.runtime.ros2.msgtypes import from_cdr, type_hash
from umbra.runtime.ros2.router import open_router, session_config

from .run_graph import start_run, write_graph

IMAGE, TOPIC = "sensor_msgs/msg/Image", "/wrist_camera/image_raw"


def _keys(graph: Path, out: Path, *names: str) -> Path:
    """``umbra keys GRAPH --out OUT --ros2 NAME...``; the folder."""
    done = subprocess.run(
        [sys.executable, "-m", "umbra.runtime.cli.main", "keys", str(graph), "--out", str(out),
         *[a for n in names for a in ("--ros2", n)]],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    return out


def _tls_of(config: Path) -> dict[str, object]:
    """The ``transport/link/tls`` settings of ``config``, certificate paths made absolute."""
    return json.loads(read_user_config(str(config)).get_json("transport/link/tls"))


@pytest.fixture
def tls_sdk(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Iterator[tuple[object, object]]:
    """zenoh-ros2-sdk configured for TLS by the environment it reads; a function opening its
    shared session with ``ros2@NAME.json5``'s settings to an endpoint, and the package."""
    sdk = pytest.importorskip("zenoh_ros2_sdk")
    from zenoh_ros2_sdk import message_registry
    from zenoh_ros2_sdk.session import ZenohSession

    write_msg_files(tmp_path / "msgs")
    monkeypatch.setattr(
        message_registry, "_registry", message_registry.MessageRegistry(str(tmp_path / "msgs"))
    )
    monkeypatch.setattr(ZenohSession, "_instance", None)
    monkeypatch.setenv("ZENOH_SESSION_CONFIG_URI", "")
    opened = []

    def open_tls(endpoint: str, config: Path) -> object:
        override = {
            "mode": '"client"',
            "scouting/multicast/enabled": "false",
            "scouting/gossip/enabled": "false",
            "connect/endpoints": json.dumps([endpoint]),  # after its own tcp/IP:PORT
            "transport/link/tls": json.dumps(_tls_of(config)),
        }
        monkeypatch.setenv(
            "ZENOH_CONFIG_OVERRIDE", ";".join(f"{k}={v}" for k, v in override.items())
        )
        opened.append(ZenohSession.get_instance())
        return opened[-1]

    yield open_tls, sdk
    for session in opened:
        session.close()


def test_a_ros2_certificate_name_is_checked(tmp_path):
    done = subprocess.run(
        [sys.executable, "-m", "umbra.runtime.cli.main", "keys", str(write_graph(tmp_path)),
         "--out", str(tmp_path / "keys"), "--ros2", "robot", "--ros2", "a/b"],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert done.returncode == 2, done.stderr
    assert (
        "--ros2: expected a new NAME of letters, digits, '_', '.', '-', found 'a/b'" in done.stderr
    )
    assert "Traceback" not in done.stderr and not (tmp_path / "keys").exists()


@pytest.mark.slow  # a real run of a few seconds through a TLS router
@pytest.mark.timeout(150)
def test_a_run_publishes_through_a_mutual_tls_router_that_refuses_outsiders(tmp_path, tls_sdk):
    import zenoh

    open_sdk, sdk = tls_sdk
    graph = write_graph(tmp_path)
    keys = _keys(graph, tmp_path / "keys", "router", "umbra", "robot")
    other = _keys(graph, tmp_path / "other", "robot")  # another CA, the same names
    (tmp_path / "bare.json5").write_text(
        json.dumps({"transport": {"link": {"tls": {"root_ca_certificate": str(keys / "ca.pem")}}}})
    )
    files = sorted(p.name for p in keys.glob("ros2@*"))
    assert "ros2@umbra.json5" in files and "ros2@umbra.key" in files
    assert (
        json.loads(read_user_config(str(keys / "ros2@umbra.json5")).get_json("access_control"))[
            "enabled"
        ]
        is False
    )  # TLS only: the graph's rules would deny every ROS 2 key

    endpoint = f"tls/127.0.0.1:{free_loopback_ports(1)[0]}"
    router = open_router(endpoint, str(keys / "ros2@router.json5"))
    key = data_key(0, TOPIC, IMAGE, type_hash(IMAGE))
    got: dict[str, list[object]] = {"ours": [], "no certificate": [], "another CA": []}
    sessions = {
        "ours": zenoh.open(session_config(endpoint, config_file=str(keys / "ros2@robot.json5"))),
        # peers: their open does not fail; they simply never get a session with the router
        "no certificate": zenoh.open(
            session_config(endpoint, mode="peer", config_file=str(tmp_path / "bare.json5"))
        ),
        "another CA": zenoh.open(
            session_config(endpoint, mode="peer", config_file=str(other / "ros2@robot.json5"))
        ),
    }
    subs = [
        s.declare_subscriber(key, lambda sample, name=name: got[name].append(sample))
        for name, s in sessions.items()
    ]
    open_sdk(endpoint, keys / "ros2@robot.json5")
    frames: list[object] = []
    sdk_sub = sdk.ROS2Subscriber(TOPIC, IMAGE, frames.append)
    proc = start_run(
        graph, tmp_path / "out", "--ros2-router", endpoint,
        "--ros2-config", str(keys / "ros2@umbra.json5"), "--duration", "4",
    )  # fmt: skip
    try:
        wait_for(lambda: len(got["ours"]) >= 5 and len(frames) >= 5, 60.0, "5 samples and 5 frames")
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
        sdk_sub.close()
        for sub in subs:
            sub.undeclare()
        outsiders = {n: list(sessions[n].info.routers_zid()) for n in sessions}
        for s in sessions.values():
            s.close()
        router.close()
    assert proc.returncode == 0, err
    assert "Traceback" not in err and "no router answered" not in err, err
    # ours: the rmw_zenoh key, the 33-byte attachment, CDR that rosbags decodes
    sample = got["ours"][-1]
    assert len(bytes(sample.attachment)) == 33
    msg = from_cdr(bytes(sample.payload), IMAGE)
    assert (msg.width, msg.height, msg.encoding, len(msg.data)) == (640, 480, "bgr8", 921600)
    assert msg.header.stamp.sec > 0
    frame = frames[-1]  # the independent implementation's decoding
    assert (frame.width, frame.height, frame.encoding) == (640, 480, "bgr8")
    # the outsiders: no session with the router, not one sample
    assert len(outsiders["ours"]) == 1
    assert outsiders["no certificate"] == [] and got["no certificate"] == []
    assert outsiders["another CA"] == [] and got["another CA"] == []
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())["ros2"]
    assert summary["router"] == endpoint
    assert summary["topics"][TOPIC]["sent"] >= len(got["ours"]) >= 5
