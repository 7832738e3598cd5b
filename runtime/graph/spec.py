"""What a graph file says, with the source location of every part (before semantic checks)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from umbra.connectors.errors import Location
from umbra.runtime.graph.spec_ros2 import Ros2Section
from umbra.runtime.recording.settings import RecordSettings

DEFAULT_PROCESS = "main"


@dataclass
class Endpoint:
    """``module.port`` in a connection, with the location of the module and of the port names."""

    module: str
    port: str
    module_loc: Location
    port_loc: Location

    def __str__(self) -> str:
        return f"{self.module}.{self.port}"


@dataclass
class ConnectionSpec:
    """``src -> dst`` (or ``src ~> dst`` when delayed: dst reads the previous tick's value)."""

    src: Endpoint
    dst: Endpoint
    delayed: bool
    loc: Location

    def __str__(self) -> str:
        return f"{self.src} {'~>' if self.delayed else '->'} {self.dst}"


@dataclass
class ModuleSpec:
    """One module instance: type, process, rate [Hz] or trigger inputs, raw parameters."""

    name: str
    type: str
    process: str
    rate: float | None
    trigger: list[str] | None
    params: dict[str, Any]
    loc: Location
    type_loc: Location
    process_loc: Location
    trigger_loc: Location
    params_loc: Location
    param_key_loc: dict[str, Location] = field(default_factory=dict)
    param_val_loc: dict[str, Location] = field(default_factory=dict)
    rate_loc: Location | None = None


@dataclass
class StaticFrameSpec:
    """``parent->child`` with T_parent_child (metres)."""

    parent: str
    child: str
    T_parent_child: np.ndarray
    loc: Location


@dataclass
class LinkSettings:
    """Zenoh link settings: key prefix, endpoints, optional zenoh JSON5 configuration file."""

    prefix: str = ""
    listen: list[str] = field(default_factory=list)
    connect: list[str] = field(default_factory=list)
    zenoh_config: str = ""
    #: "inline": a link sample arriving while a process is idle is handled on zenoh's thread at
    #: once; "loop": always handed to the process's loop thread (see ``umbra.runtime.scheduler``).
    dispatch: str = "inline"
    loc: Location | None = None
    zenoh_config_loc: Location | None = None


@dataclass
class GraphSpec:
    """A whole graph file."""

    name: str
    file: str
    description: str = ""
    seed: int = 0
    clock: str = "sim"
    duration: float | None = None
    processes: dict[str, Location] = field(default_factory=dict)
    #: process -> the CPU wake-up latency [µs] it holds while running (``umbra.runtime.realtime``)
    cpu_latency_us: dict[str, int] = field(default_factory=dict)
    #: process -> the SCHED_FIFO priority its threads run at (``umbra.runtime.rt_priority``)
    realtime_priority: dict[str, int] = field(default_factory=dict)
    #: per process: ``nice`` (0..19) for a process that gives way (SCHED_BATCH), e.g. the pages
    nice: dict[str, int] = field(default_factory=dict)
    modules: dict[str, ModuleSpec] = field(default_factory=dict)
    connections: list[ConnectionSpec] = field(default_factory=list)
    frames: list[StaticFrameSpec] = field(default_factory=list)
    links: LinkSettings = field(default_factory=LinkSettings)
    #: ``record:``: whether and how the run records its connections (``umbra.runtime.recording``)
    record: RecordSettings = field(default_factory=RecordSettings)
    #: ``ros2:``: the ports mapped to ROS 2 topics (``umbra.runtime.graph.spec_ros2``)
    ros2: Ros2Section = field(default_factory=Ros2Section)
    loc: Location | None = None
    #: modules whose declaration was broken (already reported); later checks stay quiet on them
    broken_modules: set[str] = field(default_factory=set)
    #: the graph as run: the file's text, or the composed graph when it extends another
    #: (``umbra.runtime.graph.parse_extends``); empty for a graph made in code
    text: str = ""
    #: every graph file read, the given one first (more than one when it extends another)
    sources: list[str] = field(default_factory=list)
