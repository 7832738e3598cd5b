"""A graph's mapping of one port to one ROS 2 topic: the declaration a graph's ``ros2:`` section
parses into, checked here once for every caller (``umbra check``, ``umbra run --ros2``, tests).

An **out** mapping publishes an output's samples to ROS 2; an **in** mapping feeds an input from
a ROS 2 topic. Each names a fully qualified topic, a message type the distribution knows, and the
umbra message type at our end; the pair must have a conversion (:mod:`~umbra.runtime.ros2.outbound`,
:mod:`~umbra.runtime.ros2.inbound`). Command types (:data:`COMMAND_TYPES`) are what makes a ROS 2
arm move: the graph checker requires that every path to such an output passes a guard.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

from umbra.runtime.ros2.inbound import INBOUND, InOptions
from umbra.runtime.ros2.msgtypes import DEFAULT_DISTRO, distro_problem, known_type_problem
from umbra.runtime.ros2.names import topic_name_problem
from umbra.runtime.ros2.outbound import OUTBOUND, OutOptions
from umbra.runtime.ros2.qos import ROS_DEFAULT, QosProfile

#: ROS 2 types that command motion (moveit_servo's twist; ros2_control's forward velocity
#: controller): an out mapping of one must be fed through a guard (REG_VEL).
COMMAND_TYPES = frozenset({"geometry_msgs/msg/TwistStamped", "std_msgs/msg/Float64MultiArray"})
#: Largest wall-clock error bound a mapping may declare [s] (beyond it every input is old).
MAX_CLOCK_ERROR_S = 1.0
#: The worst age an input's sample has when it arrives, unless the mapping declares one [s]
#: (capture to receipt through a router on one site's network).
DEFAULT_TRANSPORT_AGE_S = 0.05
#: Largest worst-case transport age a mapping may declare [s].
MAX_TRANSPORT_AGE_S = 10.0


class Direction(str, Enum):
    """Which way samples cross: ``out`` to ROS 2, ``in`` from ROS 2."""

    OUT = "out"
    IN = "in"


class MappingError(ValueError):
    """A mapping that cannot be: ``problems`` lists ``(field, reason)`` pairs, so a parser can
    point at the YAML node of each field."""

    def __init__(self, problems: list[tuple[str, str]]) -> None:
        self.problems = problems
        super().__init__("; ".join(f"{f}: {why}" for f, why in problems))


def mapping_problems(
    topic: object,
    ros_type: object,
    umbra_type: object,
    direction: object,
    distro: object = DEFAULT_DISTRO,
    clock_error_s: object = 0.0,
    max_transport_age_s: object = DEFAULT_TRANSPORT_AGE_S,
) -> list[tuple[str, str]]:
    """Every ``(field, reason)`` why these settings cannot make a mapping (empty: they can)."""
    out: list[tuple[str, str]] = []
    if problem := topic_name_problem(topic):
        out.append(("topic", problem))
    if problem := distro_problem(distro):
        out.append(("distro", problem))
        return out
    if problem := known_type_problem(ros_type, str(distro)):
        out.append(("type", problem))
    try:
        way = Direction(direction)
    except ValueError:
        out.append(("direction", f"expected `out` or `in`, found {direction!r}"))
        return out
    pairs = list(OUTBOUND) if way is Direction.OUT else [(u, r) for r, u in INBOUND]
    if not any(p == (umbra_type, ros_type) for p in pairs) and not out:
        known = sorted(r for u, r in pairs if u == umbra_type)
        where = "to" if way is Direction.OUT else "from"
        if known:
            out.append(
                (
                    "type",
                    f"umbra's {umbra_type} converts {where} {', '.join(known)}; found {ros_type}",
                )
            )
        else:
            takes = sorted({u for u, _ in pairs})
            out.append(
                (
                    "umbra_type",
                    f"expected a message type with a conversion {where} ROS 2"
                    f" ({', '.join(takes)}), found {umbra_type!r}",
                )
            )
    if (
        not isinstance(clock_error_s, (int, float))
        or not math.isfinite(clock_error_s)
        or not 0.0 <= clock_error_s <= MAX_CLOCK_ERROR_S
    ):
        out.append(
            (
                "clock_error_s",
                f"expected seconds in [0, {MAX_CLOCK_ERROR_S}], found {clock_error_s!r}",
            )
        )
    if (
        isinstance(max_transport_age_s, bool)
        or not isinstance(max_transport_age_s, (int, float))
        or not math.isfinite(max_transport_age_s)
        or not 0.0 < max_transport_age_s <= MAX_TRANSPORT_AGE_S
    ):
        out.append(
            (
                "max_transport_age_s",
                f"expected seconds in (0, {MAX_TRANSPORT_AGE_S:g}], found {max_transport_age_s!r}",
            )
        )
    return out


@dataclass(frozen=True)
class Ros2Mapping:
    """One port mapped to one ROS 2 topic (checked when made: :class:`MappingError`).

    ``frame_id``: the frame for messages whose umbra type names none (a contour's image frame; a
    joint state's header) or for inputs whose header names none; ``gripper_joint``: a joint name
    under which a JointState's gripper opening is published or taken (empty: left out);
    ``joints``: for a JointState input, the joint names taken, in the consumer's order (empty:
    every name the message has, in its order);
    ``clock_error_s`` [s]: for inputs, the bound of the sender's wall clock against ours;
    ``max_transport_age_s`` [s]: for inputs, the worst age a sample has when it arrives (from
    its ``header.stamp`` to our receipt: the sender's capture, its period and the transport),
    what ``umbra check`` counts for the input as it counts a link's latency."""

    topic: str
    ros_type: str
    umbra_type: str
    direction: Direction
    qos: QosProfile = ROS_DEFAULT
    frame_id: str = ""
    gripper_joint: str = ""
    status_name: str = "umbra"
    clock_error_s: float = 0.0
    distro: str = DEFAULT_DISTRO
    max_transport_age_s: float = DEFAULT_TRANSPORT_AGE_S
    joints: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        found = mapping_problems(
            self.topic,
            self.ros_type,
            self.umbra_type,
            self.direction,
            self.distro,
            self.clock_error_s,
            self.max_transport_age_s,
        )
        if found:
            raise MappingError(found)
        object.__setattr__(self, "direction", Direction(self.direction))

    @property
    def is_command(self) -> bool:
        """True when this publishes motion commands to a ROS 2 arm."""
        return self.direction is Direction.OUT and self.ros_type in COMMAND_TYPES

    def out_options(self) -> OutOptions:
        return OutOptions(
            frame_id=self.frame_id,
            gripper_joint=self.gripper_joint,
            status_name=self.status_name,
            distro=self.distro,
        )

    @property
    def worst_arrival_age_s(self) -> float:
        """The worst origin age [s] of an input's sample as it arrives: the declared transport
        age plus the clock error bound its origin is moved by
        (:mod:`~umbra.runtime.ros2.stamps`)."""
        return self.max_transport_age_s + self.clock_error_s

    def in_options(self) -> InOptions:
        return InOptions(
            frame_id=self.frame_id,
            clock_error_s=self.clock_error_s,
            joints=self.joints,
            gripper_joint=self.gripper_joint,
        )
