"""Semantic checks of a graph: every problem at the YAML node at fault, all reported at once.

Beyond types, this holds contracts that other frameworks leave to run time: frames on
frame-bearing types, joint names on joint vectors, the largest sample age an input accepts, safety
guards on the command path to a joint driver, and the oldest sensor data a guard accepts
(``umbra.runtime.graph.origin_age``). This file reads a graph and runs the checks in their order;
each check has a file of its own: the module instances (``check_modules``), the static frames
(``check_frames``), the connections (``check_wiring``), loops and guards (``check_paths``), the
links between processes (``check_links``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from umbra.connectors.errors import CheckFailed, Diagnostic, Location, UserError
from umbra.connectors.user_files import OnCommandLine
from umbra.runtime.graph.check_frames import check_frames, static_frames
from umbra.runtime.graph.check_links import check_zenoh_config, plan_links
from umbra.runtime.graph.check_modules import module_plan
from umbra.runtime.graph.check_paths import check_guards, check_loops
from umbra.runtime.graph.check_ros2 import check_ros2
from umbra.runtime.graph.check_wiring import (
    check_connections,
    check_required_inputs,
    check_scheduling,
)
from umbra.runtime.graph.names import key_prefix_problem
from umbra.runtime.graph.origin_age import check_origin_ages
from umbra.runtime.graph.parse import ShapeProblems, parse_graph_file, parse_graph_text
from umbra.runtime.graph.plan import GraphPlan, ModulePlan
from umbra.runtime.graph.spec import GraphSpec
from umbra.runtime.hints import did_you_mean
from umbra.runtime.recording.settings import check_record_ports
from umbra.runtime.registry import Registry


def _check(spec: GraphSpec, registry: Registry) -> tuple[GraphPlan | None, list[Diagnostic]]:
    """Every check of ``spec``, in order: the plan (None when any problem was found) and the
    problems."""
    problems: list[Diagnostic] = []

    def error(loc: Location, message: str, hint: str = "") -> None:
        problems.append(Diagnostic(loc, message, hint))

    modules: dict[str, ModulePlan] = {}
    for mspec in spec.modules.values():
        checked = module_plan(mspec, registry, error)
        if checked is not None:
            modules[mspec.name] = checked
    frames = static_frames(spec, error)
    check_frames(modules, frames, error)
    connections = check_connections(spec, modules, error)
    check_required_inputs(spec, modules, error)
    check_scheduling(spec, modules, error)
    order = check_loops(spec, modules, connections, error)
    check_guards(spec, modules, connections, error)
    ros2 = check_ros2(spec, modules, connections, error)  # the ports mapped to ROS 2 topics
    if not problems:  # ages are followed along connections already found sound
        check_origin_ages(modules, connections, error, ros2.sources())
    check_zenoh_config(spec, error)
    outputs = {n: set(m.outputs) if (m := modules.get(n)) else None for n in spec.modules}
    check_record_ports(spec.record, outputs, error)
    if problems:
        return None, problems
    plan = GraphPlan(spec, modules, connections, order, frames)
    plan.links = plan_links(plan, connections)
    plan.ros2 = ros2.ports
    return plan, problems


def check_spec(
    spec: GraphSpec, registry: Registry | None = None, earlier: list[Diagnostic] | None = None
) -> GraphPlan:
    """Check a parsed graph; raises CheckFailed with every problem (``earlier`` ones first)."""
    plan, found = _check(spec, registry or Registry())
    problems = [*(earlier or []), *found]
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
    """Apply ``--set module.param=value`` overrides; UserError for an unknown module. Text
    values arrive as :class:`OnCommandLine`: a file the user names there may lie outside the
    run folder."""
    for module, values in overrides.items():
        if module not in spec.modules:
            raise UserError(f"--set: unknown module `{module}`{did_you_mean(module, spec.modules)}")
        spec.modules[module].params.update(
            {k: OnCommandLine(v) if isinstance(v, str) else v for k, v in values.items()}
        )
        for key in values:
            where = Location(f"--set {module}.{key}", 0, 0)
            spec.modules[module].param_val_loc[key] = where
            spec.modules[module].param_key_loc[key] = where
