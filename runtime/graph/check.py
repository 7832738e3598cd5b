"""Semantic checks of a graph: every problem at the YAML node at fault, all reported at once.

Beyond types, this holds contracts that other frameworks leave to run time: frames on
frame-bearing types, joint names on joint vectors, the largest sample age an input accepts, safety
guards on the command path to a joint driver, and the oldest sensor data a guard accepts
(``umbra.runtime.graph.origin_age``).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pydantic

from umbra.connectors.errors import CheckFailed, Diagnostic, Location, UserError
from umbra.connectors.frames import FrameTree
from umbra.connectors.params import ParamProblem
from umbra.connectors.ports import Input
from umbra.runtime.graph.names import key_prefix_problem
from umbra.runtime.graph.order import find_cycle, topological_order
from umbra.runtime.graph.origin_age import check_origin_ages
from umbra.runtime.graph.parse import ShapeProblems, parse_graph_file, parse_graph_text
from umbra.runtime.graph.plan import GraphPlan, LinkPlan, ModulePlan, PortInfo
from umbra.runtime.graph.spec import ConnectionSpec, GraphSpec, ModuleSpec
from umbra.runtime.hints import did_you_mean
from umbra.runtime.recording.settings import check_record_ports
from umbra.runtime.registry import Registry

#: Frames every graph knows without declaring them.
WELL_KNOWN_FRAMES = ("base", "world", "lab", "tool", "flange", "camera")


class _Checker:
    def __init__(self, spec: GraphSpec, registry: Registry) -> None:
        self.spec = spec
        self.registry = registry
        self.problems: list[Diagnostic] = []
        self.modules: dict[str, ModulePlan] = {}
        self.connections: list[ConnectionSpec] = []

    def error(self, loc: Location, message: str, hint: str = "") -> None:
        self.problems.append(Diagnostic(loc, message, hint))

    def run(self) -> GraphPlan | None:
        for mspec in self.spec.modules.values():
            plan = self.module(mspec)
            if plan is not None:
                self.modules[mspec.name] = plan
        frames = self.static_frames()
        self.check_frames(frames)
        self.check_connections()
        self.check_required_inputs()
        self.check_scheduling()
        order = self.check_loops()
        self.check_guards()
        if not self.problems:  # ages are followed along connections already found sound
            check_origin_ages(self.modules, self.connections, self.error)
        self.check_zenoh_config()
        outputs = {
            n: set(m.outputs) if (m := self.modules.get(n)) else None for n in self.spec.modules
        }
        check_record_ports(self.spec.record, outputs, self.error)
        if self.problems:
            return None
        plan = GraphPlan(self.spec, self.modules, self.connections, order, frames)
        plan.links = self.links(plan)
        return plan

    # -- modules --------------------------------------------------------------------------------
    def module(self, mspec: ModuleSpec) -> ModulePlan | None:
        cls = self.registry.get(mspec.type)
        if cls is None:
            self.error(mspec.type_loc, self.registry.missing(mspec.type))
            return None
        params = self.params(mspec, cls.Params)
        if params is None:
            return None
        problem = params.rate_problem(mspec.rate)
        if problem:
            self.error(
                mspec.rate_loc or mspec.loc, f"module `{mspec.name}` ({mspec.type}): {problem}"
            )
        in_decls = cls.input_decls(params)
        inputs = _port_infos(in_decls, params)
        outputs = _port_infos(cls.output_decls(), params)
        triggers = [n for n, d in in_decls.items() if d.trigger]
        if mspec.trigger is not None:
            triggers = []
            for name in mspec.trigger:
                if name not in inputs:
                    self.error(
                        mspec.trigger_loc,
                        f"`trigger` names `{name}`, which is not an input "
                        f"of `{mspec.name}` ({mspec.type})"
                        f"{did_you_mean(name, inputs)}",
                    )
                else:
                    triggers.append(name)
        return ModulePlan(mspec, cls, params, inputs, outputs, triggers, in_decls)

    def params(self, mspec: ModuleSpec, params_cls: type) -> Any:
        try:
            return params_cls(**mspec.params)
        except pydantic.ValidationError as exc:
            fields = list(params_cls.model_fields)
            for err in exc.errors():
                loc = err.get("loc") or ()
                key = str(loc[0]) if loc else ""
                if err["type"] == "extra_forbidden":
                    self.error(
                        mspec.param_key_loc.get(key, mspec.params_loc),
                        f"unknown parameter `{key}` for {mspec.type} `{mspec.name}`"
                        f"{did_you_mean(key, fields)}",
                    )
                elif err["type"] == "missing":
                    self.error(
                        mspec.params_loc, f"{mspec.type} `{mspec.name}` needs parameter `{key}`"
                    )
                elif not loc and isinstance(_cause(err), ParamProblem):
                    field = _cause(err).field
                    self.error(
                        mspec.param_val_loc.get(field, mspec.params_loc),
                        f"parameters of `{mspec.name}`: {_cause(err)}",
                    )
                elif err["type"] == "value_error" and _cause(err) is not None:
                    where = ".".join(str(p) for p in loc)  # a validator's own message
                    self.error(
                        mspec.param_val_loc.get(key, mspec.params_loc),
                        f"parameter `{where}` of `{mspec.name}`: {_cause(err)}",
                    )
                else:
                    where = ".".join(str(p) for p in loc)
                    self.error(
                        mspec.param_val_loc.get(key, mspec.params_loc),
                        f"parameter `{where}` of `{mspec.name}`: {err['msg']}, "
                        f"found {_short(err.get('input'))}",
                    )
            return None
        except (TypeError, ValueError) as exc:  # a module's own validator
            self.error(mspec.params_loc, f"parameters of `{mspec.name}`: {exc}")
            return None

    # -- frames ---------------------------------------------------------------------------------
    def static_frames(self) -> FrameTree:
        tree = FrameTree()
        seen: dict[tuple[str, str], Location] = {}
        for f in self.spec.frames:
            pair = (f.parent, f.child)
            if pair in seen or (f.child, f.parent) in seen:
                self.error(f.loc, f"frame `{f.parent}->{f.child}` declared twice")
                continue
            if tree.has(f.parent, f.child):
                self.error(f.loc, f"frame `{f.parent}->{f.child}` closes a loop of static frames")
                continue
            seen[pair] = f.loc
            tree.add(f.parent, f.child, f.T_parent_child)
        return tree

    def check_frames(self, tree: FrameTree) -> None:
        for plan in self.modules.values():
            missing = [f"{a}->{b}" for a, b in plan.params.required_frames() if not tree.has(a, b)]
            if missing:
                self.error(
                    plan.spec.loc,
                    f"module `{plan.name}` ({plan.spec.type}) needs the static frame(s) "
                    f"{', '.join(missing)}, which the graph's `frames:` do not join",
                    "declare them under `frames:` as `parent->child`",
                )
        known = set(WELL_KNOWN_FRAMES) | tree.names
        for plan in self.modules.values():
            for decl in [*plan.input_decls.values(), *plan.cls.output_decls().values()]:
                if isinstance(decl.frame, str):
                    known.add(decl.frame)
                    known.update(decl.frame.split("->"))
        for plan in self.modules.values():
            for key, value in plan.spec.params.items():
                if not (key == "frame" or key.endswith("_frame")) or not isinstance(value, str):
                    continue
                if value and value not in known:
                    self.error(
                        plan.spec.param_val_loc.get(key, plan.spec.params_loc),
                        f"unknown frame `{value}` in parameter `{key}` of `{plan.name}`"
                        f"{did_you_mean(value, sorted(known))}",
                        "declare it under `frames:` as `parent->child`",
                    )

    # -- connections ----------------------------------------------------------------------------
    def check_connections(self) -> None:
        producers: dict[tuple[str, str], ConnectionSpec] = {}
        for conn in self.spec.connections:
            src = self.port(conn.src, "output")
            dst = self.port(conn.dst, "input")
            if src is None or dst is None:
                continue
            key = (conn.dst.module, conn.dst.port)
            if key in producers:
                first = producers[key]
                self.error(
                    conn.dst.module_loc,
                    f"input `{conn.dst}` has two producers: "
                    f"`{first.src}` (line {first.loc.line}) and "
                    f"`{conn.src}`",
                )
                continue
            producers[key] = conn
            if not issubclass(src.msg_type, dst.msg_type):
                self.error(
                    conn.src.port_loc,
                    f"type mismatch: `{conn.src}` sends "
                    f"{src.msg_type.__name__}, `{conn.dst}` expects "
                    f"{dst.msg_type.__name__}",
                )
                continue
            kind = src.msg_type.FRAME_KIND
            if kind and dst.frame is not None and src.frame != dst.frame:
                found = src.frame or "no frame"
                self.error(
                    conn.src.port_loc,
                    f"frame mismatch: `{conn.src}` is a "
                    f"{src.msg_type.__name__} in `{found}`, `{conn.dst}` "
                    f"wants `{dst.frame}`",
                    "transform it first (e.g. ROTATE_KIN) or fix the frame parameter",
                )
                continue
            if (
                src.msg_type.HAS_JOINTS
                and src.joints is not None
                and dst.joints is not None
                and src.joints != dst.joints
            ):
                self.error(
                    conn.src.port_loc,
                    f"joint mismatch: `{conn.src}` carries joints "
                    f"{list(src.joints)}, `{conn.dst}` expects "
                    f"{list(dst.joints)}",
                )
                continue
            self.check_max_age(conn)
            self.connections.append(conn)

    def port(self, end: Any, kind: str) -> PortInfo | None:
        plan = self.modules.get(end.module)
        if plan is None:
            if end.module not in self.spec.modules and end.module not in self.spec.broken_modules:
                self.error(
                    end.module_loc,
                    f"unknown module `{end.module}`{did_you_mean(end.module, self.spec.modules)}",
                )
            return None
        ports = plan.outputs if kind == "output" else plan.inputs
        if end.port in ports:
            return ports[end.port]
        other = plan.inputs if kind == "output" else plan.outputs
        if end.port in other:
            self.error(
                end.port_loc,
                f"`{end}` is an {'input' if kind == 'output' else 'output'}; "
                f"a connection goes from an output to an input",
            )
        else:
            self.error(
                end.port_loc,
                f"{plan.spec.type} `{end.module}` has no {kind} `{end.port}`"
                f"{did_you_mean(end.port, ports)}",
            )
        return None

    def check_max_age(self, conn: ConnectionSpec) -> None:
        decl: Input = self.modules[conn.dst.module].input_decls[conn.dst.port]
        rate = self.modules[conn.src.module].spec.rate
        if decl.max_age is not None and rate is not None and 1.0 / rate > decl.max_age:
            self.error(
                conn.src.module_loc,
                f"`{conn.dst}` accepts samples up to {decl.max_age} s "
                f"old, but `{conn.src.module}` runs at {rate:g} Hz "
                f"(every {1.0 / rate:g} s)",
            )

    def check_required_inputs(self) -> None:
        # inputs of connections that failed a check are not reported again as unconnected
        attempted = {(c.dst.module, c.dst.port) for c in self.spec.connections}
        for plan in self.modules.values():
            for name, decl in plan.input_decls.items():
                if decl.required and (plan.name, name) not in attempted:
                    self.error(
                        plan.spec.loc,
                        f"required input `{plan.name}.{name}` "
                        f"({decl.msg_type.__name__}) is not connected",
                    )

    def check_scheduling(self) -> None:
        connected = {(c.dst.module, c.dst.port) for c in self.spec.connections}
        for plan in self.modules.values():
            if plan.spec.rate is not None or plan.spec.rate_loc is not None:
                continue  # a rate, or a bad one (reported when the graph was read)
            live = [t for t in plan.triggers if (plan.name, t) in connected]
            reported = any(plan.input_decls[t].required for t in plan.triggers if t not in live)
            if not live and not reported:
                self.error(
                    plan.spec.loc,
                    f"module `{plan.name}` needs `rate: HZ` or a connected trigger input",
                )

    def check_loops(self) -> list[str]:
        names = [n for n in self.spec.modules if n in self.modules]
        edges: dict[str, list[str]] = {n: [] for n in names}
        by_pair: dict[tuple[str, str], ConnectionSpec] = {}
        for conn in self.connections:
            if not conn.delayed:
                edges[conn.src.module].append(conn.dst.module)
                by_pair[(conn.src.module, conn.dst.module)] = conn
        cycle = find_cycle(names, edges)
        if cycle is not None:
            last = by_pair[(cycle[-2], cycle[-1])]
            self.error(
                last.loc,
                f"loop {' -> '.join(cycle)} has no delayed connection",
                "write one of its connections with `~>` so it reads the previous tick",
            )
            return names
        return topological_order(names, edges)

    def check_guards(self) -> None:
        feeding: dict[str, list[str]] = {}
        for conn in self.connections:
            decl = self.modules[conn.dst.module].input_decls[conn.dst.port]
            if not decl.feedback:
                feeding.setdefault(conn.dst.module, []).append(conn.src.module)
        unknown = {c.dst.module for c in self.spec.connections if c.src.module not in self.modules}
        for conn in self.connections:
            decl = self.modules[conn.dst.module].input_decls[conn.dst.port]
            if not decl.requires_guard:
                continue
            path = self.unguarded_path(conn.src.module, conn.dst.module, feeding, unknown)
            if path is not None:
                names = [*reversed(path), str(conn.dst)]
                if len(names) > 12:  # a long chain: its ends and how many between
                    names = [*names[:5], f"... {len(names) - 10} more ...", *names[-5:]]
                chain = " -> ".join(names)
                self.error(
                    conn.loc,
                    f"`{conn.dst}` must be fed through a safety guard, but the "
                    f"command path {chain} has none",
                    "put a watchdog register (e.g. REG_VEL) on that path",
                )

    def unguarded_path(
        self, start: str, target: str, feeding: dict[str, list[str]], unknown: set[str]
    ) -> list[str] | None:
        """A command path into ``target`` from ``start`` upstream that passes no guard (``start``
        first), or None when every path passes one. A path ends unguarded at a module nothing
        feeds, or when it closes a loop (back to a module on it, or to ``target``): a loop with
        no guard on it keeps a command alive with no producer behind it. Paths through a module
        that could not be built, or fed by one, are not judged (that failure is reported
        already). Depth-first without recursion and visiting each module once, so a chain of
        thousands of modules or a lattice of many paths is checked in linear time."""
        done: set[str] = set()
        stack: list[tuple[str, list[str]]] = [(start, list(feeding.get(start, [])))]
        on_path = {start}
        if self._ends_here(start, unknown):
            return None
        if not stack[0][1]:
            return [start]
        while stack:
            module, pending = stack[-1]
            if not pending:
                stack.pop()
                on_path.discard(module)
                done.add(module)
                continue
            up = pending.pop()
            if up in on_path or up == target:
                return [m for m, _ in stack] + [up]
            if up in done or self._ends_here(up, unknown):
                continue
            upstream = list(feeding.get(up, []))
            if not upstream:
                return [m for m, _ in stack] + [up]
            stack.append((up, upstream))
            on_path.add(up)
        return None

    def _ends_here(self, module: str, unknown: set[str]) -> bool:
        """A path stops at a guard, and is not judged past a module that failed or its inputs."""
        plan = self.modules.get(module)
        return plan is None or module in unknown or plan.cls.SAFETY_GUARD

    # -- links ----------------------------------------------------------------------------------
    def check_zenoh_config(self) -> None:
        """``links.zenoh_config`` (relative to the graph file) is a zenoh configuration file, or
        a folder written by ``umbra keys`` with one for every process: ``run`` would refuse it
        only once the processes start."""
        links = self.spec.links
        if not links.zenoh_config:
            return
        from umbra.runtime.links.config import check_config_file
        from umbra.runtime.links.exposure import config_for

        path = Path(links.zenoh_config)
        if not path.is_absolute():
            path = Path(self.spec.file).parent / path
        loc = links.zenoh_config_loc or links.loc or Location(self.spec.file, 1, 1)
        processes = sorted({m.process for m in self.spec.modules.values()})
        try:
            for process in processes:
                check_config_file(config_for(str(path), process))
        except UserError as exc:
            where, _, reason = str(exc).partition(": error: ")
            self.error(loc, f"`links.zenoh_config`: {where}: {reason or where}")

    def links(self, plan: GraphPlan) -> list[LinkPlan]:
        out = []
        for conn in self.connections:
            if plan.modules[conn.src.module].process == plan.modules[conn.dst.module].process:
                continue
            producer = plan.modules[conn.src.module]
            msg_type = producer.outputs[conn.src.port].msg_type
            events = producer.cls.output_decls()[conn.src.port].events
            key = f"{plan.key_prefix}/{conn.src.module}/{conn.src.port}"
            out.append(LinkPlan(conn, key, msg_type, events))
        return out


def check_spec(
    spec: GraphSpec, registry: Registry | None = None, earlier: list[Diagnostic] | None = None
) -> GraphPlan:
    """Check a parsed graph; raises CheckFailed with every problem (``earlier`` ones first)."""
    checker = _Checker(spec, registry or Registry())
    plan = checker.run()
    problems = [*(earlier or []), *checker.problems]
    if plan is None or problems:
        raise CheckFailed(problems)
    return plan


def check_text(text: str | bytes, file: str, registry: Registry | None = None) -> GraphPlan:
    """Parse and check graph text, reporting shape and semantic problems together."""
    spec, earlier = _read(lambda: parse_graph_text(text, file))
    return check_spec(spec, registry, earlier)


def load_graph(
    path: str,
    registry: Registry | None = None,
    overrides: dict[str, dict[str, Any]] | None = None,
    prefix: str | None = None,
) -> GraphPlan:
    """Parse and check a graph file, with ``--set`` overrides ``{module: {param: value}}`` and a
    ``--prefix`` replacing the zenoh key prefix of ``links:`` (when given)."""
    if prefix and key_prefix_problem(prefix):
        raise UserError(f"--prefix: error: {key_prefix_problem(prefix)}")
    spec, earlier = _read(lambda: parse_graph_file(path))
    apply_overrides(spec, overrides or {})
    if prefix:
        spec.links.prefix = prefix
    return check_spec(spec, registry, earlier)


def _read(parse: Callable[[], GraphSpec]) -> tuple[GraphSpec, list[Diagnostic]]:
    """The parsed graph and its shape problems: semantic checks still run on the part that could
    be read, so that every problem is reported at once. Re-raises when nothing could be read."""
    try:
        return parse(), []
    except ShapeProblems as exc:
        if exc.spec is None:
            raise
        return exc.spec, exc.diagnostics


def apply_overrides(spec: GraphSpec, overrides: dict[str, dict[str, Any]]) -> None:
    """Apply ``--set module.param=value`` overrides; UserError for an unknown module."""
    for module, values in overrides.items():
        if module not in spec.modules:
            raise UserError(f"--set: unknown module `{module}`{did_you_mean(module, spec.modules)}")
        spec.modules[module].params.update(values)
        for key in values:
            where = Location(f"--set {module}.{key}", 0, 0)
            spec.modules[module].param_val_loc[key] = where
            spec.modules[module].param_key_loc[key] = where


def _cause(err: Any) -> BaseException | None:
    """The exception a validator raised, kept by pydantic in the error's context."""
    ctx = err.get("ctx") or {}
    return ctx.get("error") if isinstance(ctx.get("error"), BaseException) else None


def _short(value: Any) -> str:
    """``repr(value)`` cut to 120 characters (a 5000-digit number is not printed whole)."""
    try:
        text = repr(value)
    except ValueError:  # an int too long for repr
        return "a number too long to print"
    return text if len(text) <= 120 else text[:117] + "..."


def _port_infos(decls: dict[str, Any], params: Any) -> dict[str, PortInfo]:
    """Declared ports with their frame and joint names resolved from ``params``."""
    return {
        name: PortInfo(name, d.msg_type, d.resolve_frame(params), d.resolve_joints(params))
        for name, d in decls.items()
    }
