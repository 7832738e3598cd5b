"""A graph's ROS 2 node: publishes mapped outputs and feeds mapped inputs exactly as an rmw_zenoh
node does (``docs/ros2.md``).

One zenoh session, one ROS 2 node (its ``NN`` liveliness token), and per mapping one endpoint: an
``MP`` token and a publisher on the topic's data key for an out mapping, an ``MS`` token and a
subscriber for an in mapping. A sample goes out as CDR with the 33-byte attachment (sequence
number from 1, the wall-clock time of sending, the endpoint's GID). A sample comes in only on the
mapped key (type name and RIHS01 hash included, so a same-named topic of another type never
matches), and is refused — counted, with the reason kept — when its attachment is not
rmw_zenoh's, its payload is larger than its type allows, it does not decode, does not convert,
or its sequence number does not advance for its publisher (latest only, no replay).

Usage (what ``umbra run --ros2`` builds)::

    bridge = Ros2Bridge(session_config(router), domain=0, node_name="umbra", mappings=maps)
    bridge.publish("/joint_states", joint_state_sample)
    bridge.subscribe("/wrist_camera/image_raw", on_image)
    ...
    bridge.close()
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import zenoh

from umbra.connectors.messages import Message
from umbra.runtime.links.session import open_session
from umbra.runtime.ros2.attachment import Attachment
from umbra.runtime.ros2.inbound import INBOUND, max_payload_bytes
from umbra.runtime.ros2.keys import Endpoint, EntityKind, Node, data_key
from umbra.runtime.ros2.mapping import Direction, Ros2Mapping
from umbra.runtime.ros2.msgtypes import from_cdr, to_cdr, type_hash
from umbra.runtime.ros2.names import namespace_problem, node_name_problem
from umbra.runtime.ros2.outbound import OUTBOUND
from umbra.runtime.ros2.qos import QosProfile, Reliability
from umbra.runtime.ros2.stamps import relate

#: Highest ROS 2 domain id (``ROS_DOMAIN_ID``; rmw_zenoh takes any non-negative number, DDS 232).
MAX_DOMAIN = 232


def zenoh_reliability(qos: QosProfile) -> zenoh.Reliability:
    """The zenoh reliability a publisher of ``qos`` asks for, as rmw_zenoh maps it: best effort
    for a best-effort profile (a best-effort link such as UDP may carry it, where the session
    has one), reliable otherwise."""
    if qos.reliability is Reliability.BEST_EFFORT:
        return zenoh.Reliability.BEST_EFFORT
    return zenoh.Reliability.RELIABLE


@dataclass
class TopicStats:
    """What crossed on one topic: samples ``sent`` or ``received``, ``refused`` ones and the
    reason of the latest refusal."""

    sent: int = 0
    received: int = 0
    refused: int = 0
    last_refusal: str = ""

    def as_dict(self) -> dict[str, int | str]:
        return {
            "sent": self.sent,
            "received": self.received,
            "refused": self.refused,
            "last_refusal": self.last_refusal,
        }


@dataclass
class _Out:
    mapping: Ros2Mapping
    endpoint: Endpoint
    publisher: Any
    gid: bytes
    seq: int = 0
    lock: threading.Lock = field(default_factory=threading.Lock)


@dataclass
class _In:
    mapping: Ros2Mapping
    endpoint: Endpoint
    key: str
    subscriber: Any = None
    last_seq: dict[bytes, int] = field(default_factory=dict)


class Ros2Bridge:
    """One ROS 2 node on ``domain`` named ``node_name`` (in ``namespace``), speaking for
    ``mappings`` over a zenoh session opened with ``session_config``
    (:func:`umbra.runtime.ros2.router.session_config`). ``run_clock`` is the run's clock [s] that
    samples' stamps and origins are on."""

    def __init__(
        self,
        session_config: zenoh.Config,
        domain: int = 0,
        node_name: str = "umbra",
        mappings: Sequence[Ros2Mapping] = (),
        *,
        namespace: str = "/",
        run_clock: Callable[[], float] = time.monotonic,
        log: logging.Logger | None = None,
    ) -> None:
        problems = [p for p in (node_name_problem(node_name), namespace_problem(namespace)) if p]
        if not isinstance(domain, int) or not 0 <= domain <= MAX_DOMAIN:
            problems.append(f"expected a ROS 2 domain id 0..{MAX_DOMAIN}, found {domain!r}")
        topics = [m.topic for m in mappings]
        problems += [
            f"topic {t} is mapped twice" for t in sorted({t for t in topics if topics.count(t) > 1})
        ]
        if problems:
            raise ValueError("; ".join(problems))
        self._clock = run_clock
        self._log = log or logging.getLogger("umbra.ros2")
        self._session = open_session(session_config)
        self.domain = domain
        self.node = Node(domain, str(self._session.zid()), 0, node_name, namespace)
        self.stats: dict[str, TopicStats] = {m.topic: TopicStats() for m in mappings}
        self._tokens: list[Any] = []
        self._outs: dict[str, _Out] = {}
        self._ins: dict[str, _In] = {}
        liveliness = self._session.liveliness()
        self._tokens.append(liveliness.declare_token(self.node.token()))
        for entity_id, m in enumerate(mappings, start=1):
            kind = EntityKind.PUBLISHER if m.direction is Direction.OUT else EntityKind.SUBSCRIPTION
            h = type_hash(m.ros_type, m.distro)
            ep = Endpoint(self.node, entity_id, kind, m.topic, m.ros_type, h, m.qos)
            key = data_key(domain, m.topic, m.ros_type, h)
            if kind is EntityKind.PUBLISHER:
                pub = self._session.declare_publisher(
                    key,
                    congestion_control=zenoh.CongestionControl.DROP,
                    reliability=zenoh_reliability(m.qos),
                )
                self._outs[m.topic] = _Out(m, ep, pub, ep.gid())
            else:
                self._ins[m.topic] = _In(m, ep, key)
            self._tokens.append(liveliness.declare_token(ep.token()))

    @property
    def session(self) -> zenoh.Session:
        return self._session

    def endpoints(self) -> list[Endpoint]:
        """Every endpoint this node declares (publishers, then subscriptions)."""
        return [o.endpoint for o in self._outs.values()] + [i.endpoint for i in self._ins.values()]

    def publish(self, topic: str, sample: Message) -> None:
        """Send ``sample`` (of the mapping's umbra type) on the out-mapped ``topic``."""
        out = self._outs.get(topic)
        if out is None:
            raise KeyError(f"{topic} is not mapped as an output to ROS 2")
        m = out.mapping
        msg = OUTBOUND[(m.umbra_type, m.ros_type)](sample, relate(self._clock), m.out_options())
        payload = to_cdr(msg, m.ros_type, m.distro)
        with out.lock:
            out.seq += 1
            attachment = Attachment(out.seq, time.time_ns(), out.gid).encode()
            out.publisher.put(payload, attachment=attachment)
        self.stats[topic].sent += 1

    def subscribe(self, topic: str, callback: Callable[[Message], None]) -> None:
        """Call ``callback`` (on zenoh's thread) with each sample of the in-mapped ``topic``,
        converted to the mapping's umbra type."""
        entry = self._ins.get(topic)
        if entry is None:
            raise KeyError(f"{topic} is not mapped as an input from ROS 2")
        if entry.subscriber is not None:
            raise ValueError(f"{topic} already has a subscriber")

        def on_sample(sample: zenoh.Sample) -> None:
            converted = self._take(entry, sample)
            if converted is None:
                return
            try:
                callback(converted)
            except Exception:
                self._log.exception("ROS 2 input %s: callback failed", topic)

        entry.subscriber = self._session.declare_subscriber(entry.key, on_sample)

    def _take(self, entry: _In, sample: zenoh.Sample) -> Message | None:
        """The umbra sample a zenoh sample holds; None (counted, the reason kept) when refused."""
        m = entry.mapping
        stats = self.stats[m.topic]
        try:
            raw = sample.attachment.to_bytes() if sample.attachment is not None else None
            att = Attachment.decode(raw)
            limit = max_payload_bytes(m.ros_type)
            if len(sample.payload) > limit:
                raise ValueError(f"expected at most {limit} bytes, found {len(sample.payload)}")
            last = entry.last_seq.get(att.gid)
            if last is not None and att.seq <= last:
                raise ValueError(f"sequence number {att.seq} after {last} from one publisher")
            msg = from_cdr(sample.payload.to_bytes(), m.ros_type, m.distro)
            converted = INBOUND[(m.ros_type, m.umbra_type)](
                msg, relate(self._clock), m.in_options()
            )
        except ValueError as exc:
            stats.refused += 1
            stats.last_refusal = str(exc)
            self._log.debug("ROS 2 input %s refused: %s", m.topic, exc)
            return None
        entry.last_seq[att.gid] = att.seq
        stats.received += 1
        return converted

    def close(self) -> None:
        """Undeclare every endpoint and the node, then close the session."""
        for entry in self._ins.values():
            if entry.subscriber is not None:
                entry.subscriber.undeclare()
        for out in self._outs.values():
            out.publisher.undeclare()
        for token in reversed(self._tokens):
            token.undeclare()
        self._tokens.clear()
        self._session.close()

    def __enter__(self) -> Ros2Bridge:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
