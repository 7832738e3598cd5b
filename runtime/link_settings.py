"""Where a process's link settings come from: the command line, the graph's ``links:``, a zenoh
configuration file (``umbra run`` and ``umbra run --process``, one rule for both)."""

from __future__ import annotations

import argparse
from pathlib import Path

from umbra.runtime.graph.plan import GraphPlan
from umbra.runtime.links.config import check_endpoint


def zenoh_config_file(plan: GraphPlan, args: argparse.Namespace) -> str | None:
    """The zenoh configuration of the run: ``--zenoh-config``, else the graph's (relative to
    the graph file), else None."""
    if getattr(args, "zenoh_config", None):
        return str(args.zenoh_config)
    if plan.spec.links.zenoh_config:
        path = Path(plan.spec.links.zenoh_config)
        if not path.is_absolute():  # relative to the graph file
            path = Path(plan.spec.file).parent / path
        return str(path)
    return None


def graph_links_origin(plan: GraphPlan) -> str:
    """``FILE:LINE`` of the graph's ``links:`` section (where its endpoints come from)."""
    loc = plan.spec.links.loc
    return f"{loc.file}:{loc.line}" if loc is not None else str(plan.spec.file)


def checked_endpoints(values: list[str], where: str) -> list[str]:
    """``values`` as endpoints, each checked (UserError naming ``where``)."""
    return [check_endpoint(v, where) for v in values]
