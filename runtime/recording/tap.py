"""Recording a whole run: every output of a process, into one MCAP file.

The scheduler calls :func:`attach` after wiring (``SchedulerOptions.record``): each output of this
process — feeding a connection to a module here or, over a link, in another process, or feeding
nothing, as ``ros2 bag record --all`` records a topic nobody subscribes to (the arm's link frames,
a solver's status) — gets one more sink that hands its samples to a :class:`RecordingFile`, so
every sample is recorded once, by the process that produced it. The exception is an image output
that feeds nothing (an operator view drawn for a video file): it costs an encoding per frame, so
it is recorded only when ``record.ports`` names it. The topic of output
``module.port`` is ``/module/port``. Recording starts with the graph file and the frames as
attachments, and the run, parameters, modules and versions as metadata; ``/tf_static`` holds the
static frames (but those whose child a recorded pose moves: a frame has one parent in a viewer).
A split run writes one part per process (``<file stem>-<process>.mcap``) that the launcher merges
into the run's file when every process has ended (``umbra.runtime.recording.merge``).
"""

from __future__ import annotations

import json
import platform
import time
from collections.abc import Mapping
from importlib import metadata as importlib_metadata
from pathlib import Path
from typing import TYPE_CHECKING, Any

from umbra.connectors.messages import Image, Pose
from umbra.runtime.recording.foxglove_msgs import time_ns, wall_offset
from umbra.runtime.recording.settings import RecordSettings
from umbra.runtime.recording.writer import (
    META_FRAME,
    META_JOINTS,
    META_PORT,
    META_PROCESS,
    RecordingFile,
)
from umbra.runtime.rt_priority import priority_for

if TYPE_CHECKING:
    import logging

    from umbra.connectors.module import Module
    from umbra.runtime.graph.plan import GraphPlan

#: Distributions whose versions a recording names.
VERSIONED = (
    "umbra-smart",
    "numpy",
    "mcap",
    "mcap-protobuf-support",
    "foxglove-schemas-protobuf",
    "eclipse-zenoh",
    "opencv-python-headless",
    "opencv-python",
    "msgspec",
)


def topic_of(module: str, port: str) -> str:
    """The MCAP topic of output ``module.port``."""
    return f"/{module}/{port}"


def part_path(out: Path, settings: RecordSettings, process: str | None) -> Path:
    """The file a process records into: the run's file, or its part of a split run."""
    path = out / settings.file
    if process is None:
        return path
    return path.with_name(f"{path.stem}-{process}{path.suffix}")


def versions() -> dict[str, str]:
    """Python, platform and the versions of the packages that made the recording."""
    found = {"python": platform.python_version(), "platform": platform.platform()}
    for dist in VERSIONED:
        try:
            found[dist] = importlib_metadata.version(dist)
        except importlib_metadata.PackageNotFoundError:
            continue
    return found


def recorded_outputs(
    plan: GraphPlan, local: set[str], named: set[str] | frozenset[str] = frozenset()
) -> list[tuple[str, str]]:
    """``(module, port)`` of every output of the modules in ``local``, in data order, but image
    outputs that feed no connection unless ``named`` (``module.port``) holds them."""
    fed = {(c.src.module, c.src.port) for c in plan.connections}
    return [
        (m, p)
        for m in plan.order
        if m in local
        for p, info in plan.modules[m].outputs.items()
        if (m, p) in fed or f"{m}.{p}" in named or not issubclass(info.msg_type, Image)
    ]


def kept_outputs(
    plan: GraphPlan, local: set[str], settings: RecordSettings
) -> list[tuple[str, str, str, Any]]:
    """``(module, port, choice, port info)`` of the outputs of ``local`` that are recorded:
    :func:`recorded_outputs`, but those ``record.ports`` turns off."""
    found = []
    for module, port in recorded_outputs(plan, local, set(settings.ports)):
        choice = settings.choice(module, port)
        if choice != "off":
            found.append((module, port, choice, plan.modules[module].outputs[port]))
    return found


def moving_frames(plan: GraphPlan, settings: RecordSettings) -> set[str]:
    """Children of the ``Pose`` outputs (declared ``parent->child``) recorded in any process."""
    return {
        info.frame.split("->", 1)[1]
        for _m, _p, _c, info in kept_outputs(plan, set(plan.modules), settings)
        if issubclass(info.msg_type, Pose) and info.frame and "->" in info.frame
    }


