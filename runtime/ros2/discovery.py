"""The ROS 2 graph of a domain as its liveliness tokens tell it: topics with their types,
publishers and subscriptions (``umbra topics`` beside our own links).

Every rmw_zenoh node keeps a token per node and per endpoint alive under
``@ros2_lv/<domain>/…`` (:mod:`umbra.runtime.ros2.keys`); one liveliness query gathers those alive
now. A token that does not parse is counted and left out, never guessed at.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass

import zenoh

from umbra.runtime.ros2.keys import Entity, EntityKind, parse_token, tokens_of_domain

#: How long a query for tokens waits for answers [s].
QUERY_TIMEOUT_S = 1.0


@dataclass(frozen=True)
class Ros2Topic:
    """One topic of a domain: its ``name``, the message ``types`` its endpoints declare (more than
    one is a mismatch ROS 2 tools also show), and the fully qualified names of the nodes that
    publish and subscribe to it."""

    name: str
    types: tuple[str, ...]
    publishers: tuple[str, ...]
    subscribers: tuple[str, ...]


@dataclass(frozen=True)
class Ros2Graph:
    """What the tokens of a domain say: ``entities`` parsed, ``unparsed`` tokens left out."""

    entities: tuple[Entity, ...]
    unparsed: int

    def nodes(self) -> list[str]:
        """Fully qualified names of the nodes alive, sorted."""
        return sorted({e.node_fqn for e in self.entities if e.kind is EntityKind.NODE})

    def topics(self) -> list[Ros2Topic]:
        """The topics that have a publisher or a subscription, sorted by name."""
        types: dict[str, set[str]] = defaultdict(set)
        pubs: dict[str, list[str]] = defaultdict(list)
        subs: dict[str, list[str]] = defaultdict(list)
        for e in self.entities:
            if e.kind not in (EntityKind.PUBLISHER, EntityKind.SUBSCRIPTION):
                continue
            types[e.topic].add(e.ros_type or "?")
            (pubs if e.kind is EntityKind.PUBLISHER else subs)[e.topic].append(e.node_fqn)
        return [
            Ros2Topic(t, tuple(sorted(types[t])), tuple(sorted(pubs[t])), tuple(sorted(subs[t])))
            for t in sorted(types)
        ]


def parse_tokens(keys: list[str]) -> Ros2Graph:
    """The graph that the liveliness token ``keys`` describe (a token heard twice, from our
    session and through the router, counts once)."""
    entities = []
    unparsed = 0
    for key in sorted(set(keys)):
        try:
            entities.append(parse_token(key))
        except ValueError:
            unparsed += 1
    return Ros2Graph(tuple(entities), unparsed)


def query_graph(
    session: zenoh.Session, domain: int, timeout_s: float = QUERY_TIMEOUT_S
) -> Ros2Graph:
    """The ROS 2 graph of ``domain`` alive now, as the tokens reachable from ``session`` say."""
    keys = []
    for reply in session.liveliness().get(tokens_of_domain(domain), timeout=timeout_s):
        if reply.ok is not None:
            keys.append(str(reply.ok.key_expr))
    return parse_tokens(keys)
