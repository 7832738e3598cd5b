"""The graph's connections: each from an existing output to an existing input, one producer per
input, matching message types, frames and joint names, samples young enough for the input's
``max_age``; every required input connected, and every module scheduled (a rate or a connected
trigger)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from umbra.connectors.ports import Input
from umbra.runtime.graph.check_report import Report
from umbra.runtime.graph.plan import ModulePlan, PortInfo
from umbra.runtime.graph.spec import ConnectionSpec, GraphSpec
from umbra.runtime.hints import did_you_mean


def check_connections(
    spec: GraphSpec, modules: Mapping[str, ModulePlan], error: Report
) -> list[ConnectionSpec]:
    """The connections found sound, each other one reported (once, at its first fault)."""
    sound: list[ConnectionSpec] = []
    producers: dict[tuple[str, str], ConnectionSpec] = {}
    for conn in spec.connections:
        src = _port(spec, modules, conn.src, "output", error)
        dst = _port(spec, modules, conn.dst, "input", error)
        if src is None or dst is None:
            continue
        key = (conn.dst.module, conn.dst.port)
        if key in producers:
            first = producers[key]
            error(
                conn.dst.module_loc,
                f"input `{conn.dst}` has two producers: "
                f"`{first.src}` (line {first.loc.line}) and "
                f"`{conn.src}`",
            )
            continue
        producers[key] = conn
        if not issubclass(src.msg_type, dst.msg_type):
            error(
                conn.src.port_loc,
                f"type mismatch: `{conn.src}` sends "
                f"{src.msg_type.__name__}, `{conn.dst}` expects "
                f"{dst.msg_type.__name__}",
            )
            continue
        kind = src.msg_type.FRAME_KIND
        if kind and dst.frame is not None and src.frame != dst.frame:
            found = src.frame or "no frame"
            error(
                conn.src.port_loc,
                f"frame mismatch: `{conn.src}` is a "
                f"{src.msg_type.__name__} in `{found}`, `{conn.dst}` "
                f"wants `{dst.frame}`",
                "transform it first (e.g. ROTATE_KIN) or fix the frame parameter",
            )
            continue
        mismatch = joint_mismatch(
            src.msg_type.HAS_JOINTS, src.joints, dst.joints, f"`{conn.src}`", f"`{conn.dst}`"
        )
        if mismatch:
            error(conn.src.port_loc, mismatch)
            continue
        _check_max_age(modules, conn, error)
        sound.append(conn)
    return sound


def joint_mismatch(
    has_joints: bool,
    carried: tuple[str, ...] | None,
    expected: tuple[str, ...] | None,
    source: str,
    dest: str,
) -> str:
    """Why ``source``'s joints ``carried`` cannot feed ``dest``, an input that declares
    ``expected`` (empty: they can, or either side declares none): the rule for a connection and
    for a ROS 2 topic's joint state (``check_ros2``)."""
    if not has_joints or carried is None or expected is None or tuple(carried) == tuple(expected):
        return ""
    return (
        f"joint mismatch: {source} carries joints {list(carried)}, {dest} expects {list(expected)}"
    )


def _port(
    spec: GraphSpec, modules: Mapping[str, ModulePlan], end: Any, kind: str, error: Report
) -> PortInfo | None:
    """The port ``end`` names (``kind``: "output" or "input"), or None, reported unless its
    module could not be built (reported already)."""
    plan = modules.get(end.module)
    if plan is None:
        if end.module not in spec.modules and end.module not in spec.broken_modules:
            error(
                end.module_loc,
                f"unknown module `{end.module}`{did_you_mean(end.module, spec.modules)}",
            )
        return None
    ports = plan.outputs if kind == "output" else plan.inputs
    if end.port in ports:
        return ports[end.port]
    other = plan.inputs if kind == "output" else plan.outputs
    if end.port in other:
        error(
            end.port_loc,
            f"`{end}` is an {'input' if kind == 'output' else 'output'}; "
            f"a connection goes from an output to an input",
        )
    else:
        error(
            end.port_loc,
            f"{plan.spec.type} `{end.module}` has no {kind} `{end.port}`"
            f"{did_you_mean(end.port, ports)}",
        )
    return None


def _check_max_age(modules: Mapping[str, ModulePlan], conn: ConnectionSpec, error: Report) -> None:
    """The producer's period [s] fits within the input's ``max_age`` [s]."""
    decl: Input = modules[conn.dst.module].input_decls[conn.dst.port]
    rate = modules[conn.src.module].spec.rate
    if decl.max_age is not None and rate is not None and 1.0 / rate > decl.max_age:
        error(
            conn.src.module_loc,
            f"`{conn.dst}` accepts samples up to {decl.max_age} s "
            f"old, but `{conn.src.module}` runs at {rate:g} Hz "
            f"(every {1.0 / rate:g} s)",
        )


def check_required_inputs(
    spec: GraphSpec, modules: Mapping[str, ModulePlan], error: Report
) -> None:
    """Every required input has a connection or is fed from ROS 2 (inputs of connections that
    failed a check are not reported again as unconnected)."""
    attempted = {(c.dst.module, c.dst.port) for c in spec.connections} | spec.ros2.fed_inputs()
    for plan in modules.values():
        for name, decl in plan.input_decls.items():
            if decl.required and (plan.name, name) not in attempted:
                error(
                    plan.spec.loc,
                    f"required input `{plan.name}.{name}` "
                    f"({decl.msg_type.__name__}) is not connected",
                )


def check_scheduling(spec: GraphSpec, modules: Mapping[str, ModulePlan], error: Report) -> None:
    """Every module runs: at a rate, or on a connected trigger input."""
    connected = {(c.dst.module, c.dst.port) for c in spec.connections} | spec.ros2.fed_inputs()
    for plan in modules.values():
        if plan.spec.rate is not None or plan.spec.rate_loc is not None:
            continue  # a rate, or a bad one (reported when the graph was read)
        live = [t for t in plan.triggers if (plan.name, t) in connected]
        reported = any(plan.input_decls[t].required for t in plan.triggers if t not in live)
        if not live and not reported:
            error(
                plan.spec.loc,
                f"module `{plan.name}` needs `rate: HZ` or a connected trigger input",
            )
