"""Graph file -> :class:`GraphSpec`: the shape of the YAML, every problem with its location.

Format (see README "Graphs")::

    graph: counter_chain          # name, also the default zenoh key prefix
    seed: 0                       # sim runs are reproducible for a seed
    clock: sim                    # default clock: sim | real
    processes: {umbra: {}, smart: {cpu_latency_us: 0}}   # hold idle CPUs awake:
    umbra.runtime.realtime
    # smart: {realtime_priority: 80}  # its threads under SCHED_FIFO: umbra.runtime.rt_priority
    frames:
      tool->camera: {xyz: [0, 0.05, 0.1], rpy_deg: [0, 0, 90]}
    modules:
      source: {type: Counter, process: umbra, rate: 100, params: {start: 0}}
      sink:   {type: Printer, process: smart, trigger: value}
    connections:
      - source.count -> sink.value
      - sink.x ~> source.y        # delayed: reads the previous tick's value
    links: {prefix: demo, listen: [tcp/127.0.0.1:7447]}

Before the sections are read, a graph that ``extends:`` another is composed with it
(``parse_extends``) and each ``$NAME`` is replaced by its entry of ``values:`` (``parse_values``);
every part keeps the file and line where it is written.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from umbra.connectors.errors import CheckFailed, Diagnostic, Location, UserError
from umbra.connectors.frames import NAME_RE  # one rule for every graph name
from umbra.connectors.user_files import read_bytes
from umbra.runtime.graph.located_yaml import MAX_BYTES, YMap, load_located
from umbra.runtime.graph.names import (
    MAX_NAME_CHARS,
)
from umbra.runtime.graph.parse_base import _kind, _plain
from umbra.runtime.graph.parse_extends import compose
from umbra.runtime.graph.parse_links import LinksParser
from umbra.runtime.graph.parse_modules import ModulesParser
from umbra.runtime.graph.parse_processes import ProcessesParser
from umbra.runtime.graph.parse_ros2 import Ros2Parser
from umbra.runtime.graph.parse_values import substitute
from umbra.runtime.graph.spec import (
    GraphSpec,
)
from umbra.runtime.recording.settings import parse_record

TOP_KEYS = (
    "graph",
    "description",
    "seed",
    "clock",
    "duration",
    "processes",
    "frames",
    "modules",
    "connections",
    "links",
    "record",
    "ros2",
)


class _Parser(ProcessesParser, ModulesParser, LinksParser, Ros2Parser):
    """The whole file: its top-level keys, then each section (``umbra.runtime.graph.parse_*``)."""

    def parse(self, doc: Any) -> GraphSpec | None:
        if not isinstance(doc, YMap):
            where = getattr(doc, "loc", Location(self.file, 1, 1))
            self.error(
                where,
                f"a graph file must be a mapping with keys `graph`, `modules`, `connections`; "
                f"found {_kind(doc)}",
            )
            return None
        self.unknown_keys(doc, TOP_KEYS, "the graph")
        spec = GraphSpec(name="", file=self.file, loc=doc.loc)
        name = doc.get("graph")
        if "graph" not in doc:
            self.error(doc.loc, "missing `graph: NAME` (the graph's name)")
        elif not isinstance(name, str) or not NAME_RE.match(name) or len(name) > MAX_NAME_CHARS:
            self.error(
                doc.val_loc["graph"],
                f"graph name must be an identifier (letters, digits, `_`) of at most "
                f"{MAX_NAME_CHARS} characters, found {_kind(name)}",
            )
        else:
            spec.name = name
        spec.description = str(doc.get("description", ""))
        if "seed" in doc:
            seed = doc["seed"]
            if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
                self.error(
                    doc.val_loc["seed"], f"seed must be a non-negative integer, found {seed!r}"
                )
            else:
                spec.seed = seed
        if "clock" in doc:
            if doc["clock"] not in ("sim", "real"):
                self.error(
                    doc.val_loc["clock"], f"clock must be `sim` or `real`, found {doc['clock']!r}"
                )
            else:
                spec.clock = doc["clock"]
        if "duration" in doc:
            spec.duration = self.positive(doc["duration"], doc.val_loc["duration"], "duration [s]")
        spec.processes = self.processes(doc, spec)
        spec.frames = self.frames(doc)
        spec.modules = self.modules(doc, spec.processes)
        spec.connections = self.connections(doc)
        spec.links = self.links(doc)
        spec.ros2 = self.ros2(doc)
        if "record" in doc:
            spec.record = parse_record(doc["record"], doc.val_loc["record"], self.error)
        return spec


def resolved_text(doc: YMap, texts: dict[str, str]) -> str:
    """The composed graph as one YAML text that reads as the same graph (what a recording
    attaches): every value substituted, nothing extended."""
    files = list(texts)
    head = f"# {files[0]} as run: composed from {', '.join(files)}\n"
    body: str = yaml.safe_dump(
        _plain(doc), sort_keys=False, allow_unicode=True, width=100, default_flow_style=None
    )
    return head + body


class ShapeProblems(CheckFailed):
    """Shape problems, with the part of the graph that could still be read (``spec``), so the
    semantic checks can report their problems too."""

    def __init__(self, diagnostics: list[Diagnostic], spec: GraphSpec | None) -> None:
        super().__init__(diagnostics)
        self.spec = spec


def parse_graph_text(text: str | bytes, file: str) -> GraphSpec:
    """Parse graph text; raises ShapeProblems (a CheckFailed) listing every shape problem. A graph
    that ``extends:`` another reads it relative to ``file``'s folder."""
    doc = load_located(text, file)
    as_text = text.decode("utf-8", "replace") if isinstance(text, bytes) else text
    composed = compose(doc, file, as_text)
    doc = substitute(composed.doc, composed.problems)
    parser = _Parser(file, as_text, composed.texts)
    parser.problems.extend(composed.problems)
    if doc is None:
        raise CheckFailed(
            [
                Diagnostic(
                    Location(file, 1, 1),
                    "empty graph file: expected a mapping "
                    "with `graph`, `modules` and `connections`",
                )
            ]
        )
    spec = parser.parse(doc)
    if spec is not None:
        spec.broken_modules = parser.broken
        spec.sources = list(composed.texts)
        spec.text = resolved_text(doc, composed.texts) if composed.extends else as_text
    if parser.problems or spec is None:
        raise ShapeProblems(parser.problems, spec)
    return spec


def parse_graph_file(path: str | Path) -> GraphSpec:
    """Read and parse a graph file; UserError when it cannot be read. Only a regular file of at
    most MAX_BYTES is read (``/dev/zero`` or a FIFO named as a graph is refused unread)."""
    path = Path(path)
    if path.is_dir():
        raise UserError(f"{path}: error: is a directory, expected a graph file (.yaml)")
    if not path.exists():
        raise UserError(f"{path}: error: no such graph file")
    try:
        data = read_bytes(path, "graph file", MAX_BYTES)
    except UserError as exc:
        if "more than" in str(exc) and path.is_file():
            size = path.stat().st_size
            raise CheckFailed(
                [
                    Diagnostic(
                        Location(str(path), 1, 1),
                        f"file is {size} bytes; a graph file is at most {MAX_BYTES}",
                    )
                ]
            ) from None
        raise
    return parse_graph_text(data, str(path))
