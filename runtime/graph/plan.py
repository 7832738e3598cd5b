"""A checked graph, ready to run: module classes, validated parameters, resolved ports, order."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from umbra.connectors.frames import FrameTree
from umbra.connectors.messages import Message
from umbra.connectors.module import Module
from umbra.connectors.params import Parameters
from umbra.runtime.graph.spec import ConnectionSpec, GraphSpec, ModuleSpec


@dataclass
class PortInfo:
    """A port of a module instance with its frame and joint names resolved from parameters."""

    name: str
    msg_type: type[Message]
    frame: str | None
    joints: tuple[str, ...] | None


@dataclass
class ModulePlan:
    """One module instance as checked."""

    spec: ModuleSpec
    cls: type[Module[Any]]
    params: Parameters
    inputs: dict[str, PortInfo]
    outputs: dict[str, PortInfo]
    triggers: list[str]
    input_decls: dict[str, Any]

    @property
    def name(self) -> str:
        return self.spec.name

    @property
    def process(self) -> str:
        return self.spec.process


#: Message types of bulk data (frames): sent at data priority, below commands and state.
BULK_TYPES = ("Image", "StereoSnapshot")


@dataclass
class LinkPlan:
    """A connection that crosses processes and becomes a zenoh link on ``key``.

    ``reliable``: the output is declared ``events`` (operator actions, gripper, paths): ordered
    and lossless (zenoh congestion control BLOCK). Otherwise a state stream, latest-only: the
    publisher drops rather than queues under congestion (DROP) and the consumer takes the newest.
    """

    connection: ConnectionSpec
    key: str
    msg_type: type[Message]
    reliable: bool

    @property
    def bulk(self) -> bool:
        """Frames (images): below commands and state in zenoh's priorities."""
        return self.msg_type.__name__ in BULK_TYPES

    @property
    def policy(self) -> str:
        """What ``umbra check`` says of the link's delivery."""
        if self.reliable:
            return "events: ordered, lossless"
        return "state: latest-only" + (", bulk" if self.bulk else "")


@dataclass
class GraphPlan:
    """Everything the scheduler and the launcher need."""

    spec: GraphSpec
    modules: dict[str, ModulePlan]
    connections: list[ConnectionSpec]
    order: list[str]
    frames: FrameTree
    links: list[LinkPlan] = field(default_factory=list)
    #: ports mapped to ROS 2 topics, each with its owning process
    #: (``umbra.runtime.graph.check_ros2.PortMapping``)
    ros2: list[Any] = field(default_factory=list)

    @property
    def processes(self) -> list[str]:
        """Process names in declaration order (``main`` when the graph declares none)."""
        return list(self.spec.processes) or sorted({m.process for m in self.modules.values()})

    @property
    def populated_processes(self) -> list[str]:
        """Process names in declaration order, leaving out those without modules."""
        hosting = {m.process for m in self.modules.values()}
        return [p for p in self.processes if p in hosting]

    def modules_in(self, process: str | None) -> list[str]:
        """Module names of ``process`` in data order (all modules when ``process`` is None)."""
        return [n for n in self.order if process is None or self.modules[n].process == process]

    @property
    def key_prefix(self) -> str:
        return self.spec.links.prefix or f"umbra/{self.spec.name}"
