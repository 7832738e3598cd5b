"""The graph's ``ros2:`` section against its modules: each mapped port exists, has a conversion
to or from the named ROS 2 type, and is owned by its module's process.

ROS 2 peers are outsiders. They feed only the inputs the section maps ``in`` (a topic may feed
several) — an input that a
connection feeds cannot be mapped too, and an input that ``requires_guard`` (a drive's command)
never takes a ROS 2 topic directly — and nothing maps a topic onto a link between our own
processes: links stay on the run's own zenoh session. An output that moves a ROS 2 arm
(:attr:`Ros2Mapping.is_command`) is held to the rule every guarded input is
(:func:`umbra.runtime.graph.check_paths.unguarded_chain`): every command path into it passes a
safety guard. An input mapped ``in`` counts as connected, and its declared worst arrival age
enters the origin ages (:class:`umbra.runtime.graph.origin_age.OutsideFeed`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from umbra.connectors.errors import Location
from umbra.runtime.graph.check_paths import GUARD_HINT, command_feeding, unguarded_chain
from umbra.runtime.graph.check_report import Report
from umbra.runtime.graph.check_wiring import joint_mismatch
from umbra.runtime.graph.origin_age import Hop, OutsideFeed, WorstAge
from umbra.runtime.graph.plan import ModulePlan, PortInfo
from umbra.runtime.graph.spec import ConnectionSpec, GraphSpec
from umbra.runtime.graph.spec_ros2 import Ros2PortSpec
from umbra.runtime.hints import did_you_mean
from umbra.runtime.ros2.qos import ROS_DEFAULT, SENSOR_DATA, QosProfile

if TYPE_CHECKING:  # imported where used: checking a graph loads this file without it
    from umbra.runtime.ros2.mapping import Ros2Mapping

#: The QoS profiles a mapping may name (``qos:``), as rclcpp names them.
QOS_PROFILES: dict[str, QosProfile] = {"default": ROS_DEFAULT, "sensor_data": SENSOR_DATA}
_TEXT_OPTIONS = ("frame_id", "gripper_joint", "status_name")


@dataclass(frozen=True)
class PortMapping:
    """Port ``module.port`` mapped to a ROS 2 topic, checked: ``process`` owns it (the module's)."""

    module: str
    port: str
    process: str
    mapping: Ros2Mapping
    loc: Location

    def __str__(self) -> str:
        return f"{self.module}.{self.port}"


@dataclass
class Ros2Check:
    """What the checks of the ``ros2:`` section found sound."""

    ports: list[PortMapping] = field(default_factory=list)

    def sources(self) -> list[OutsideFeed]:
        """The inputs fed from ROS 2, each with its declared worst arrival age, for the origin
        ages."""
        return [
            OutsideFeed(
                p.module,
                p.port,
                WorstAge(
                    p.mapping.worst_arrival_age_s,
                    [Hop(f"ROS 2 {p.mapping.topic} (declared)", p.mapping.worst_arrival_age_s)],
                ),
                p.loc,
            )
            for p in self.ports
            if p.mapping.direction.value == "in"
        ]


def check_ros2(
    spec: GraphSpec,
    modules: Mapping[str, ModulePlan],
    connections: Sequence[ConnectionSpec],
    error: Report,
) -> Ros2Check:
    """Check every port of ``spec.ros2``; the sound ones (each other one reported)."""
    found = Ros2Check()
    section = spec.ros2
    if not section.ports:
        return found
    feeding, unknown = command_feeding(spec, modules, connections)
    fed = {(c.dst.module, c.dst.port): c for c in spec.connections}
    topics: dict[str, Ros2PortSpec] = {}
    for p in section.ports:
        first = topics.setdefault(p.topic, p)
        fans_out = p.direction == first.direction == "in" and p.ros_type == first.ros_type
        if first is not p and not fans_out:  # one topic may feed several inputs, no more
            error(
                p.where("topic"),
                f"ROS 2 topic {p.topic} is mapped twice: to `{first}` (line {first.loc.line}) "
                f"and to `{p}`",
                "a topic feeds any number of inputs (`ros2.in`, one type), or is published by "
                "one output",
            )
            continue
        info = _port(spec, modules, p, error)
        if info is None:
            continue
        mapping = _mapping(p, info, section.distro, error)
        if mapping is None:
            continue
        plan = modules[p.module]
        if p.direction == "in":
            conn = fed.get((p.module, p.port))
            if conn is not None:
                error(
                    p.loc,
                    f"input `{p}` has two producers: `{conn.src}` (line {conn.loc.line}) and "
                    f"ROS 2 topic {p.topic}",
                )
                continue
            if plan.input_decls[p.port].requires_guard:
                error(
                    p.loc,
                    f"`{p}` must be fed through a safety guard, but ROS 2 topic {p.topic} would "
                    "feed it directly",
                    "map the topic to an input upstream of a watchdog register (e.g. REG_VEL)",
                )
                continue
        elif mapping.is_command:
            chain = unguarded_chain(modules, p.module, f"ROS 2 {p.topic}", feeding, unknown)
            if chain is not None:
                error(
                    p.loc,
                    f"`{p}` commands a ROS 2 arm ({p.ros_type}) and must be fed through a "
                    f"safety guard, but the command path {chain} has none",
                    GUARD_HINT,
                )
                continue
        found.ports.append(PortMapping(p.module, p.port, plan.process, mapping, p.loc))
    return found


def _port(
    spec: GraphSpec, modules: Mapping[str, ModulePlan], p: Ros2PortSpec, error: Report
) -> PortInfo | None:
    """The port ``p`` maps, or None, reported unless its module could not be built."""
    plan = modules.get(p.module)
    if plan is None:
        if p.module not in spec.modules and p.module not in spec.broken_modules:
            error(p.loc, f"unknown module `{p.module}`{did_you_mean(p.module, spec.modules)}")
        return None
    kind, ports, other = (
        ("output", plan.outputs, plan.inputs)
        if p.direction == "out"
        else ("input", plan.inputs, plan.outputs)
    )
    if p.port in ports:
        return ports[p.port]
    if p.port in other:
        error(
            p.loc,
            f"`{p}` is an {'input' if kind == 'output' else 'output'}; `ros2.{p.direction}` maps "
            f"{kind}s",
        )
    else:
        error(
            p.loc,
            f"{plan.spec.type} `{p.module}` has no {kind} `{p.port}`{did_you_mean(p.port, ports)}",
        )
    return None


def _mapping(p: Ros2PortSpec, info: PortInfo, distro: str, error: Report) -> Ros2Mapping | None:
    """The mapping ``p`` declares for a port carrying ``info.msg_type``; None when it cannot be
    (every problem reported at its field)."""
    from umbra.runtime.ros2.mapping import Direction, MappingError, Ros2Mapping

    ok = True
    for name in _TEXT_OPTIONS:
        if name in p.options and not isinstance(p.options[name], str):
            error(p.where(name), f"`{name}` must be a string, found {p.options[name]!r}")
            ok = False
    qos_name = p.options.get("qos", "default")
    if qos_name not in QOS_PROFILES:
        error(
            p.where("qos"),
            f"`qos` must be one of {', '.join(QOS_PROFILES)}, found {qos_name!r}",
        )
        ok = False
    joints = _joints(p, info, error)
    if not ok or joints is None:
        return None
    numbers = {k: p.options[k] for k in ("clock_error_s", "max_transport_age_s") if k in p.options}
    texts = {k: p.options[k] for k in _TEXT_OPTIONS if k in p.options}
    try:
        return Ros2Mapping(
            p.topic,
            p.ros_type,
            info.msg_type.__name__,
            Direction(p.direction),  # "out" or "in": the parser takes no other
            qos=QOS_PROFILES[qos_name],
            distro=distro,
            joints=joints,
            **texts,
            **numbers,
        )
    except MappingError as exc:
        for name, why in exc.problems:
            where = p.loc if name == "umbra_type" else p.where(name)
            prefix = f"`{p}` carries {info.msg_type.__name__}: " if name == "umbra_type" else ""
            error(where, prefix + why)
        return None


def _joints(p: Ros2PortSpec, info: PortInfo, error: Report) -> tuple[str, ...] | None:
    """The joint names a JointState input takes from its topic: the mapping's ``joints``, else
    the consuming port's declared ones (empty: every name a sample has); None when the mapping's
    contradict the port's (the rule of a connection: ``check_wiring.joint_mismatch``)."""
    declared = info.joints if info.msg_type.HAS_JOINTS else None
    if "joints" not in p.options:
        return tuple(declared or ()) if p.direction == "in" else ()
    given = p.options["joints"]
    if (
        p.ros_type != "sensor_msgs/msg/JointState"
        or not isinstance(given, list)
        or not given
        or not all(isinstance(n, str) and n for n in given)
    ):
        error(
            p.where("joints"),
            f"`joints` must be a list of joint names of a sensor_msgs/msg/JointState input, "
            f"found {given!r} for {p.ros_type}",
        )
        return None
    mismatch = joint_mismatch(True, tuple(given), declared, f"ROS 2 topic {p.topic}", f"`{p}`")
    if mismatch:
        error(p.where("joints"), mismatch)
        return None
    return tuple(given)
