"""The links between processes: the zenoh configuration ``links.zenoh_config`` names, checked
before any process starts, and the connections that cross processes (one zenoh key each)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from umbra.connectors.errors import Location, UserError
from umbra.runtime.graph.check_report import Report
from umbra.runtime.graph.plan import GraphPlan, LinkPlan
from umbra.runtime.graph.spec import ConnectionSpec, GraphSpec


def check_zenoh_config(spec: GraphSpec, error: Report) -> None:
    """``links.zenoh_config`` (relative to the graph file) is a zenoh configuration file, or
    a folder written by ``umbra keys`` with one for every process: ``run`` would refuse it
    only once the processes start."""
    links = spec.links
    if not links.zenoh_config:
        return
    from umbra.runtime.links.config import check_config_file
    from umbra.runtime.links.exposure import config_for

    path = Path(links.zenoh_config)
    if not path.is_absolute():
        path = Path(spec.file).parent / path
    loc = links.zenoh_config_loc or links.loc or Location(spec.file, 1, 1)
    processes = sorted({m.process for m in spec.modules.values()})
    try:
        for process in processes:
            check_config_file(config_for(str(path), process))
    except UserError as exc:
        where, _, reason = str(exc).partition(": error: ")
        error(loc, f"`links.zenoh_config`: {where}: {reason or where}")


def plan_links(plan: GraphPlan, connections: Sequence[ConnectionSpec]) -> list[LinkPlan]:
    """The connections between modules of different processes, each with its zenoh key."""
    out = []
    for conn in connections:
        if plan.modules[conn.src.module].process == plan.modules[conn.dst.module].process:
            continue
        producer = plan.modules[conn.src.module]
        msg_type = producer.outputs[conn.src.port].msg_type
        events = producer.cls.output_decls()[conn.src.port].events
        key = f"{plan.key_prefix}/{conn.src.module}/{conn.src.port}"
        out.append(LinkPlan(conn, key, msg_type, events))
    return out
