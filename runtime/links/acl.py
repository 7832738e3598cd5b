"""Zenoh access-control rules derived from a graph: nobody writes a policy by hand.

Every process of the graph is a subject (identified by the user name it authenticates with, by
the common name of its certificate, or by the zenoh id the credentials give it). Seen from any
process's zenoh node, a peer of subject ``Y`` may:

* put (and end, ``delete``) only the keys of ``Y``'s own outputs that cross processes — so an
  operator console's commands are accepted only from the console's process;
* declare subscribers only on the keys ``Y`` consumes;
* declare a liveliness token only under ``P/_alive/Y/`` (its own identity), and watch or query the
  graph's tokens;

and is sent only what it consumes. Everything else is denied (``default_permission: deny``), so a
peer that authenticates but is not a process of the graph can do nothing at all. The same rules
go into every process's configuration (``zenoh_acl``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from runtime.graph.plan import GraphPlan
from runtime.links.identity import ALIVE

#: Subject of a process: the zenoh subject fields naming it (user or certificate names, zenoh
#: ids), or a list of such subjects of which any one names it.
Subject = dict[str, list[str]]
SubjectOf = Callable[[str], Subject | list[Subject]]


def by_username(process: str) -> dict[str, list[str]]:
    """Subject of a process authenticated by user name (the launcher's per-run credentials)."""
    return {"usernames": [process]}


def common_name(graph: str, process: str) -> str:
    """Common name of the certificate of ``process`` of graph ``graph``."""
    return f"{process}.{graph}.umbra"


def by_certificate(graph: str) -> SubjectOf:
    """Subjects identified by the common names ``umbra keys`` gives certificates."""
    return lambda process: {"cert_common_names": [common_name(graph, process)]}


def link_keys(plan: GraphPlan) -> tuple[dict[str, set[str]], dict[str, set[str]]]:
    """Keys each process publishes and keys each process consumes."""
    produces: dict[str, set[str]] = {p: set() for p in plan.populated_processes}
    consumes: dict[str, set[str]] = {p: set() for p in plan.populated_processes}
    for link in plan.links:
        produces[plan.modules[link.connection.src.module].process].add(link.key)
        consumes[plan.modules[link.connection.dst.module].process].add(link.key)
    return produces, consumes


def zenoh_acl(plan: GraphPlan, subject_of: SubjectOf) -> dict[str, Any]:
    """The ``access_control`` section for every process of ``plan``."""
    produces, consumes = link_keys(plan)
    prefix = plan.key_prefix
    alive_all = f"{prefix}/{ALIVE}/**"
    rules: list[dict[str, Any]] = []
    subjects: list[dict[str, Any]] = []
    policies: list[dict[str, Any]] = []

    def rule(rid: str, messages: list[str], flows: list[str], keys: set[str] | list[str]) -> str:
        rules.append(
            {
                "id": rid,
                "permission": "allow",
                "flows": flows,
                "messages": messages,
                "key_exprs": sorted(keys),
            }
        )
        return rid

    for process in plan.populated_processes:
        named = subject_of(process)
        ids = []
        for i, fields in enumerate(named if isinstance(named, list) else [named]):
            ids.append(process if i == 0 else f"{process}#{i + 1}")
            subjects.append({"id": ids[-1], **fields})
        mine = [
            rule(
                f"{process}: liveliness",
                ["declare_liveliness_subscriber", "liveliness_query", "reply"],
                ["ingress", "egress"],
                [alive_all],
            ),
            rule(
                f"{process}: own token",
                ["liveliness_token"],
                ["ingress"],
                [f"{prefix}/{ALIVE}/{process}/**"],
            ),
            rule(f"{process}: tokens to it", ["liveliness_token"], ["egress"], [alive_all]),
        ]
        if produces[process]:
            mine.append(
                rule(f"{process}: its outputs", ["put", "delete"], ["ingress"], produces[process])
            )
            mine.append(
                rule(
                    f"{process}: subscribers to its outputs",
                    ["declare_subscriber"],
                    ["egress"],
                    produces[process],
                )
            )
        if consumes[process]:
            mine.append(
                rule(f"{process}: its inputs", ["put", "delete"], ["egress"], consumes[process])
            )
            mine.append(
                rule(
                    f"{process}: its subscribers",
                    ["declare_subscriber"],
                    ["ingress"],
                    consumes[process],
                )
            )
        policies.append({"id": f"{process}: graph", "rules": mine, "subjects": ids})
    return {
        "enabled": True,
        "default_permission": "deny",
        "rules": rules,
        "subjects": subjects,
        "policies": policies,
    }
