"""``umbra graph GRAPH --format dot|mermaid``: draw a graph's modules and connections."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # annotations only: `umbra --help` loads this file without them
    from umbra.runtime.graph.plan import GraphPlan

NAME = "graph"
HELP = "print a graph as Graphviz dot or Mermaid"
GUIDE = "docs/guide/graphs.md"  # the guide page this command's --help points to


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("graph", metavar="GRAPH")
    parser.add_argument("--format", choices=("dot", "mermaid"), default="dot")


def to_dot(plan: GraphPlan) -> str:
    lines = [f'digraph "{plan.spec.name}" {{', "  rankdir=LR;", "  node [shape=box];"]
    for process in plan.processes:
        lines.append(f'  subgraph "cluster_{process}" {{ label="{process}";')
        for name in plan.modules_in(process):
            lines.append(f'    "{name}" [label="{name}\\n{plan.modules[name].spec.type}"];')
        lines.append("  }")
    links = {id(link.connection) for link in plan.links}
    for c in plan.connections:
        style = []
        if c.delayed:
            style.append("style=dashed")
        if id(c) in links:
            style.append("color=blue")
        attrs = f", {', '.join(style)}" if style else ""
        lines.append(
            f'  "{c.src.module}" -> "{c.dst.module}" [label="{c.src.port} → {c.dst.port}"{attrs}];'
        )
    lines.append("}")
    return "\n".join(lines)


def to_mermaid(plan: GraphPlan) -> str:
    lines = ["flowchart LR"]
    for process in plan.processes:
        lines.append(f"  subgraph {process}")
        for name in plan.modules_in(process):
            lines.append(f'    {name}["{name}<br/>{plan.modules[name].spec.type}"]')
        lines.append("  end")
    for c in plan.connections:
        arrow = "-.->" if c.delayed else "-->"
        lines.append(f"  {c.src.module} {arrow}|{c.src.port} → {c.dst.port}| {c.dst.module}")
    return "\n".join(lines)


def main(args: argparse.Namespace) -> int:
    from umbra.runtime.graph.check import load_graph

    plan = load_graph(args.graph)
    print(to_dot(plan) if args.format == "dot" else to_mermaid(plan))
    return 0
