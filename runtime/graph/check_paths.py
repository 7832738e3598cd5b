"""Paths through the graph's sound connections: every loop has a delayed connection (then the
modules' order), and every command path into an input that ``requires_guard`` passes a safety
guard."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from umbra.runtime.graph.check_report import Report
from umbra.runtime.graph.order import find_cycle, topological_order
from umbra.runtime.graph.plan import ModulePlan
from umbra.runtime.graph.spec import ConnectionSpec, GraphSpec


def check_loops(
    spec: GraphSpec,
    modules: Mapping[str, ModulePlan],
    connections: Sequence[ConnectionSpec],
    error: Report,
) -> list[str]:
    """The modules in the order a tick runs them; a loop without a delayed (``~>``) connection
    is reported (the order is then the graph's)."""
    names = [n for n in spec.modules if n in modules]
    edges: dict[str, list[str]] = {n: [] for n in names}
    by_pair: dict[tuple[str, str], ConnectionSpec] = {}
    for conn in connections:
        if not conn.delayed:
            edges[conn.src.module].append(conn.dst.module)
            by_pair[(conn.src.module, conn.dst.module)] = conn
    cycle = find_cycle(names, edges)
    if cycle is not None:
        last = by_pair[(cycle[-2], cycle[-1])]
        error(
            last.loc,
            f"loop {' -> '.join(cycle)} has no delayed connection",
            "write one of its connections with `~>` so it reads the previous tick",
        )
        return names
    return topological_order(names, edges)


#: What to do about a command path without a guard.
GUARD_HINT = "put a watchdog register (e.g. REG_VEL) on that path"


def command_feeding(
    spec: GraphSpec, modules: Mapping[str, ModulePlan], connections: Sequence[ConnectionSpec]
) -> tuple[dict[str, list[str]], set[str]]:
    """Which modules feed each module along command paths (feedback inputs carry no commands and
    are not followed), and the modules fed by one that could not be built (not judged)."""
    feeding: dict[str, list[str]] = {}
    for conn in connections:
        decl = modules[conn.dst.module].input_decls[conn.dst.port]
        if not decl.feedback:
            feeding.setdefault(conn.dst.module, []).append(conn.src.module)
    unknown = {c.dst.module for c in spec.connections if c.src.module not in modules}
    return feeding, unknown


def unguarded_chain(
    modules: Mapping[str, ModulePlan],
    start: str,
    end: str,
    feeding: dict[str, list[str]],
    unknown: set[str],
    target: str = "",
) -> str | None:
    """The command path ``... -> start -> end`` that passes no guard, as text (None when every
    path into ``start`` passes one; :func:`unguarded_path` says which paths count)."""
    path = unguarded_path(modules, start, target, feeding, unknown)
    if path is None:
        return None
    names = [*reversed(path), end]
    if len(names) > 12:  # a long chain: its ends and how many between
        names = [*names[:5], f"... {len(names) - 10} more ...", *names[-5:]]
    return " -> ".join(names)


def check_guards(
    spec: GraphSpec,
    modules: Mapping[str, ModulePlan],
    connections: Sequence[ConnectionSpec],
    error: Report,
) -> None:
    """Every command path into an input that ``requires_guard`` passes a safety guard (feedback
    inputs carry no commands and are not followed)."""
    feeding, unknown = command_feeding(spec, modules, connections)
    for conn in connections:
        decl = modules[conn.dst.module].input_decls[conn.dst.port]
        if not decl.requires_guard:
            continue
        chain = unguarded_chain(
            modules, conn.src.module, str(conn.dst), feeding, unknown, conn.dst.module
        )
        if chain is not None:
            error(
                conn.loc,
                f"`{conn.dst}` must be fed through a safety guard, but the "
                f"command path {chain} has none",
                GUARD_HINT,
            )


def unguarded_path(
    modules: Mapping[str, ModulePlan],
    start: str,
    target: str,
    feeding: dict[str, list[str]],
    unknown: set[str],
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
    if _ends_here(modules, start, unknown):
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
        if up in done or _ends_here(modules, up, unknown):
            continue
        upstream = list(feeding.get(up, []))
        if not upstream:
            return [m for m, _ in stack] + [up]
        stack.append((up, upstream))
        on_path.add(up)
    return None


def _ends_here(modules: Mapping[str, ModulePlan], module: str, unknown: set[str]) -> bool:
    """A path stops at a guard, and is not judged past a module that failed or its inputs."""
    plan = modules.get(module)
    return plan is None or module in unknown or plan.cls.SAFETY_GUARD
