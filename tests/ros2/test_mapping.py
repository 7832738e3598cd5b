"""The mapping declaration refuses what cannot cross, naming the field and the reason."""

from __future__ import annotations

import pytest

from umbra.runtime.ros2.mapping import Direction, MappingError, Ros2Mapping, mapping_problems


def test_a_good_mapping_and_its_command_flag():
    m = Ros2Mapping("/joint_states", "sensor_msgs/msg/JointState", "JointState", "out")
    assert m.direction is Direction.OUT and not m.is_command
    cmd = Ros2Mapping(
        "/servo_node/delta_twist_cmds", "geometry_msgs/msg/TwistStamped", "Twist", "out"
    )
    assert cmd.is_command
    cam = Ros2Mapping(
        "/camera/image_raw/compressed", "sensor_msgs/msg/CompressedImage", "Image", "in"
    )
    assert cam.in_options().clock_error_s == 0.0


@pytest.mark.parametrize(
    "args, field, why",
    [
        (("joint_states", "sensor_msgs/msg/JointState", "JointState", "out"), "topic", "absolute"),
        (("/j", "sensor_msgs/msg/JointStates", "JointState", "out"), "type", "no message type"),
        (("/j", "sensor_msgs/JointState", "JointState", "out"), "type", "like `sensor_msgs/msg"),
        (
            ("/j", "sensor_msgs/msg/Image", "JointState", "out"),
            "type",
            "converts to sensor_msgs/msg/JointState; found sensor_msgs/msg/Image",
        ),
        (("/j", "sensor_msgs/msg/Image", "Twist", "in"), "umbra_type", "conversion from ROS 2"),
        (("/j", "sensor_msgs/msg/JointState", "JointState", "both"), "direction", "`out` or `in`"),
    ],
)
def test_refusals_name_the_field_and_the_reason(args, field, why):
    with pytest.raises(MappingError) as err:
        Ros2Mapping(*args)
    fields = [f for f, _ in err.value.problems]
    assert field in fields
    assert why in dict(err.value.problems)[field]


def test_every_problem_is_reported_at_once():
    problems = mapping_problems("bad name", "nope", "JointState", "in", clock_error_s=float("inf"))
    assert [f for f, _ in problems] == ["topic", "type", "clock_error_s"]
    assert (
        mapping_problems("/x", "sensor_msgs/msg/Image", "Image", "in", distro="humble")[0][0]
        == "distro"
    )
