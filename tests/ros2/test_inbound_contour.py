"""ROS 2 inputs of a robot: a ``PolygonStamped`` becomes a Contour with the same moment features
vsSnake's contours have, and a ``JointState`` gives the consumer's joints in its order (the
gripper's joint as its opening), which ``umbra check`` holds to the joints the consumer
declares, by the rule of a connection."""

from __future__ import annotations

import numpy as np
import pytest

from umbra.connectors.errors import CheckFailed
from umbra.connectors.tracking import TrackStatus
from umbra.modules.vision.features import polygon_features
from umbra.runtime.graph.check import check_text
from umbra.runtime.ros2.inbound import INBOUND, InOptions
from umbra.runtime.ros2.msgtypes import from_cdr, message_class, to_cdr
from umbra.runtime.ros2.stamps import WallRelation

from .graph_text import graph

REL = WallRelation(run_s=1000.0, offset_ns=1_700_000_000 * 10**9, error_ns=200)


def _header(sec: int = 1_700_000_999, nanosec: int = 250_000_000):
    return message_class("std_msgs/msg/Header")(
        stamp=message_class("builtin_interfaces/msg/Time")(sec=sec, nanosec=nanosec),
        frame_id="camera",
    )


def _polygon(vertices: np.ndarray):
    point = message_class("geometry_msgs/msg/Point32")
    msg = message_class("geometry_msgs/msg/PolygonStamped")(
        header=_header(),
        polygon=message_class("geometry_msgs/msg/Polygon")(
            points=[point(x=float(u), y=float(v), z=0.0) for u, v in vertices]
        ),
    )
    ros_type = "geometry_msgs/msg/PolygonStamped"
    return from_cdr(to_cdr(msg, ros_type), ros_type)  # as it comes off the wire


def test_a_polygon_comes_in_with_the_features_of_the_snakes_contours():
    # a rotated 60 x 24 px rectangle, densely sampled (as the sim camera's outline is)
    t = np.linspace(0.0, 1.0, 16, endpoint=False)
    corners = np.array([[-30.0, -12.0], [30.0, -12.0], [30.0, 12.0], [-30.0, 12.0]])
    edges = [
        a + (b - a) * t[:, None] for a, b in zip(corners, np.roll(corners, -1, 0), strict=True)
    ]
    c, s = np.cos(0.4), np.sin(0.4)
    vertices = np.concatenate(edges) @ np.array([[c, s], [-s, c]]) + [640.0, 360.0]
    got = INBOUND[("geometry_msgs/msg/PolygonStamped", "Contour")](
        _polygon(vertices), REL, InOptions(clock_error_s=0.001)
    )
    want = polygon_features(vertices)
    assert got.status is TrackStatus.TRACKING
    assert np.allclose(got.vertices, vertices, atol=1e-4)  # float32 on the wire
    assert got.area == pytest.approx(want.area_px2, rel=1e-5) and got.area == pytest.approx(1440)
    assert np.allclose(got.centroid, want.centroid_uv, atol=1e-4)
    assert got.orientation == pytest.approx(want.orientation_rad, abs=1e-5)
    assert got.orientation == pytest.approx(0.4, abs=1e-5)
    assert np.allclose(got.axes, [want.major_axis_px, want.minor_axis_px], rtol=1e-5)
    assert got.stamp == pytest.approx(999.25, abs=1e-9)
    assert got.origin == pytest.approx(999.25 - 0.001 - 200e-9, abs=1e-9)


def test_a_degenerate_polygon_is_idle():
    flat = np.array([[0.0, 0.0], [10.0, 0.0], [20.0, 0.0]])
    for vertices in (flat, flat[:2]):
        got = INBOUND[("geometry_msgs/msg/PolygonStamped", "Contour")](
            _polygon(vertices), REL, InOptions()
        )
        assert got.status is TrackStatus.IDLE and got.area == 0.0 and got.centroid.size == 0


def _joint_state(names: list[str], position: list[float]):
    return message_class("sensor_msgs/msg/JointState")(
        header=_header(),
        name=names,
        position=np.array(position),
        velocity=np.zeros(0),
        effort=np.zeros(0),
    )


def test_joint_states_give_the_consumers_joints_in_its_order_and_the_gripper():
    convert = INBOUND[("sensor_msgs/msg/JointState", "JointState")]
    msg = _joint_state(["gripper", "b", "a"], [0.25, 2.0, 1.0])
    got = convert(msg, REL, InOptions(joints=("a", "b"), gripper_joint="gripper"))
    assert got.names == ("a", "b") and got.position.tolist() == [1.0, 2.0]
    assert got.gripper == 0.25
    every = convert(msg, REL, InOptions(gripper_joint="gripper"))  # no joints named: all
    assert every.names == ("b", "a")
    with pytest.raises(ValueError, match=r"expected joints \['a', 'c'\], found"):
        convert(msg, REL, InOptions(joints=("a", "c")))
    with pytest.raises(ValueError, match="expected gripper joint 'hand'"):
        convert(msg, REL, InOptions(gripper_joint="hand"))


def _problems(text: str) -> list[str]:
    with pytest.raises(CheckFailed) as err:
        check_text(text, "g.yaml")
    return str(err.value).splitlines()


def test_check_holds_a_ros2_joint_state_to_the_consumers_joints():
    plan = check_text(graph(), "g.yaml")
    joints = next(p for p in plan.ros2 if p.port == "joint_state").mapping
    assert joints.joints == ("j1", "j2", "j3", "j4", "j5", "j6")  # WOLVERINE_KIN's Puma
    old = "kin.joint_state: {topic: /joint_states, type: sensor_msgs/msg/JointState}"
    wrong = "kin.joint_state: {topic: /joint_states, type: sensor_msgs/msg/JointState,\n"
    wrong += "                      joints: [j1, j2, j3, j4, j6, j5]}"
    text = graph(replace={old: wrong})
    line = next(i for i, s in enumerate(text.splitlines(), 1) if "joints: [j1" in s)
    (problem,) = [p for p in _problems(text) if "joint mismatch" in p]
    assert problem.startswith(f"g.yaml:{line}:")
    assert (
        "joint mismatch: ROS 2 topic /joint_states carries joints "
        "['j1', 'j2', 'j3', 'j4', 'j6', 'j5'], `kin.joint_state` expects "
        "['j1', 'j2', 'j3', 'j4', 'j5', 'j6']"
    ) in problem
    right = wrong.replace("j6, j5", "j5, j6")
    assert check_text(graph(replace={old: right}), "g.yaml")
    numbers = graph(replace={old: wrong.replace("[j1, j2, j3, j4, j6, j5]", "[1, 2]")})
    assert any("`joints` must be a list of joint names" in p for p in _problems(numbers))
    on_image = graph(
        replace={"max_transport_age_s: 0.05}": "max_transport_age_s: 0.05, joints: [j1]}"}
    )
    assert any("`joints` must be a list of joint names" in p for p in _problems(on_image))
