"""Zenoh access-control rules derived from a graph: nobody writes a policy by hand.

Every process of the graph is a subject (identified by the user name it authenticates with, by
the common name of its certificate, or by the zenoh id the credentials give it). Seen from any
process's zenoh node, a peer of subject ``Y`` may:

* put (and end, ``delete``) only the keys of ``Y``'s own outputs that cross processes — so an
  operator console's commands are accepted only from the console's process;
* declare subscribers only on the keys ``Y`` consumes;
* declare a liveliness token only under ``P/_alive/Y/`` (its own identity), and watch or query the
  graph's tokens;
* declare a clock queryable and reply to clock queries only under ``P/_clock/Y/`` (its own clock:
  nobody answers for another process's), and ask every clock of the graph (a reply counts only
  from the session the producer's proven token names);

and is sent only what it consumes. Everything else is denied (``default_permission: deny``), so a
peer that authenticates but is not a process of the graph can do nothing at all. The same rules
go into every process's configuration (``zenoh_acl``).

An *observer* (``Observer``: ``umbra topics``, a viewer) is a read-only subject: it may declare
subscribers on its keys (by default every output key of the graph, ``output_keys``) and is sent
their samples and ends of stream; it may watch and query the graph's liveliness tokens. It may
not put, delete, declare a token or query anything else.

The *tuner* (user ``TUNER_USER``, only in a run served live with ``--foxglove``: the launcher's
process, which hosts the live server) may put parameter changes on ``P/_params/<process>``
(``param_key``) and be told of the processes' subscribers there; nothing else. A process
subscribes only to its own key, and nobody else may put there.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

from umbra.runtime.graph.plan import GraphPlan
from umbra.runtime.links.clock_sync import CLOCK, clock_keys
from umbra.runtime.links.identity import ALIVE

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


#: User name of the observer of a local run (``@`` is in no process name, so no process has it).
OBSERVER_USER = "observer@umbra"
#: User name of the live server's process when it sends parameter changes (``@``: no process).
TUNER_USER = "tuner@umbra"
#: Key segment of the parameter changes sent to a process.
PARAMS = "_params"


def param_key(prefix: str, process: str) -> str:
    """Key on which ``process`` takes changes of its modules' tunable parameters."""
    return f"{prefix}/{PARAMS}/{process}"


@dataclass(frozen=True)
class Observer:
    """A read-only subject: who (zenoh subject fields) and the key expressions it may read."""

    name: str
    subject: dict[str, list[str]]
    keys: tuple[str, ...]


def output_key(prefix: str, module: str, port: str) -> str:
    """Key of the samples of output ``port`` of ``module`` (docs/wire-format.md, section 1)."""
    return f"{prefix}/{module}/{port}"


def output_keys(plan: GraphPlan) -> list[str]:
    """The key of every output of every module of ``plan`` (links and the others)."""
    return sorted(
        output_key(plan.key_prefix, name, port)
        for name, module in plan.modules.items()
        for port in module.outputs
    )


def local_observer(plan: GraphPlan) -> Observer:
    """The observer of a run on this host: user ``OBSERVER_USER``, every output key of ``plan``."""
    return Observer("local", {"usernames": [OBSERVER_USER]}, tuple(output_keys(plan)))


def observer_certificate_name(graph: str, observer: str) -> str:
    """Common name of observer ``observer``'s certificate (``@``: never a process's)."""
    return f"{observer}@observer.{graph}.umbra"


def ros2_certificate_name(graph: str, name: str) -> str:
    """Common name of ROS 2 certificate ``name`` (``@``: never a process's, so the graph's rules
    give it nothing on the links: it is for the ROS 2 router's endpoint only)."""
    return f"{name}@ros2.{graph}.umbra"


def link_keys(plan: GraphPlan) -> tuple[dict[str, set[str]], dict[str, set[str]]]:
    """Keys each process publishes and keys each process consumes."""
    produces: dict[str, set[str]] = {p: set() for p in plan.populated_processes}
    consumes: dict[str, set[str]] = {p: set() for p in plan.populated_processes}
    for link in plan.links:
        produces[plan.modules[link.connection.src.module].process].add(link.key)
        consumes[plan.modules[link.connection.dst.module].process].add(link.key)
    return produces, consumes


def zenoh_acl(
    plan: GraphPlan,
    subject_of: SubjectOf,
    observers: Sequence[Observer] = (),
    tuner: dict[str, list[str]] | None = None,
) -> dict[str, Any]:
    """The ``access_control`` section for every process of ``plan`` (and ``observers``, and the
    ``tuner`` subject when the run is served live)."""
    produces, consumes = link_keys(plan)
    prefix = plan.key_prefix
    alive_all = f"{prefix}/{ALIVE}/**"
    clocks_all = f"{prefix}/{CLOCK}/**"
    rules: list[dict[str, Any]] = []
    subjects: list[dict[str, Any]] = []
    policies: list[dict[str, Any]] = []

    def rule(rid: str, messages: list[str], flows: list[str], keys: Iterable[str]) -> str:
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
            # the graph's one time base (umbra.runtime.links.clock_sync): only the clock's owner
            # answers for it; anyone of the graph may ask and hear the answers
            rule(
                f"{process}: its clock",
                ["declare_queryable", "reply"],
                ["ingress"],
                [clock_keys(prefix, process)],
            ),
            rule(
                f"{process}: queries to its clock",
                ["query"],
                ["egress"],
                [clock_keys(prefix, process)],
            ),
            rule(f"{process}: asks clocks", ["query"], ["ingress"], [clocks_all]),
            rule(
                f"{process}: clocks to it", ["declare_queryable", "reply"], ["egress"], [clocks_all]
            ),
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
    for observer in observers:
        oid = f"observer {observer.name}"
        subjects.append({"id": oid, **observer.subject})
        reads = [
            rule(f"{oid}: subscribe", ["declare_subscriber"], ["ingress"], observer.keys),
            rule(f"{oid}: samples to it", ["put", "delete"], ["egress"], observer.keys),
            rule(
                f"{oid}: watch tokens",
                ["declare_liveliness_subscriber", "liveliness_query"],
                ["ingress"],
                [alive_all],
            ),
            rule(f"{oid}: tokens to it", ["liveliness_token", "reply"], ["egress"], [alive_all]),
        ]
        policies.append({"id": f"{oid}: read only", "rules": reads, "subjects": [oid]})
    if tuner is not None:
        changes = [param_key(prefix, p) for p in plan.populated_processes]
        subjects.append({"id": "tuner", **tuner})
        sends = [
            rule("tuner: parameter changes", ["put"], ["ingress"], changes),
            rule("tuner: their subscribers", ["declare_subscriber"], ["egress"], changes),
        ]
        policies.append(
            {"id": "tuner: parameter changes only", "rules": sends, "subjects": ["tuner"]}
        )
    return {
        "enabled": True,
        "default_permission": "deny",
        "rules": rules,
        "subjects": subjects,
        "policies": policies,
    }
