"""``umbra check GRAPH...``: report every problem of each graph, and what becomes a zenoh link."""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

from umbra.connectors.errors import CheckFailed

if TYPE_CHECKING:  # annotations only: `umbra --help` loads this file without them
    from umbra.runtime.graph.spec import GraphSpec

NAME = "check"
HELP = "check graph files: report every problem as FILE:LINE:COL, list links"
GUIDE = "docs/guide/graphs.md"  # the guide page this command's --help points to


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("graphs", nargs="+", metavar="GRAPH", help="graph files (.yaml)")
    parser.add_argument("-q", "--quiet", action="store_true", help="print only problems")


def main(args: argparse.Namespace) -> int:
    from umbra.runtime.graph.check import load_graph
    from umbra.runtime.graph.check_ros2 import Ros2Check
    from umbra.runtime.graph.origin_age import bounded_inputs
    from umbra.runtime.registry import Registry

    registry = Registry()
    failed = False
    for path in args.graphs:
        try:
            plan = load_graph(path, registry)
        except CheckFailed as exc:
            failed = True
            print(str(exc), file=sys.stderr)
            continue
        if args.quiet:
            continue
        processes = [_process_text(p, plan.spec) for p in plan.processes]
        print(
            f"{path}: ok: graph `{plan.spec.name}`, {len(plan.modules)} modules, "
            f"{len(plan.connections)} connections, processes: {', '.join(processes)}"
        )
        outside = Ros2Check(plan.ros2).sources()
        for item in bounded_inputs(plan.modules, plan.connections, outside):
            print(
                f"  origin age at `{item.connection.dst}`: at least {item.worst.age * 1e3:.0f} ms "
                f"of {item.bound * 1e3:.0f} ms allowed ({item.worst.text()})"
            )
        for link in plan.links:
            print(
                f"  link {link.connection} ({link.msg_type.__name__}, {link.policy}): "
                f"key `{link.key}`"
            )
        for port in plan.ros2:
            m = port.mapping
            way = "->" if m.direction.value == "out" else "<-"
            print(f"  ros2 {port} {way} {m.topic} ({m.ros_type}), process `{port.process}`")
    return 2 if failed else 0


def _process_text(name: str, spec: GraphSpec) -> str:
    """A process and the real-time settings the graph asks for it."""
    asks = [
        f"{key} {values[name]}"
        for key, values in (
            ("cpu_latency_us", spec.cpu_latency_us),
            ("realtime_priority", spec.realtime_priority),
            ("nice", spec.nice),
        )
        if name in values
    ]
    return f"{name} ({', '.join(asks)})" if asks else name
