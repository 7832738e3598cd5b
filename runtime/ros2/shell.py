"""The shell on the ROS 2 side: ``umbra topics --ros2`` lists the topics of a ROS 2 domain beside
ours (name, types, publishing and subscribing nodes, from their liveliness tokens:
:mod:`umbra.runtime.ros2.discovery`), and ``umbra echo /topic --ros2`` prints a ROS 2 topic's
messages decoded (CDR with the type its publishers declare), as ``umbra echo`` prints ours.

Both connect to the ROS 2 router as a zenoh client (``--ros2-router``, default
``tcp/127.0.0.1:7447``) on ``--ros2-domain`` (default 0) and declare nothing: no node, no
token, no publisher.
"""

from __future__ import annotations

import argparse
import dataclasses
import queue
import sys
import time
from typing import TYPE_CHECKING, Any

from umbra.connectors.errors import UserError
from umbra.connectors.json_text import json_text
from umbra.runtime.graph.names import endpoint_problem
from umbra.runtime.graph.spec_ros2 import DEFAULT_ROS2_ROUTER as DEFAULT_ROUTER
from umbra.runtime.ros2.attachment import Attachment
from umbra.runtime.ros2.keys import EntityKind, data_key
from umbra.runtime.ros2.names import topic_name_problem
from umbra.runtime.ros2.run_args import router_answers

if TYPE_CHECKING:  # imported where used: `umbra --help` loads this file without them
    import zenoh

    from umbra.runtime.ros2.discovery import Ros2Topic


def add_shell_args(parser: argparse.ArgumentParser) -> None:
    """``--ros2``, ``--ros2-domain``, ``--ros2-router`` of ``umbra topics`` and ``umbra echo``."""
    parser.add_argument(
        "--ros2",
        action="store_true",
        help="topics: the ROS 2 domain's topics beside the run's; echo: KEY is a ROS 2 topic "
        "(/name), read from the ROS 2 domain instead of a run",
    )
    parser.add_argument(
        "--ros2-domain", type=int, metavar="N", help="ROS 2 domain id (default 0); implies --ros2"
    )
    parser.add_argument(
        "--ros2-router",
        metavar="ENDPOINT",
        help=f"the ROS 2 zenoh router (default {DEFAULT_ROUTER}); implies --ros2",
    )


def _open(args: argparse.Namespace) -> tuple[zenoh.Session, int, str]:
    """A client session of the ROS 2 router the options name, the domain and the router."""
    from umbra.runtime.links.session import open_session
    from umbra.runtime.ros2.bridge import MAX_DOMAIN
    from umbra.runtime.ros2.router import session_config

    domain = getattr(args, "ros2_domain", None)
    domain = 0 if domain is None else domain
    if not 0 <= domain <= MAX_DOMAIN:
        raise UserError(
            f"--ros2-domain: expected a ROS 2 domain id 0..{MAX_DOMAIN}, found {domain}"
        )
    router = getattr(args, "ros2_router", None) or DEFAULT_ROUTER
    if endpoint_problem(router):
        raise UserError(f"--ros2-router: error: {endpoint_problem(router)}")
    if not router_answers(router):
        raise UserError(
            f"--ros2: expected a ROS 2 router at {router}, found none answering (start "
            "rmw_zenohd, or `umbra run GRAPH --ros2`, which starts one)"
        )
    return open_session(session_config(router)), domain, router


def list_topics(args: argparse.Namespace, timeout_s: float) -> tuple[int, str, list[Ros2Topic]]:
    """The ROS 2 topics alive on the domain: ``(domain, router, topics)``."""
    from umbra.runtime.ros2.discovery import query_graph

    session, domain, router = _open(args)
    try:
        return domain, router, query_graph(session, domain, timeout_s).topics()
    finally:
        session.close()


