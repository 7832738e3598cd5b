"""rmw_zenoh's key expressions: the data key of a topic and the liveliness tokens of nodes and
endpoints (rmw_zenoh's ``docs/design.md``, "Topic and Service name mapping" and "Graph Cache").

Data key::

    <domain>/<topic without its first slash>/<DDS type name>/<RIHS01 hash>

Liveliness tokens::

    @ros2_lv/<domain>/<session id>/<node id>/<node id>/NN/<enclave>/<namespace>/<node name>
    @ros2_lv/<domain>/<session id>/<node id>/<entity id>/<MP|MS|SS|SC>/<enclave>/<namespace>/
        <node name>/<topic>/<DDS type name>/<RIHS01 hash>/<QoS>

where enclave, namespace and topic are mangled (``/`` -> ``%``; empty -> ``%``) and QoS is the
compact form of :mod:`umbra.runtime.ros2.qos`.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from enum import Enum

from umbra.runtime.ros2.names import dds_type_name, demangle, mangle, ros_type_name
from umbra.runtime.ros2.qos import QosProfile

#: The hermetic key prefix of every ROS 2 liveliness token.
ADMIN_SPACE = "@ros2_lv"


class EntityKind(str, Enum):
    """What a liveliness token stands for."""

    NODE = "NN"
    PUBLISHER = "MP"
    SUBSCRIPTION = "MS"
    SERVICE = "SS"
    CLIENT = "SC"


def data_key(domain: int, topic: str, ros_type: str, type_hash: str) -> str:
    """The key a topic's samples travel on (``0/chatter/std_msgs::msg::dds_::String_/RIHS01_…``)."""
    return f"{domain}/{topic.strip('/')}/{dds_type_name(ros_type)}/{type_hash}"


def tokens_of_domain(domain: int) -> str:
    """The key expression matching every liveliness token of ``domain``."""
    return f"{ADMIN_SPACE}/{domain}/**"


@dataclass(frozen=True)
class Node:
    """A ROS 2 node: its ``domain``, zenoh ``session`` id, ``node_id`` within the session,
    ``namespace`` (``/`` when none), ``name`` and SROS ``enclave`` (empty when none)."""

    domain: int
    session: str
    node_id: int
    name: str
    namespace: str = "/"
    enclave: str = ""

    def token(self) -> str:
        """The node's liveliness token (kind ``NN``)."""
        return "/".join(self._head(self.node_id, EntityKind.NODE))

    def _head(self, entity_id: int, kind: EntityKind) -> list[str]:
        return [
            ADMIN_SPACE,
            str(self.domain),
            self.session,
            str(self.node_id),
            str(entity_id),
            kind.value,
            mangle(self.enclave),
            mangle(self.namespace),
            mangle(self.name),
        ]


@dataclass(frozen=True)
class Endpoint:
    """A publisher or subscription (``kind``) of ``node`` on ``topic`` of ``ros_type``."""

    node: Node
    entity_id: int
    kind: EntityKind
    topic: str
    ros_type: str
    type_hash: str
    qos: QosProfile

    def token(self) -> str:
        """The endpoint's liveliness token."""
        head = self.node._head(self.entity_id, self.kind)
        tail = [mangle(self.topic), dds_type_name(self.ros_type), self.type_hash, self.qos.encode()]
        return "/".join(head + tail)

    def gid(self) -> bytes:
        """A 16-byte GID for the endpoint, derived from its token (stable for one session):
        BLAKE2b-128 of the token, where rmw_zenoh_cpp takes XXH3-128 (only uniqueness counts)."""
        return hashlib.blake2b(self.token().encode(), digest_size=16).digest()


@dataclass(frozen=True)
class Entity:
    """What a liveliness token of another node says (``topic`` and what follows: endpoints
    only). ``ros_type`` is None when the DDS type name is not one of a message."""

    kind: EntityKind
    domain: int
    session: str
    node_id: str
    entity_id: str
    enclave: str
    namespace: str
    node_name: str
    topic: str = ""
    ros_type: str | None = None
    type_hash: str = ""
    qos: QosProfile | None = None

    @property
    def node_fqn(self) -> str:
        """The node's fully qualified name (``/robot1/talker``)."""
        return f"{self.namespace.rstrip('/')}/{self.node_name}"


def parse_token(key: str) -> Entity:
    """The entity a liveliness token ``key`` declares; ValueError saying what is wrong."""
    parts = key.split("/")
    if len(parts) < 9 or parts[0] != ADMIN_SPACE:
        raise ValueError(f"expected `{ADMIN_SPACE}/<domain>/…` with 9 or 13 chunks, found {key!r}")
    if any(p == "" for p in parts):
        raise ValueError(f"empty chunk in liveliness token {key!r}")
    try:
        kind = EntityKind(parts[5])
    except ValueError:
        raise ValueError(f"unknown entity kind {parts[5]!r} in {key!r}") from None
    if not parts[1].isdigit():
        raise ValueError(f"expected a domain number, found {parts[1]!r} in {key!r}")
    common = dict(
        kind=kind,
        domain=int(parts[1]),
        session=parts[2],
        node_id=parts[3],
        entity_id=parts[4],
        enclave=demangle(parts[6]).rstrip("/") if parts[6] != "%" else "",
        namespace=demangle(parts[7]),
        node_name=parts[8],
    )
    if kind is EntityKind.NODE:
        if len(parts) != 9:
            raise ValueError(f"expected 9 chunks in a node's token, found {len(parts)} in {key!r}")
        return Entity(**common)  # type: ignore[arg-type]
    if len(parts) != 13:
        raise ValueError(
            f"expected 13 chunks in an endpoint's token, found {len(parts)} in {key!r}"
        )
    return Entity(
        **common,  # type: ignore[arg-type]
        topic=demangle(parts[9]),
        ros_type=ros_type_name(parts[10]),
        type_hash=parts[11],
        qos=QosProfile.decode(parts[12]),
    )
