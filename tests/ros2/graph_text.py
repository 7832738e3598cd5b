"""A small graph whose camera and arm are on the ROS 2 side: the wrist camera's image and the
joint states come in from ROS 2, the joint rates go out (behind REG_VEL), for the checker's and
the run's tests."""

from __future__ import annotations

GRAPH = """\
graph: r2
clock: real
frames:
  tool->camera: {xyz: [0, 0, -0.12]}
modules:
  snake: {type: vsSnake, params: {seed_mode: none}}
  servo: {type: vsServo}
  register: {type: REG_VEL, rate: 100}
  rotate: {type: ROTATE_KIN}
  kin: {type: WOLVERINE_KIN}
connections:
  - snake.contour -> servo.contour
  - servo.twist -> register.command
  - register.twist -> rotate.camera_twist
  - rotate.tool_twist -> kin.tool_twist
ros2:
  out:
    kin.joint_rates:
      {topic: /forward_velocity_controller/commands, type: std_msgs/msg/Float64MultiArray}
    snake.contour: {topic: /snake/contour, type: geometry_msgs/msg/PolygonStamped}
  in:
    snake.image:
      {topic: /wrist_camera/image_raw, type: sensor_msgs/msg/Image, max_transport_age_s: AGE}
    kin.joint_state: {topic: /joint_states, type: sensor_msgs/msg/JointState}
"""


def graph(age: float = 0.05, replace: dict[str, str] | None = None) -> str:
    """The graph text, its camera's declared transport age ``age`` [s], with ``replace``'s
    substitutions (old text: new text)."""
    text = GRAPH.replace("AGE", repr(age))
    for old, new in (replace or {}).items():
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    return text
