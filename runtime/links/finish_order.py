"""Which input streams a finishing process waits for.

When one process of a split run ends normally, the launcher tells every other process to
``finish``: run on until its input streams have ended, so that the last samples in flight are
handled. Processes that feed each other (the vision process sends images to the console's
process, which sends seeds back) would each wait for the other's streams to end, and neither
ends before it stops. So a finishing process waits only for producers *upstream* of it: those
outside its own strongly connected component of the graph's process-level data flow. Those
finish without waiting for it, so the wait always ends, and a chain (``A -> B -> C``) still
hands its last samples down. The streams of the process whose end caused the finish are waited
for even when it is a mutual peer: it has ended, so they end too, and what it sent last (the
judge's verdict, say) reaches the modules before they stop.
"""

from __future__ import annotations

from collections.abc import Iterable

from umbra.runtime.graph.plan import GraphPlan


def process_edges(plan: GraphPlan) -> set[tuple[str, str]]:
    """(producer, consumer) pairs of processes joined by at least one link."""
    return {
        (
            plan.modules[link.connection.src.module].process,
            plan.modules[link.connection.dst.module].process,
        )
        for link in plan.links
    }


def reachable(edges: Iterable[tuple[str, str]], start: str) -> set[str]:
    """Every process that data from ``start`` reaches (``start`` included)."""
    onward: dict[str, set[str]] = {}
    for src, dst in edges:
        onward.setdefault(src, set()).add(dst)
    seen, todo = {start}, [start]
    while todo:
        for nxt in onward.get(todo.pop(), ()):
            if nxt not in seen:
                seen.add(nxt)
                todo.append(nxt)
    return seen


def mutual_peers(plan: GraphPlan, process: str) -> frozenset[str]:
    """The other processes that both feed ``process`` and are fed by it, directly or through
    others (its strongly connected component): a finishing ``process`` does not wait for their
    streams to end."""
    edges = process_edges(plan)
    downstream = reachable(edges, process)
    upstream = reachable(((dst, src) for src, dst in edges), process)
    return frozenset((downstream & upstream) - {process})
