"""``umbra run GRAPH --ros2`` against an independent ROS 2 implementation (zenoh-ros2-sdk) on
the other end of a real zenoh router: the camera's frames reach it, its frames feed the snake, the
contour made from them comes back dated by the frame's own stamp, and the summary counts it."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest

from tests.poll import wait_for
from umbra.runtime.links.config import free_loopback_ports

from .run_graph import start_run, write_graph


def _image_publisher(sdk, port: int):
    """A ROS 2 camera: publishes 64x48 rgb8 frames stamped ``stamp_ns`` (a new one each call)."""
    pub = sdk.ROS2Publisher("/camera/image_raw", "sensor_msgs/msg/Image", router_port=port)
    types = pub.session_mgr.store.types
    sent: list[int] = []

    def send() -> None:
        stamp_ns = time.time_ns() - 20_000_000  # exposed 20 ms ago
        rgb = np.full((48, 64, 3), len(sent) % 250, np.uint8)  # never two frames alike
        header = types["std_msgs/msg/Header"](
            stamp=types["builtin_interfaces/msg/Time"](
                sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9
            ),
            frame_id="ros_camera",
        )
        pub.publish(
            header=header,
            height=48,
            width=64,
            encoding="rgb8",
            is_bigendian=0,
            step=192,
            data=rgb.reshape(-1),
        )
        sent.append(stamp_ns)

    return pub, send, sent


def _finish(proc, timeout_s: float = 30.0) -> str:
    _, err = proc.communicate(timeout=timeout_s)
    assert proc.returncode == 0, err
    assert "Traceback" not in err
    return err


@pytest.mark.slow  # a real run of a few seconds in a child process
@pytest.mark.timeout(120)
def test_a_run_publishes_to_ros2_and_takes_from_it(router_port, sdk, tmp_path):
    frames, contours = [], []
    sub_img = sdk.ROS2Subscriber(
        "/wrist_camera/image_raw", "sensor_msgs/msg/Image", frames.append, router_port=router_port
    )
    sub_contour = sdk.ROS2Subscriber(
        "/snake/contour",
        "geometry_msgs/msg/PolygonStamped",
        contours.append,
        router_port=router_port,
    )
    proc = start_run(
        write_graph(tmp_path),
        tmp_path / "out",
        "--ros2",
        "--ros2-router",
        f"tcp/127.0.0.1:{router_port}",
        "--duration",
        "6",
    )
    pub, send, sent = _image_publisher(sdk, router_port)
    try:
        wait_for(
            lambda: len(frames) >= 3 and len(contours) >= 3,
            40.0,
            "3 frames and 3 contours",
            interval_s=0.02,
            step=send,
        )
        err = _finish(proc)
    finally:
        if proc.poll() is None:
            proc.kill()
        for closing in (pub, sub_img, sub_contour):
            closing.close()
    frame = frames[-1]
    assert (frame.width, frame.height, frame.encoding, frame.step) == (640, 480, "bgr8", 1920)
    assert len(frame.data) == 640 * 480 * 3
    assert frame.header.stamp.sec > 0  # dated by its capture (origin), on the wall clock
    # each contour is dated by the ROS 2 frame it was made from: its own stamp, come back
    stamps = {c.header.stamp.sec * 10**9 + c.header.stamp.nanosec for c in contours}
    assert any(min(abs(s - t) for t in sent) < 2_000_000 for s in stamps), (stamps, sent[:5])
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())["ros2"]
    assert summary["domain"] == 0 and summary["node"] == "umbra"
    topics = summary["topics"]
    assert topics["/wrist_camera/image_raw"]["sent"] >= len(frames)
    assert topics["/snake/contour"]["ports"] == ["snake.contour"]
    cam = topics["/camera/image_raw"]
    assert cam["received"] >= 3 and cam["refused"] == 0
    ages = cam["origin_age_s"]
    assert 0.020 + 0.001 <= ages["median"] < 1.0  # its 20 ms, the clock bound, the transport
    assert "in  /camera/image_raw (sensor_msgs/msg/Image) snake.image: received" in err
    assert "origin age median" in err


@pytest.mark.slow
@pytest.mark.timeout(120)
def test_a_run_starts_a_router_when_none_answers(tmp_path):
    port = free_loopback_ports(1)[0]
    proc = start_run(
        write_graph(tmp_path),
        tmp_path / "out",
        "--ros2-router",
        f"tcp/127.0.0.1:{port}",
        "--ros2-domain",
        "3",
        "--duration",
        "2",
    )
    err = _finish(proc)
    assert f"no router answered at tcp/127.0.0.1:{port}; started one in this process" in err
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())["ros2"]
    assert summary["domain"] == 3
    assert summary["topics"]["/wrist_camera/image_raw"]["sent"] >= 10  # 10 Hz for 2 s


@pytest.mark.slow
@pytest.mark.timeout(150)
def test_a_split_run_has_a_node_per_process_and_keeps_its_links_off_the_router(
    router_port, sdk, tmp_path
):
    import zenoh

    from umbra.runtime.ros2.router import session_config

    keys: set[str] = set()
    watcher = zenoh.open(session_config(f"tcp/127.0.0.1:{router_port}"))
    spy = watcher.declare_subscriber("**", lambda s: keys.add(str(s.key_expr)))
    contours = []
    sub = sdk.ROS2Subscriber(
        "/snake/contour",
        "geometry_msgs/msg/PolygonStamped",
        contours.append,
        router_port=router_port,
    )
    proc = start_run(
        write_graph(tmp_path, split=True),
        tmp_path / "out",
        "--ros2",
        "--ros2-router",
        f"tcp/127.0.0.1:{router_port}",
        "--duration",
        "8",
    )
    pub, send, _sent = _image_publisher(sdk, router_port)
    try:
        wait_for(lambda: len(contours) >= 3, 60.0, "3 contours", interval_s=0.02, step=send)
        topics = dict(sdk.get_topic_names_and_types(router_port=router_port, timeout=1.0))
        info = sdk.get_topic_info(
            "/wrist_camera/image_raw", router_port=router_port, timeout=1.0, verbose=True
        )
        _finish(proc, 60.0)
    finally:
        if proc.poll() is None:
            proc.kill()
        for closing in (pub, sub, spy):
            closing.close() if hasattr(closing, "close") else closing.undeclare()
        watcher.close()
    assert topics["/snake/contour"] == ["geometry_msgs/msg/PolygonStamped"]
    assert [p.node_name for p in info.publishers] == ["umbra_vision"]
    track = json.loads((tmp_path / "out" / "summary-track.json").read_text())["ros2"]
    assert track["node"] == "umbra_track" and track["topics"]["/camera/image_raw"]["received"] >= 3
    assert keys and not [k for k in keys if k.startswith("umbra/")], sorted(keys)[:10]
