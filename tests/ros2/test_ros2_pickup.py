"""A ROS 2 robot picked up end to end: the simulated robot of ``examples/ros2_robot`` (its own
process, on zenoh-ros2-sdk only) publishes its wrist camera and joint states and takes joint
velocities; ``umbra run graphs/ros2_pickup.yaml --ros2`` (three processes, each a ROS 2 node)
drives it through a real zenoh router. The robot knows the truth and judges the grasp."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.poll import wait_for
from umbra.connectors.errors import CheckFailed
from umbra.runtime.graph.check import check_text

from .robot_process import ROOT, interrupt, judged, start_robot
from .run_graph import start_run

GRAPH = ROOT / "graphs" / "ros2_pickup.yaml"


@pytest.mark.slow  # a real pick-up: ~20 s of motion, 60 s under load
@pytest.mark.timeout(300)
def test_a_ros2_robot_grasps_as_the_native_graph_does(router_port: int, tmp_path: Path) -> None:
    router = f"tcp/127.0.0.1:{router_port}"
    verdict = tmp_path / "verdict.json"
    robot = start_robot(router, verdict, "--duration", "240", "--linger", "30")
    run = start_run(GRAPH, tmp_path / "out", "--ros2", "--ros2-router", router)
    try:
        alive = lambda: robot.poll() is None and run.poll() is None  # noqa: E731
        record = wait_for(
            lambda: judged(verdict) or not alive(), 200.0, "the verdict or the run's end"
        )
        assert alive(), (robot.poll(), run.poll())
    finally:
        code, _, err = interrupt(run)
        interrupt(robot)
    assert isinstance(record, dict)
    assert record["grasped"], record["verdict"]
    assert record["position_error_mm"] <= 2.0 and abs(record["roll_error_deg"]) <= 1.0
    assert record["velocity_commands"] > 100 and not record["refused"]
    assert "Traceback" not in err and code in (0, 1, 130), err[-2000:]
    # the summary states the ROS 2 inputs' origin ages, per process that takes them
    umbra = json.loads((tmp_path / "out" / "summary-umbra.json").read_text())["ros2"]
    smart = json.loads((tmp_path / "out" / "summary-smart.json").read_text())["ros2"]
    assert umbra["node"] == "umbra_umbra" and smart["node"] == "umbra_smart"
    image = umbra["topics"]["/wrist_camera/image_raw"]
    joints = smart["topics"]["/joint_states"]
    for topic in (image, joints):
        ages = topic["origin_age_s"]
        assert topic["received"] >= 100 and topic["refused"] == 0, topic
        assert ages["undated"] == 0 and 0.001 <= ages["median"] <= ages["p95"] <= ages["max"]
        assert ages["median"] < 0.25  # fresher than REG_VEL's bound, as it must be to move
    rates = smart["topics"]["/forward_velocity_controller/commands"]
    assert rates["sent"] >= record["velocity_commands"]  # all it applied came from us
    assert smart["topics"]["/gripper/command"]["sent"] >= 1  # the close, behind REG_VEL
    for line in (
        "in  /wrist_camera/image_raw (sensor_msgs/msg/Image) snake.image: received",
        "in  /joint_states (sensor_msgs/msg/JointState) kinematics.joint_state: received",
    ):
        assert line in err and "origin age median" in err.split(line, 1)[1].split("\n", 1)[0]


def test_the_ros2_pickup_refuses_a_command_path_around_the_guard() -> None:
    text = GRAPH.read_text()
    plan = check_text(text, str(GRAPH))
    assert {str(p) for p in plan.ros2 if p.mapping.is_command} == {"kinematics.joint_rates"}
    bypass = text.replace("  - register.twist -> rotate.camera_twist\n", "").replace(
        "  - servo.twist -> register.command\n", "  - servo.twist -> rotate.camera_twist\n"
    )
    with pytest.raises(CheckFailed) as err:
        check_text(bypass, str(GRAPH))
    assert "`kinematics.joint_rates` commands a ROS 2 arm" in str(err.value)