def print_topics(domain: int, router: str, topics: list[Ros2Topic], as_json: bool) -> None:
    """The ROS 2 topics as a table (or one JSON object per topic)."""
    if as_json:
        for t in topics:
            row = {"ros2_topic": t.name, "types": list(t.types), "domain": domain}
            print(json_text({**row, "publishers": t.publishers, "subscribers": t.subscribers}))
        return
    print(f"ROS 2 domain {domain} via {router}: {len(topics)} topics", file=sys.stderr)
    head = ("ROS 2 TOPIC", "TYPE", "PUBLISHERS", "SUBSCRIBERS")
    lines = [head] + [
        (
            t.name,
            ", ".join(t.types),
            ", ".join(t.publishers) or "-",
            ", ".join(t.subscribers) or "-",
        )
        for t in topics
    ]
    widths = [max(len(line[i]) for line in lines) for i in range(len(head))]
    for line in lines:
        print("  ".join(c.ljust(w) for c, w in zip(line, widths, strict=True)).rstrip())


def message_dict(msg: Any) -> dict[str, Any]:
    """A rosbags message as JSON-ready fields (big arrays summarised as ``umbra echo`` does)."""
    from umbra.runtime.cli.observing import _plain

    return {k: _plain(v) for k, v in dataclasses.asdict(msg).items()}


def echo(args: argparse.Namespace, topic: str) -> int:
    """``umbra echo /topic --ros2``: print the topic's messages, decoded, until ``--once`` or
    ``--timeout``; exit 1 when nothing came within ``--timeout``."""
    from umbra.runtime.ros2.discovery import query_graph

    problem = topic_name_problem(topic)
    if problem:
        raise UserError(f"umbra echo: {problem}")
    session, domain, router = _open(args)
    try:
        graph = query_graph(session, domain)
        publishers = [
            e for e in graph.entities if e.kind is EntityKind.PUBLISHER and e.topic == topic
        ]
        if not publishers:
            names = ", ".join(t.name for t in graph.topics()) or "none"
            raise UserError(
                f"umbra echo: expected a publisher of {topic} on ROS 2 domain {domain} via "
                f"{router}, found none (topics: {names})"
            )
        kinds = {(e.ros_type, e.type_hash) for e in publishers if e.ros_type}
        if len(kinds) != 1:
            raise UserError(
                f"umbra echo: expected one message type on {topic}, found "
                f"{', '.join(sorted(str(t) for t, _ in kinds)) or 'none that is a message'}"
            )
        ((ros_type, type_hash),) = kinds
        samples: queue.Queue[zenoh.Sample] = queue.Queue()
        sub = session.declare_subscriber(data_key(domain, topic, ros_type, type_hash), samples.put)
        try:
            return _print_samples(args, topic, ros_type, samples)
        finally:
            sub.undeclare()
    finally:
        session.close()


def _print_samples(
    args: argparse.Namespace, topic: str, ros_type: str, samples: queue.Queue[zenoh.Sample]
) -> int:
    from umbra.runtime.ros2.msgtypes import from_cdr

    last = time.monotonic()
    while True:
        try:
            sample = samples.get(timeout=0.2)
        except queue.Empty:
            if args.timeout is not None and time.monotonic() - last > args.timeout:
                print(f"umbra echo: no message on {topic} for {args.timeout:g} s", file=sys.stderr)
                return 1
            continue
        last = time.monotonic()
        payload = sample.payload.to_bytes()
        try:
            raw = sample.attachment.to_bytes() if sample.attachment is not None else None
            seq = Attachment.decode(raw).seq
            fields = message_dict(from_cdr(payload, ros_type))
        except ValueError as exc:
            print(f"umbra echo: {topic}: undecodable message: {exc}", file=sys.stderr)
            continue
        if args.json:
            print(json_text({"topic": topic, "type": ros_type, "seq": seq, **fields}), flush=True)
        else:
            print(f"--- {topic} ({ros_type}, {len(payload)} bytes, seq {seq})")
            for name, value in fields.items():
                print(f"{name}: {json_text(value)}")
            sys.stdout.flush()
        if args.once:
            return 0
