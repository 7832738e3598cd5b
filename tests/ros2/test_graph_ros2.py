"""The graph's ``ros2:`` section: read with FILE:LINE diagnostics, checked against the modules
(ports, conversions, producers, the guard rule for command outputs), and origin ages through
ROS 2 inputs."""

from __future__ import annotations

import subprocess
import sys

import pytest

from umbra.connectors import Input, Module
from umbra.connectors.errors import CheckFailed
from umbra.connectors.messages import Image
from umbra.runtime.graph.check import check_text
from umbra.runtime.graph.check_ros2 import Ros2Check
from umbra.runtime.graph.origin_age import bounded_inputs
from umbra.runtime.registry import Registry

from .graph_text import graph


def _problems(text: str) -> list[str]:
    with pytest.raises(CheckFailed) as err:
        check_text(text, "g.yaml")
    return str(err.value).splitlines()


def _line_of(text: str, needle: str) -> int:
    return next(i for i, line in enumerate(text.splitlines(), 1) if needle in line)


def test_mapped_ports_have_owners_and_ros2_inputs_count_as_wired():
    plan = check_text(graph(), "g.yaml")
    got = {(str(p), p.mapping.topic, p.mapping.direction.value, p.process) for p in plan.ros2}
    assert got == {
        ("kin.joint_rates", "/forward_velocity_controller/commands", "out", "main"),
        ("snake.contour", "/snake/contour", "out", "main"),
        ("snake.image", "/wrist_camera/image_raw", "in", "main"),
        ("kin.joint_state", "/joint_states", "in", "main"),
    }
    rates = next(p for p in plan.ros2 if p.port == "joint_rates")
    assert rates.mapping.is_command
    # snake.image is required and fed by nothing but ROS 2: without the mapping it is unwired
    text = graph(
        replace={
            "    snake.image:\n      {topic: /wrist_camera/image_raw, type: sensor_msgs/msg/Image, "
            "max_transport_age_s: 0.05}\n": ""
        }
    )
    assert any(
        "required input `snake.image` (Image) is not connected" in p for p in _problems(text)
    )


def test_origin_ages_count_the_declared_transport_age_of_a_ros2_input():
    plan = check_text(graph(age=0.08), "g.yaml")
    (item,) = bounded_inputs(plan.modules, plan.connections, Ros2Check(plan.ros2).sources())
    assert str(item.connection.dst) == "register.command"
    assert item.worst.age == pytest.approx(0.08)  # snake and servo are triggered: add nothing
    assert item.worst.text().startswith("ROS 2 /wrist_camera/image_raw (declared) +80 ms")
    # beyond REG_VEL's max_origin_age (0.25 s): refused, the path named
    text = graph(age=0.3)
    (problem,) = [p for p in _problems(text) if "max_origin_age" in p]
    assert problem.startswith(f"g.yaml:{_line_of(text, '- servo.twist -> register.command')}:")
    assert "the graph's rates allow 0.300 s: ROS 2 /wrist_camera/image_raw (declared) +300" in (
        problem
    )


@pytest.mark.parametrize(
    "old, new, needle, why",
    [
        ("/snake/contour,", "snake/contour,", "snake/contour,", "must be absolute"),
        ("/joint_states,", "/joint__states/,", "/joint__states/", "must not end with `/`"),
        (
            "type: geometry_msgs/msg/PolygonStamped",
            "type: geometry_msgs/msg/Polygonstamped",
            "Polygonstamped",
            "no message type 'geometry_msgs/msg/Polygonstamped'",
        ),
        (
            "type: geometry_msgs/msg/PolygonStamped",
            "type: sensor_msgs/msg/Image",
            "snake.contour:",
            "converts to geometry_msgs/msg/PolygonStamped; found sensor_msgs/msg/Image",
        ),
        ("    snake.contour:", "    snak.contour:", "snak.contour", "unknown module `snak`"),
        ("    snake.contour:", "    snake.contours:", "snake.contours", "has no output"),
        ("    kin.joint_state:", "    kin.tool_pose:", "kin.tool_pose", "is an output"),
        (
            "    kin.joint_state: {topic: /joint_states, type: sensor_msgs/msg/JointState}",
            "    servo.guard: {topic: /joint_states, type: sensor_msgs/msg/JointState}",
            "    servo.guard: {topic",
            "expected a message type with a conversion from ROS 2 (Contour, Image, JointState)",
        ),
        (
            "    kin.joint_state: {topic: /joint_states, type: sensor_msgs/msg/JointState}",
            "    servo.contour: {topic: /joint_states, type: sensor_msgs/msg/JointState}",
            "type: sensor_msgs/msg/JointState}",
            "umbra's Contour converts from geometry_msgs/msg/PolygonStamped; found",
        ),
        (
            "max_transport_age_s: 0.05",
            "max_transport_age_s: 20",
            "max_transport_age_s: 20",
            "expected seconds in (0, 10], found 20",
        ),
        (
            "max_transport_age_s: 0.05",
            "status_name: g",
            "status_name: g",
            "`status_name` is for `ros2.out` mappings only",
        ),
    ],
)
def test_problems_are_placed_at_their_yaml_node(old, new, needle, why):
    text = graph(replace={old: new})
    line = _line_of(text, needle)
    found = [p for p in _problems(text) if why in p]
    assert found, _problems(text)
    assert found[0].startswith(f"g.yaml:{line}:"), found


