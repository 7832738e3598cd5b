"""The split pick-up (``graphs/tool_pickup_ros2.yaml``: ``tool_pickup.yaml`` and a ``ros2:``
section) with ``--ros2`` still grasps, and zenoh-ros2-sdk, at the other end of a real router,
receives its joint states and its wrist camera's images."""

from __future__ import annotations

import json
import threading

import numpy as np
import pytest

from tests.poll import wait_for

from .robot_process import ROOT
from .run_graph import start_run

GRAPH = ROOT / "graphs" / "tool_pickup_ros2.yaml"


class _Last:
    """The newest message of a topic and how many came (a subscriber's callback)."""

    def __init__(self) -> None:
        self.count, self.msg, self._lock = 0, None, threading.Lock()

    def __call__(self, msg: object) -> None:
        with self._lock:
            self.count, self.msg = self.count + 1, msg


class _Static:
    """Every transform seen on /tf_static, by (parent, child)."""

    def __init__(self) -> None:
        self.frames: dict[tuple[str, str], object] = {}

    def __call__(self, msg: object) -> None:
        for t in msg.transforms:  # type: ignore[attr-defined]
            self.frames[(t.header.frame_id, t.child_frame_id)] = t


@pytest.mark.slow  # a real split pick-up: ~20 s of motion, more under load
@pytest.mark.timeout(300)
def test_the_split_pickup_grasps_with_ros2_and_ros2_sees_it(router_port, sdk, tmp_path):
    joints, images, infos, statics = _Last(), _Last(), _Last(), _Static()
    subs = [
        sdk.ROS2Subscriber(
            "/joint_states", "sensor_msgs/msg/JointState", joints, router_port=router_port
        ),
        sdk.ROS2Subscriber(
            "/wrist_camera/image_raw", "sensor_msgs/msg/Image", images, router_port=router_port
        ),
        sdk.ROS2Subscriber(
            "/tf_static", "tf2_msgs/msg/TFMessage", statics, router_port=router_port
        ),
        sdk.ROS2Subscriber(
            "/wrist_camera/camera_info",
            "sensor_msgs/msg/CameraInfo",
            infos,
            router_port=router_port,
        ),
    ]
    run = start_run(
        GRAPH, tmp_path / "out", "--ros2", "--ros2-router", f"tcp/127.0.0.1:{router_port}"
    )
    try:
        wait_for(
            lambda: (
                joints.count >= 50
                and images.count >= 10
                and infos.count >= 10
                and ("tool", "camera") in statics.frames
            ),
            120.0,
            "joints, images, camera infos and the static frame",
        )
        _, err = run.communicate(timeout=200)
    finally:
        if run.poll() is None:
            run.kill()
        for sub in subs:
            sub.close()
    assert run.returncode == 0, err[-3000:]  # World: exit 0 when grasped within tolerance
    smart = json.loads((tmp_path / "out" / "summary-smart.json").read_text())
    world = next(m for m in smart["modules"] if m["module"] == "world")
    assert world["grasped"] and world["position_error_mm"] <= 2.0, world["verdict"]
    js = joints.msg
    assert list(js.name) == ["j1", "j2", "j3", "j4", "j5", "j6", "gripper"]
    assert len(js.position) == 7 and 0.0 <= js.position[6] <= 1.0
    assert js.header.stamp.sec > 0  # dated by its origin, on the wall clock
    img = images.msg
    assert (img.width, img.height, img.encoding, img.step) == (1280, 720, "bgr8", 3840)
    assert len(img.data) == 1280 * 720 * 3 and np.asarray(img.data).std() > 5  # a real picture
    info = infos.msg  # the intrinsics the frames were rendered with (the graph's `values:`)
    assert (info.width, info.height, info.distortion_model) == (1280, 720, "plumb_bob")
    assert list(info.k) == [800.0, 0.0, 640.0, 0.0, 800.0, 360.0, 0.0, 0.0, 1.0]
    assert info.header.frame_id == "camera" and info.header.stamp.sec > 0
    # the graph's static frames on /tf_static: the camera in the tool, 12 cm behind its point
    camera = statics.frames[("tool", "camera")].transform
    assert (camera.translation.x, camera.translation.y) == (0.0, 0.0)
    assert camera.translation.z == pytest.approx(-0.12) and camera.rotation.w == pytest.approx(1)
    assert ("flange", "tool") in statics.frames and ("base", "table") in statics.frames
    sent = smart["ros2"]["topics"]["/joint_states"]["sent"]
    assert sent >= joints.count
