"""Data order of modules, and loops that lack a delayed connection."""

from __future__ import annotations

from collections.abc import Iterable


def find_cycle(nodes: Iterable[str], edges: dict[str, list[str]]) -> list[str] | None:
    """One cycle ``[a, b, ..., a]`` in the directed graph, or None."""
    colour: dict[str, int] = {}
    parent: dict[str, str] = {}
    for root in nodes:
        if colour.get(root):
            continue
        stack = [(root, iter(edges.get(root, [])))]
        colour[root] = 1
        while stack:
            node, it = stack[-1]
            nxt = next(it, None)
            if nxt is None:
                colour[node] = 2
                stack.pop()
                continue
            state = colour.get(nxt, 0)
            if state == 0:
                colour[nxt] = 1
                parent[nxt] = node
                stack.append((nxt, iter(edges.get(nxt, []))))
            elif state == 1:
                cycle = [nxt, node]
                while cycle[-1] != nxt:
                    cycle.append(parent[cycle[-1]])
                cycle.reverse()
                return cycle
    return None


def topological_order(nodes: list[str], edges: dict[str, list[str]]) -> list[str]:
    """Kahn's algorithm, ties broken by declaration order (``nodes``); assumes no cycle."""
    indegree = {n: 0 for n in nodes}
    for src in nodes:
        for dst in edges.get(src, []):
            indegree[dst] += 1
    ready = [n for n in nodes if indegree[n] == 0]
    position = {n: i for i, n in enumerate(nodes)}
    out: list[str] = []
    while ready:
        ready.sort(key=position.__getitem__)
        node = ready.pop(0)
        out.append(node)
        for dst in edges.get(node, []):
            indegree[dst] -= 1
            if indegree[dst] == 0:
                ready.append(dst)
    return out
