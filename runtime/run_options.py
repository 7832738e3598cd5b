"""How one process's loop runs (``SchedulerOptions``) and why it stops (``StopRequest``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from umbra.connectors.errors import UserError

#: Exit status of a run stopped by Ctrl-C or a signal.
INTERRUPTED = 130


@dataclass
class StopRequest:
    """Why the loop should end after the current tick, and with which exit status."""

    reason: str
    exit_code: int


@dataclass
class SchedulerOptions:
    """How to run: clock, duration [s], output folder, process, signal handling."""

    clock: str = "sim"
    duration: float | None = None
    output_dir: Path = field(default_factory=lambda: Path("."))
    process: str | None = None  # None: every module (single process)
    handle_signals: bool = False
    max_ticks: int | None = None
    log: Any = None
    #: "inline": a link sample arriving while the loop is idle is handled at once on the thread
    #: that received it; "loop": always on the loop's thread (``umbra.runtime.scheduler``).
    dispatch: str = "inline"
    #: the CPU wake-up latency [µs] held while the loop runs (``umbra.runtime.realtime``); None:
    #: none
    cpu_latency_us: int | None = None
    #: record every output of this process (``umbra.runtime.recording.tap``); None:
    #: as the graph's ``record:`` says
    record: Any = None
    #: a person runs this run (``ModuleContext.attended``): modules read it; the run ends when
    #: that person stops it, never by ``duration`` (which must then be None)
    attended: bool = False
    #: ``--ros2``: the ROS 2 side of this process's mapped ports
    #: (``umbra.runtime.ros2.run_bridge.Ros2RunOptions``); None: none
    ros2: Any = None

    def __post_init__(self) -> None:
        if self.attended and self.duration is not None:
            raise UserError(
                f"an attended run ends when its operator stops it: expected no duration, "
                f"found {self.duration:g} s"
            )