def run_metadata(plan: GraphPlan, clock: str, process: str | None) -> dict[str, dict[str, str]]:
    """The metadata records that say what produced a recording."""
    spec = plan.spec
    run = {
        "graph": spec.name,
        "graph_file": str(spec.file),
        "process": process or "",
        "processes": ",".join(plan.populated_processes),
        "clock": clock,
        "seed": str(spec.seed),
        "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    }
    params = {
        name: json.dumps(m.params.model_dump(mode="json"), sort_keys=True)
        for name, m in plan.modules.items()
    }
    modules = {
        name: json.dumps(
            {"type": m.spec.type, "process": m.process, "rate": m.spec.rate, "triggers": m.triggers}
        )
        for name, m in plan.modules.items()
    }
    frames = {f"{f.parent}->{f.child}": json.dumps(f.T_parent_child.tolist()) for f in spec.frames}
    return {
        "umbra.run": run,
        "umbra.parameters": params,
        "umbra.modules": modules,
        "umbra.frames": frames,
        "umbra.versions": versions(),
    }


def check_file_clash(plan: GraphPlan, settings: RecordSettings) -> None:
    """CheckFailed when a module's parameter names the run's recording file (a Recorder left at
    its default ``recording.mcap``): two writers would share one file."""
    from umbra.connectors.errors import CheckFailed, Diagnostic, Location

    problems = []
    for name, mplan in plan.modules.items():
        for key, value in mplan.params.model_dump().items():
            if value == settings.file:
                loc = mplan.spec.param_val_loc.get(key) or mplan.spec.loc
                problems.append(
                    Diagnostic(
                        loc or Location(str(plan.spec.file), 0),
                        f"module `{name}` writes `{value}` ({key}), the file the run records "
                        f"into; give it another {key} or set `record: {{file: ...}}`",
                    )
                )
    if problems:
        raise CheckFailed(problems)


class RunRecorder:
    """The recording of one process of a run (see the module docstring)."""

    def __init__(
        self,
        plan: GraphPlan,
        modules: Mapping[str, Module[Any]],
        settings: RecordSettings,
        *,
        process: str | None,
        output_dir: Path,
        clock_kind: str,
        now: float,
        log: logging.Logger | None = None,
    ) -> None:
        """Record the outputs of ``modules`` (this process's, wired) of ``plan`` into the part
        file of ``process`` (None: the run's file, every module in one process) under
        ``output_dir``; ``clock_kind`` ("sim", "real") and ``now`` (s) are the scheduler's
        clock."""
        self.plan = plan
        check_file_clash(self.plan, settings)
        self.settings = settings
        self.process = process
        self.clock = clock_kind
        self.path = part_path(output_dir, settings, process)
        outputs = kept_outputs(self.plan, set(modules), settings)
        # raw pixels do not compress: LZ4 would cost the recorder and every reader time for less
        # than a percent; JPEG/PNG images and the rest stay small either way
        raw_images = any(c == "raw" and issubclass(i.msg_type, Image) for _m, _p, c, i in outputs)
        # nor in a real-time process: a chunk is compressed holding the GIL (another thread waited
        # up to 2.7 ms per MiB of LZ4), and the loop would wait for it (the merge comes after)
        realtime = priority_for(plan.spec.realtime_priority, process) is not None
        self.file = RecordingFile(
            self.path,
            blocking=self.clock == "sim",
            jpeg_quality=settings.jpeg_quality,
            compress=not raw_images and not realtime,
            # one offset for the whole file: every time written is wall-clock time
            clock_offset=wall_offset(now),
            log=log,
            record_format=settings.format,
        )
        self.topics: list[str] = []
        # children of poses recorded by any process of the run: every part leaves them out of
        # its static frames, whichever part's static frames the merged file keeps
        self.moving_frames = moving_frames(self.plan, settings)
        for module, port, choice, info in outputs:
            is_image = issubclass(info.msg_type, Image)
            topic = topic_of(module, port)
            meta = {
                META_PORT: f"{module}.{port}",
                META_PROCESS: self.plan.modules[module].process,
                META_FRAME: info.frame or "",
                META_JOINTS: ",".join(info.joints or ()),
            }
            self.file.declare(topic, info.msg_type, meta, images=choice if is_image else "raw")
            modules[module].outputs[port].sinks.append(self.file.sink(topic))
            self.topics.append(topic)

    def start(self, now: float) -> None:
        """Metadata, the graph file, the static frames; call before the first tick."""
        for name, data in run_metadata(self.plan, self.clock, self.process).items():
            if name == "umbra.run":  # the first tick's time, on the file's wall-clock line
                offset = self.file.clock_offset
                data["t0_ns"] = str(time_ns(now, offset))
                data["clock_offset_ns"] = str(round(offset * 1e9))  # wall − the run's clock
            self.file.add_metadata(name, data)
        text = self.plan.spec.text.encode()  # as run: composed when the graph extends another
        if not text:  # a graph made in code
            try:
                text = Path(self.plan.spec.file).read_bytes()
            except OSError:
                text = b""
        if text:
            self.file.add_attachment("graph.yaml", "application/yaml", text)
        # a frame that a recorded pose moves keeps that one parent in a viewer's transform tree
        static = [
            (f.parent, f.child, f.T_parent_child)
            for f in self.plan.spec.frames
            if f.child not in self.moving_frames
        ]
        self.file.write_static_frames(static, now)

    def close(self) -> None:
        """Write what is queued and finish the file."""
        self.file.close()

    def summary(self) -> dict[str, Any]:
        """For the run's summary: file, samples written and dropped."""
        return {
            "file": str(self.path),
            "written": self.file.written,
            "dropped": self.file.dropped,
            "topics": len(self.topics),
            **({"error": self.file.error} if self.file.error else {}),
        }