def test_a_ros2_input_cannot_also_have_a_producer():
    text = graph(
        replace={
            "  rotate: {type: ROTATE_KIN}\n": "  rotate: {type: ROTATE_KIN}\n"
            "  joints: {type: WOLVERINE_JNTS, rate: 100}\n",
            "  - rotate.tool_twist -> kin.tool_twist\n": "  - rotate.tool_twist -> kin.tool_twist\n"
            "  - kin.joint_rates -> joints.rates\n  - joints.joint_state ~> kin.joint_state\n",
        }
    )
    (problem,) = [p for p in _problems(text) if "two producers" in p]
    assert problem.startswith(f"g.yaml:{_line_of(text, '    kin.joint_state: {topic')}:")
    assert (
        "input `kin.joint_state` has two producers: `joints.joint_state` (line 18) and ROS 2 "
        in (problem)
    )


def test_a_ros2_command_output_fed_around_the_guard_is_refused():
    text = graph(
        replace={
            "  out:\n": "  out:\n    servo.twist: {topic: /servo_node/delta_twist_cmds, "
            "type: geometry_msgs/msg/TwistStamped}\n"
        }
    )
    (problem,) = [p for p in _problems(text) if "safety guard" in p]
    assert problem.startswith(f"g.yaml:{_line_of(text, 'servo.twist: {topic')}:")
    assert "command path snake -> servo -> ROS 2 /servo_node/delta_twist_cmds has none" in problem
    # behind the guard, the same twist may go out
    ok = graph(
        replace={
            "  out:\n": "  out:\n    register.twist: {topic: /servo_node/delta_twist_cmds, "
            "type: geometry_msgs/msg/TwistStamped}\n"
        }
    )
    assert any(
        p.mapping.is_command and p.module == "register" for p in check_text(ok, "g.yaml").ros2
    )


class Drive(Module):
    """A drive whose command input must be guarded (as a joint driver's rates are)."""

    frames = Input(Image, trigger=True, requires_guard=True)


def test_a_ros2_topic_never_feeds_a_guarded_input_directly():
    registry = Registry()
    registry.add(Drive)
    text = graph(
        replace={
            "  rotate: {type: ROTATE_KIN}\n": "  rotate: {type: ROTATE_KIN}\n"
            "  drive: {type: Drive}\n",
            "  in:\n": "  in:\n    drive.frames: {topic: /f, type: sensor_msgs/msg/Image}\n",
        }
    )
    with pytest.raises(CheckFailed) as err:
        check_text(text, "g.yaml", registry)
    (problem,) = str(err.value).splitlines()
    assert problem.startswith(f"g.yaml:{_line_of(text, 'drive.frames:')}:")
    assert "`drive.frames` must be fed through a safety guard, but ROS 2 topic /f would" in problem


def test_umbra_check_says_file_line_and_exits_2(tmp_path):
    path = tmp_path / "g.yaml"
    text = graph(replace={"/snake/contour,": "/snake//contour,"})
    path.write_text(text)
    proc = subprocess.run(
        [sys.executable, "-m", "umbra.runtime.cli.main", "check", str(path)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2
    line = _line_of(text, "/snake//contour")
    assert f"{path}:{line}:" in proc.stderr and "must not contain `//`" in proc.stderr
    assert "Traceback" not in proc.stderr
    path.write_text(graph())
    ok = subprocess.run(
        [sys.executable, "-m", "umbra.runtime.cli.main", "check", str(path)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert ok.returncode == 0, ok.stderr
    assert "ros2 snake.image <- /wrist_camera/image_raw (sensor_msgs/msg/Image)" in ok.stdout
    assert "ROS 2 /wrist_camera/image_raw (declared) +50 ms" in ok.stdout
