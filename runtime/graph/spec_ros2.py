"""What a graph's ``ros2:`` section says (before the semantic checks): the ROS 2 domain, router
and node, and each port mapped to a ROS 2 topic, with the source location of every part.

The section (``docs/ros2.md``)::

    ros2:
      domain: 0                      # the default of `umbra run --ros2` (--ros2-domain N)
      router: tcp/127.0.0.1:7447     # (--ros2-router ENDPOINT)
      node: umbra                    # a split run's processes are umbra_<process>
      out:
        kinematics.joints: {topic: /joint_states, type: sensor_msgs/msg/JointState}
      in:
        camera.ros2: {topic: /wrist_camera/image_raw, type: sensor_msgs/msg/Image,
                      clock_error_s: 0.002, max_transport_age_s: 0.05}

A port is ``module.port``: an output for ``out`` (published to ROS 2), an input for ``in`` (fed
from ROS 2, as a link would feed it; it then has no producer in the graph).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from umbra.connectors.errors import Location

#: The endpoint rmw_zenoh's nodes connect to by default (``rmw_zenohd`` listens there).
DEFAULT_ROS2_ROUTER = "tcp/127.0.0.1:7447"


@dataclass
class Ros2PortSpec:
    """One ``module.port: {topic, type, ...}`` of ``ros2.out`` or ``ros2.in``.

    ``options``: the mapping's other fields as written (``frame_id``, ``gripper_joint``,
    ``status_name``, ``clock_error_s``, ``max_transport_age_s``, ``qos``); ``field_loc``: where
    each field's value is (``topic``, ``type`` and the options), for the checks' diagnostics."""

    module: str
    port: str
    direction: str
    topic: str
    ros_type: str
    loc: Location
    options: dict[str, Any] = field(default_factory=dict)
    field_loc: dict[str, Location] = field(default_factory=dict)

    def where(self, name: str) -> Location:
        """The location of field ``name`` (the port's own when the field is not written)."""
        return self.field_loc.get(name, self.loc)

    def __str__(self) -> str:
        return f"{self.module}.{self.port}"


@dataclass
class Ros2Section:
    """The ``ros2:`` section: defaults of the run's ROS 2 side and the mapped ports."""

    domain: int = 0
    router: str = DEFAULT_ROS2_ROUTER
    node: str = "umbra"
    distro: str = "jazzy"
    ports: list[Ros2PortSpec] = field(default_factory=list)
    loc: Location | None = None

    def fed_inputs(self) -> set[tuple[str, str]]:
        """``(module, port)`` of every input fed from ROS 2 (it counts as connected)."""
        return {(p.module, p.port) for p in self.ports if p.direction == "in"}
