"""Graph file -> :class:`GraphSpec`: the shape of the YAML, every problem with its location.

Format (see README "Graphs")::

    graph: counter_chain          # name, also the default zenoh key prefix
    seed: 0                       # sim runs are reproducible for a seed
    clock: sim                    # default clock: sim | real
    processes: {umbra: {}, smart: {cpu_latency_us: 0}}   # hold idle CPUs awake: runtime.realtime
    # smart: {realtime_priority: 80}  # its threads under SCHED_FIFO: runtime.rt_priority
    frames:
      tool->camera: {xyz: [0, 0.05, 0.1], rpy_deg: [0, 0, 90]}
    modules:
      source: {type: Counter, process: umbra, rate: 100, params: {start: 0}}
      sink:   {type: Printer, process: smart, trigger: value}
    connections:
      - source.count -> sink.value
      - sink.x ~> source.y        # delayed: reads the previous tick's value
    links: {prefix: demo, listen: [tcp/127.0.0.1:7447]}
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import numpy as np

from connectors.errors import CheckFailed, Diagnostic, Location, UserError
from connectors.frames import NAME_RE, transform_from_xyz_rpy  # one rule for every graph name
from connectors.limits import MAX_RATE_HZ, MIN_RATE_HZ
from connectors.safe_yaml import boolean_hint
from connectors.user_files import read_bytes
from runtime.graph.located_yaml import MAX_BYTES, YList, YMap, load_located
from runtime.graph.names import (
    MAX_NAME_CHARS,
    endpoint_problem,
    key_prefix_problem,
    plain_beyond_host,
)
from runtime.graph.spec import (
    DEFAULT_PROCESS,
    ConnectionSpec,
    Endpoint,
    GraphSpec,
    LinkSettings,
    ModuleSpec,
    StaticFrameSpec,
)
from runtime.hints import did_you_mean
from runtime.realtime import NO_CONSTRAINT_US, is_latency_us
from runtime.recording.settings import parse_record
from runtime.rt_priority import MAX_NICE, MAX_PRIORITY, MIN_PRIORITY, is_nice, is_priority

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
)
MODULE_KEYS = ("type", "process", "rate", "trigger", "params", "description")
PROCESS_KEYS = ("cpu_latency_us", "realtime_priority", "nice")
LINK_KEYS = ("prefix", "listen", "connect", "zenoh_config", "dispatch")
DISPATCH_MODES = ("inline", "loop")
CONNECTION_RE = re.compile(
    r"^\s*(?P<sm>[^.\s]+)\.(?P<sp>[^\s]+)\s*(?P<arrow>->|~>)\s*(?P<dm>[^.\s]+)\.(?P<dp>[^\s]+)\s*$"
)


class _Parser:
    def __init__(self, file: str, text: str) -> None:
        self.file = file
        self.lines = text.splitlines()
        self.problems: list[Diagnostic] = []
        self.broken: set[str] = set()

    def error(self, loc: Location | None, message: str, hint: str = "") -> None:
        self.problems.append(Diagnostic(loc or Location(self.file, 1, 1), message, hint))

    # -- helpers ----------------------------------------------------------------------------
    def expect_map(self, value: Any, loc: Location, what: str) -> YMap | None:
        if isinstance(value, YMap):
            return value
        self.error(loc, f"{what} must be a mapping, found {_kind(value)}")
        return None

    def unknown_keys(self, mapping: YMap, allowed: tuple[str, ...], what: str) -> None:
        for key in mapping:
            if key not in allowed:
                self.error(
                    mapping.key_loc[key],
                    f"unknown key `{key}` in {what}{did_you_mean(str(key), allowed)}",
                )

    def col_of(self, loc: Location, offset: int) -> Location:
        """Location ``offset`` characters into a plain or quoted scalar that starts at ``loc``."""
        line = self.lines[loc.line - 1] if 0 < loc.line <= len(self.lines) else ""
        quoted = 1 if line[loc.column - 1 : loc.column] in ("'", '"') else 0
        return Location(loc.file, loc.line, loc.column + quoted + offset)

    # -- sections -----------------------------------------------------------------------------
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
        if "record" in doc:
            spec.record = parse_record(doc["record"], doc.val_loc["record"], self.error)
        return spec

    def positive(self, value: Any, loc: Location, what: str) -> float | None:
        if (
            isinstance(value, bool)
            or not isinstance(value, int | float)
            or not value > 0
            or not math.isfinite(value)
        ):
            self.error(loc, f"{what} must be a positive number, found {value!r}")
            return None
        return float(value)

    def rate(self, value: Any, loc: Location, module: str) -> float | None:
        """A module's rate [Hz], within [MIN_RATE_HZ, MAX_RATE_HZ]."""
        rate = self.positive(value, loc, f"rate [Hz] of module `{module}`")
        if rate is not None and not MIN_RATE_HZ <= rate <= MAX_RATE_HZ:
            self.error(
                loc,
                f"rate of module `{module}` must be from {MIN_RATE_HZ:g} to {MAX_RATE_HZ:g} Hz, "
                f"found {value!r}",
            )
            return None
        return rate

    def processes(self, doc: YMap, spec: GraphSpec) -> dict[str, Location]:
        if "processes" not in doc:
            return {}
        section = self.expect_map(doc["processes"], doc.val_loc["processes"], "`processes`")
        if section is None:
            return {}
        out: dict[str, Location] = {}
        for name, body in section.items():
            if not isinstance(name, str) or not NAME_RE.match(name):
                self.error(
                    section.key_loc[name], f"process name must be an identifier, found {name!r}"
                )
                continue
            if body is not None and not isinstance(body, YMap):
                self.error(
                    section.val_loc[name],
                    f"process `{name}` must map to {{}} or its settings, found {_kind(body)}",
                )
            elif body is not None:
                self.process_settings(name, body, spec)
            out[name] = section.key_loc[name]
        return out

    def process_settings(self, name: str, body: YMap, spec: GraphSpec) -> None:
        self.unknown_keys(body, PROCESS_KEYS, f"process `{name}`")
        settings = (  # key, the check, what it must be, where the spec keeps it
            (
                "cpu_latency_us",
                is_latency_us,
                f"a whole number of microseconds from 0 to {NO_CONSTRAINT_US}",
                spec.cpu_latency_us,
            ),
            (
                "realtime_priority",
                is_priority,
                f"a whole number from {MIN_PRIORITY} to {MAX_PRIORITY} (SCHED_FIFO)",
                spec.realtime_priority,
            ),
            (
                "nice",
                is_nice,
                f"a whole number from 0 to {MAX_NICE} (the process gives way: SCHED_BATCH)",
                spec.nice,
            ),
        )
        for key, valid, expected, into in settings:
            if key not in body:
                continue
            value = body[key]
            if valid(value):
                into[name] = value
            else:
                self.error(
                    body.val_loc[key],
                    f"{key} of process `{name}` must be {expected}, found {value!r}",
                )

    def frames(self, doc: YMap) -> list[StaticFrameSpec]:
        if "frames" not in doc:
            return []
        section = self.expect_map(doc["frames"], doc.val_loc["frames"], "`frames`")
        if section is None:
            return []
        out = []
        for key, body in section.items():
            loc = section.key_loc[key]
            parts = str(key).split("->")
            if len(parts) != 2 or not all(NAME_RE.match(p.strip()) for p in parts):
                self.error(loc, f"a static frame is written `parent->child`, found `{key}`")
                continue
            body_map = self.expect_map(body, section.val_loc[key], f"frame `{key}`")
            if body_map is None:
                continue
            self.unknown_keys(body_map, ("xyz", "rpy_deg"), f"frame `{key}`")
            xyz = self.vector3(body_map, "xyz", f"frame `{key}`")
            rpy = self.vector3(body_map, "rpy_deg", f"frame `{key}`")
            if xyz is None or rpy is None:
                continue
            T = transform_from_xyz_rpy(xyz, list(np.radians(rpy)))
            out.append(StaticFrameSpec(parts[0].strip(), parts[1].strip(), T, loc))
        return out

    def vector3(self, body: YMap, key: str, what: str) -> list[float] | None:
        if key not in body:
            return [0.0, 0.0, 0.0]
        value = body[key]
        ok = (
            isinstance(value, YList)
            and len(value) == 3
            and all(
                isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
                for v in value
            )
        )
        if not ok:
            self.error(body.val_loc[key], f"`{key}` of {what} must be 3 numbers, found {value!r}")
            return None
        return [float(v) for v in value]

    def modules(self, doc: YMap, processes: dict[str, Location]) -> dict[str, ModuleSpec]:
        if "modules" not in doc:
            self.error(doc.loc, "missing `modules:` (a mapping of module name -> {type: ..., ...})")
            return {}
        section = self.expect_map(doc["modules"], doc.val_loc["modules"], "`modules`")
        if section is None:
            return {}
        if not section:
            self.error(
                doc.val_loc["modules"], "`modules` is empty: a graph needs at least one module"
            )
        out: dict[str, ModuleSpec] = {}
        for name, body in section.items():
            key_loc = section.key_loc[name]
            if not isinstance(name, str) or not NAME_RE.match(name):
                self.error(key_loc, f"module name must be an identifier, found {name!r}")
                continue
            body_map = self.expect_map(body, section.val_loc[name], f"module `{name}`")
            module = None if body_map is None else self.module(name, body_map, key_loc, processes)
            if module is not None:
                out[name] = module
            else:
                self.broken.add(str(name))
        return out

    def module(
        self, name: str, body: YMap, key_loc: Location, processes: dict[str, Location]
    ) -> ModuleSpec | None:
        self.unknown_keys(body, MODULE_KEYS, f"module `{name}`")
        if "type" not in body or not isinstance(body["type"], str):
            self.error(
                body.val_loc.get("type", key_loc),
                f"module `{name}` needs `type: TYPE_NAME`{boolean_hint(body.get('type'))}",
            )
            return None
        process = DEFAULT_PROCESS
        process_loc = body.val_loc.get("process", key_loc)
        if "process" in body:
            process = str(body["process"])
            if isinstance(body["process"], bool):
                self.error(
                    process_loc,
                    f"process of module `{name}` must be a process name, found "
                    f"{body['process']!r}{boolean_hint(body['process'])}",
                )
            elif process not in processes:
                known = list(processes) or [DEFAULT_PROCESS]
                extra = "" if processes else " (the graph declares no `processes:`)"
                self.error(
                    process_loc,
                    f"unknown process `{process}` for module `{name}`{extra}"
                    f"{did_you_mean(process, known)}",
                )
        elif processes:
            self.error(key_loc, f"module `{name}` needs `process:` (one of {', '.join(processes)})")
        rate = None
        if "rate" in body:
            rate = self.rate(body["rate"], body.val_loc["rate"], name)
        trigger = None
        trigger_loc = body.val_loc.get("trigger", key_loc)
        if "trigger" in body:
            value = body["trigger"]
            if isinstance(value, str):
                trigger = [value]
            elif isinstance(value, YList) and all(isinstance(v, str) for v in value) and value:
                trigger = list(value)
            else:
                self.error(
                    trigger_loc, f"`trigger` must name input(s) of `{name}`, found {value!r}"
                )
        params: dict[str, Any] = {}
        params_loc = body.val_loc.get("params", key_loc)
        key_locs: dict[str, Location] = {}
        val_locs: dict[str, Location] = {}
        if "params" in body and body["params"] is not None:
            pm = self.expect_map(body["params"], params_loc, f"`params` of module `{name}`")
            if pm is not None:
                params = {str(k): _plain(v) for k, v in pm.items()}
                key_locs = {str(k): pm.key_loc[k] for k in pm}
                val_locs = {str(k): pm.val_loc[k] for k in pm}
        return ModuleSpec(
            name=name,
            type=body["type"],
            process=process,
            rate=rate,
            trigger=trigger,
            params=params,
            loc=key_loc,
            type_loc=body.val_loc["type"],
            process_loc=process_loc,
            trigger_loc=trigger_loc,
            params_loc=params_loc,
            rate_loc=body.val_loc.get("rate"),
            param_key_loc=key_locs,
            param_val_loc=val_locs,
        )

    def connections(self, doc: YMap) -> list[ConnectionSpec]:
        if "connections" not in doc or doc["connections"] is None:
            return []
        section = doc["connections"]
        if not isinstance(section, YList):
            self.error(
                doc.val_loc["connections"], f"`connections` must be a list, found {_kind(section)}"
            )
            return []
        out = []
        for item, loc in zip(section, section.item_loc, strict=True):
            conn = self.connection(item, loc)
            if conn is not None:
                out.append(conn)
        return out

    def connection(self, item: Any, loc: Location) -> ConnectionSpec | None:
        if isinstance(item, YMap):
            self.unknown_keys(item, ("from", "to", "delayed"), "a connection")
            src = self.endpoint(item.get("from"), item.val_loc.get("from", loc), "from")
            dst = self.endpoint(item.get("to"), item.val_loc.get("to", loc), "to")
            delayed = item.get("delayed", False)
            if not isinstance(delayed, bool):
                self.error(
                    item.val_loc["delayed"], f"`delayed` must be true or false, found {delayed!r}"
                )
                delayed = False
            if src is None or dst is None:
                return None
            return ConnectionSpec(src, dst, delayed, loc)
        if not isinstance(item, str):
            self.error(
                loc, f"a connection is written `module.output -> module.input`, found {_kind(item)}"
            )
            return None
        match = CONNECTION_RE.match(item)
        if match is None:
            self.error(
                loc,
                f"a connection is written `module.output -> module.input` "
                f"(or `~>` when delayed), found `{item}`",
            )
            return None
        lead = len(item) - len(item.lstrip())
        src = Endpoint(
            match["sm"], match["sp"], self.col_of(loc, lead), self.col_of(loc, match.start("sp"))
        )
        dst = Endpoint(
            match["dm"],
            match["dp"],
            self.col_of(loc, match.start("dm")),
            self.col_of(loc, match.start("dp")),
        )
        return ConnectionSpec(src, dst, match["arrow"] == "~>", loc)

    def endpoint(self, value: Any, loc: Location, what: str) -> Endpoint | None:
        if not isinstance(value, str) or value.count(".") != 1 or not all(value.split(".")):
            self.error(loc, f"`{what}` must be `module.port`, found {value!r}")
            return None
        module, port = value.split(".")
        return Endpoint(module, port, loc, self.col_of(loc, len(module) + 1))

    def links(self, doc: YMap) -> LinkSettings:
        if "links" not in doc:
            return LinkSettings()
        section = self.expect_map(doc["links"], doc.val_loc["links"], "`links`")
        if section is None:
            return LinkSettings()
        self.unknown_keys(section, LINK_KEYS, "`links`")
        settings = LinkSettings(loc=section.loc)
        for key in ("listen", "connect"):
            value = section.get(key, [])
            if isinstance(value, str):
                value = [value]
            if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
                self.error(
                    section.val_loc[key],
                    f"`links.{key}` must be endpoint strings "
                    f"like `tcp/127.0.0.1:7447`, found {_kind(value)}",
                )
                continue
            where = section.val_loc.get(key, section.loc)
            item_locs = getattr(value, "item_loc", None) or [where] * len(value)
            bad = [(v, loc) for v, loc in zip(value, item_locs, strict=True) if endpoint_problem(v)]
            for endpoint, loc in bad:
                self.error(loc, f"`links.{key}`: {endpoint_problem(endpoint)}")
            exposed = [
                (v, loc)
                for v, loc in zip(value, item_locs, strict=True)
                if not endpoint_problem(v) and plain_beyond_host(v)
            ]
            for endpoint, loc in exposed:
                self.error(
                    loc,
                    f"`links.{key}`: `{endpoint}` is reachable beyond this host without TLS, "
                    "where anyone who reaches it could drive the graph",
                    "use `tls/` endpoints with the keys of `umbra keys GRAPH --out keys/` "
                    "(`links.zenoh_config: keys/`); plain TCP beyond loopback only on the "
                    "command line, with --listen/--connect and --insecure",
                )
            bad += exposed
            if not bad:
                setattr(settings, key, list(value))
        for key in ("prefix", "zenoh_config"):
            if key in section:
                if not isinstance(section[key], str):
                    self.error(section.val_loc[key], f"`links.{key}` must be a string")
                elif key == "prefix" and key_prefix_problem(section[key]):
                    self.error(
                        section.val_loc[key], f"`links.prefix`: {key_prefix_problem(section[key])}"
                    )
                else:
                    setattr(settings, key, section[key])
                    if key == "zenoh_config":
                        settings.zenoh_config_loc = section.val_loc[key]
        if "dispatch" in section:
            value = section["dispatch"]
            if value not in DISPATCH_MODES:
                self.error(
                    section.val_loc["dispatch"],
                    f"`links.dispatch` must be one of {', '.join(DISPATCH_MODES)}, "
                    f"found {_kind(value)}",
                )
            else:
                settings.dispatch = value
        return settings


def _kind(value: Any) -> str:
    if value is None:
        return "nothing"
    if isinstance(value, dict):
        return "a mapping"
    if isinstance(value, list):
        return "a list"
    return f"{type(value).__name__} {value!r}"[:80] + boolean_hint(value)


def _plain(value: Any) -> Any:
    """YMap/YList -> dict/list recursively (parameters are validated as plain values)."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_plain(v) for v in value]
    return value


class ShapeProblems(CheckFailed):
    """Shape problems, with the part of the graph that could still be read (``spec``), so the
    semantic checks can report their problems too."""

    def __init__(self, diagnostics: list[Diagnostic], spec: GraphSpec | None) -> None:
        super().__init__(diagnostics)
        self.spec = spec


def parse_graph_text(text: str | bytes, file: str) -> GraphSpec:
    """Parse graph text; raises ShapeProblems (a CheckFailed) listing every shape problem."""
    doc = load_located(text, file)
    as_text = text.decode("utf-8", "replace") if isinstance(text, bytes) else text
    parser = _Parser(file, as_text)
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
