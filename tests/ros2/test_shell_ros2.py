"""``umbra topics --ros2`` and ``umbra echo /topic --ros2`` against a ROS 2 node of an
independent implementation (zenoh-ros2-sdk) on a real zenoh router."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from tests.poll import wait_for
from umbra.runtime.links.config import free_loopback_ports


def _umbra(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "umbra.runtime.cli.main", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def _publishing_until_done(proc: subprocess.Popen[str], publish, timeout_s: float = 30.0):
    """Publish every 50 ms until ``proc`` ends; its (stdout, stderr)."""
    wait_for(lambda: proc.poll() is not None, timeout_s, "the command to end", 0.05, step=publish)
    return proc.communicate(timeout=10)


@pytest.mark.slow  # two CLI processes
@pytest.mark.timeout(90)
def test_topics_lists_and_echo_decodes_a_ros2_topic(router_port, sdk):
    pub = sdk.ROS2Publisher(
        "/joint_states", "sensor_msgs/msg/JointState", router_port=router_port, node_name="arm"
    )
    router = f"tcp/127.0.0.1:{router_port}"
    types = pub.session_mgr.store.types
    header = types["std_msgs/msg/Header"](
        stamp=types["builtin_interfaces/msg/Time"](sec=1, nanosec=0), frame_id="base"
    )

    def publish() -> None:
        pub.publish(
            header=header,
            name=["shoulder", "elbow"],
            position=np.array([0.25, -1.5]),
            velocity=np.zeros(0),
            effort=np.zeros(0),
        )

    try:
        out, err = _publishing_until_done(
            _umbra("topics", "--ros2-router", router, "--json", "--window", "1"), publish
        )
        assert "Traceback" not in err
        rows = [json.loads(line) for line in out.splitlines()]
        (row,) = [r for r in rows if r.get("ros2_topic") == "/joint_states"]
        assert row["types"] == ["sensor_msgs/msg/JointState"]
        assert row["publishers"] == ["/arm"] and row["domain"] == 0
        out, err = _publishing_until_done(
            _umbra("echo", "/joint_states", "--ros2-router", router, "--once", "--json"), publish
        )
        assert "Traceback" not in err, err
        msg = json.loads(out)
        assert (msg["topic"], msg["type"]) == ("/joint_states", "sensor_msgs/msg/JointState")
        assert msg["name"] == ["shoulder", "elbow"] and msg["position"] == [0.25, -1.5]
        assert msg["seq"] >= 1
    finally:
        pub.close()


def test_the_shell_says_when_no_router_answers():
    port = free_loopback_ports(1)[0]
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "umbra.runtime.cli.main",
            "echo",
            "/joint_states",
            "--ros2-router",
            f"tcp/127.0.0.1:{port}",
            "--once",
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2
    assert f"expected a ROS 2 router at tcp/127.0.0.1:{port}, found none answering" in proc.stderr
    assert "Traceback" not in proc.stderr
