"""``umbra keys GRAPH --out DIR``: certificates and access rules for a graph across hosts."""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from umbra.connectors.errors import UserError

if TYPE_CHECKING:  # annotations only: `umbra --help` loads this file without them
    from umbra.runtime.graph.plan import GraphPlan

NAME = "keys"
HELP = "make a CA, a certificate per process and the graph's zenoh access rules (mutual TLS)"
GUIDE = "docs/guide/processes.md"  # the guide page this command's --help points to
#: An observer's or a ROS 2 certificate's name (``@`` and ``/`` never: they name files).
NAME_PATTERN = r"[A-Za-z0-9_.\-]+"


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("graph", metavar="GRAPH", help="graph file (.yaml)")
    parser.add_argument("--out", type=Path, required=True, metavar="DIR", help="folder to write")
    parser.add_argument(
        "--days", type=int, default=365, metavar="N", help="validity of the certificates [days]"
    )
    parser.add_argument(
        "--host",
        action="append",
        default=[],
        metavar="PROCESS=ADDRESS",
        help="an address or host name a process is reached at, written into its certificate "
        "(repeatable; localhost and 127.0.0.1 are always there)",
    )
    parser.add_argument(
        "--prefix",
        metavar="KEY",
        help="zenoh key prefix (default: the graph's `links.prefix`, else umbra/<graph>)",
    )
    parser.add_argument(
        "--observer",
        action="append",
        default=[],
        metavar="NAME[=MODULE/PORT,...]",
        help="also a read-only observer certificate (observer@NAME.json5): it may subscribe to "
        "the outputs named (default: every output of the graph) and their liveliness, nothing "
        "else (repeatable; for `umbra topics/echo/hz --zenoh-config`, viewers)",
    )
    parser.add_argument(
        "--ros2",
        action="append",
        default=[],
        metavar="NAME",
        help="also a ROS 2 certificate (ros2@NAME.json5): mutual TLS with this CA and no access "
        "rules, for a TLS ROS 2 router endpoint: `umbra run --ros2-config`, the router, a ROS 2 "
        "host (repeatable: one per end; docs/ros2.md)",
    )


def _hosts(items: list[str], processes: list[str]) -> dict[str, list[str]]:
    hosts: dict[str, list[str]] = {}
    for item in items:
        process, sep, address = item.partition("=")
        if not sep or not address or process not in processes:
            raise UserError(
                f"--host: expected PROCESS=ADDRESS with PROCESS one of "
                f"{', '.join(processes)}, found {item!r}"
            )
        hosts.setdefault(process, []).append(address)
    return hosts


def _names(items: list[str], option: str) -> list[str]:
    """New names of letters, digits, '_', '.', '-' (``--ros2``)."""
    for i, name in enumerate(items):
        if not re.fullmatch(NAME_PATTERN, name) or name in items[:i]:
            raise UserError(
                f"{option}: expected a new NAME of letters, digits, '_', '.', '-', found {name!r}"
            )
    return items


def _observers(items: list[str], plan: GraphPlan) -> dict[str, list[str]]:
    """``--observer NAME[=MODULE/PORT,...]`` as name -> the full keys it may read."""
    from umbra.runtime.links.acl import output_keys

    every = output_keys(plan)
    found: dict[str, list[str]] = {}
    for item in items:
        name, sep, outputs = item.partition("=")
        if not re.fullmatch(NAME_PATTERN, name) or name in found:
            raise UserError(
                f"--observer: expected NAME[=MODULE/PORT,...] with a new NAME of letters, "
                f"digits, '_', '.', '-', found {item!r}"
            )
        keys = [
            k if k.startswith(plan.key_prefix + "/") else f"{plan.key_prefix}/{k.strip('/')}"
            for k in outputs.split(",")
            if k.strip()
        ]
        unknown = [k for k in keys if k not in every]
        if unknown or (sep and not keys):
            raise UserError(
                f"--observer {item}: expected outputs of graph `{plan.spec.name}` (MODULE/PORT), "
                f"found {', '.join(unknown) or 'none'}; its outputs: {', '.join(every)}"
            )
        found[name] = keys or every
    return found


def main(args: argparse.Namespace) -> int:
    from umbra.runtime.graph.check import load_graph
    from umbra.runtime.links.tls import write_keys

    if not 1 <= args.days <= 3650:
        raise UserError(f"--days must be from 1 to 3650, found {args.days}")
    plan = load_graph(args.graph, prefix=args.prefix)
    processes = plan.populated_processes
    if len(processes) < 2 and not args.ros2:
        raise UserError(
            f"{args.graph}: graph `{plan.spec.name}` runs in one process "
            f"({', '.join(processes)}): it has no links to secure (--ros2 NAME: certificates "
            "for a TLS ROS 2 router endpoint)"
        )
    out: Path = args.out
    if out.exists() and not out.is_dir():
        raise UserError(f"--out: {out} exists and is not a folder")
    if out.is_dir() and any(out.iterdir()):
        raise UserError(f"--out: {out} is not empty; give a new folder (keys are never mixed)")
    hosts = _hosts(args.host, processes)
    observers = _observers(args.observer, plan)
    ros2 = _names(args.ros2, "--ros2")
    written = write_keys(plan, out, args.days, hosts, observers, ros2)
    print(f"wrote {len(written)} files to {out}:", file=sys.stderr)
    for path in written:
        print(f"  {path}", file=sys.stderr)
    # the process given an address listens (the first one when none is); the others connect
    listener = next(iter(hosts), processes[0])
    address = hosts[listener][0] if listener in hosts else f"HOST-OF-{listener.upper()}"
    connects = "".join(
        f"\n  umbra run {args.graph} --process {p} --zenoh-config {out}/ "
        f"--connect tls/{address}:7447"
        for p in processes
        if p != listener
    )
    if len(processes) > 1:
        print(
            f"copy {out}/ to each host (it holds every process's private key: keep it private), "
            f"then e.g.\n  umbra run {args.graph} --process {listener} --zenoh-config {out}/ "
            f"--listen tls/0.0.0.0:7447{connects}\n"
            f"or on one host: umbra run {args.graph} --zenoh-config {out}/",
            file=sys.stderr,
        )
    for name in observers:
        print(
            f"observer `{name}`: umbra topics --zenoh-config {out}/observer@{name}.json5 "
            f"--connect tls/{address}:7447 (copy observer@{name}.* and ca.pem only)",
            file=sys.stderr,
        )
    for name in ros2:
        print(
            f"ROS 2 `{name}`: {out}/ros2@{name}.json5, one end of a TLS ROS 2 router endpoint "
            f"(copy ros2@{name}.* and ca.pem only), e.g. umbra run {args.graph} --ros2-router "
            f"tls/HOST:7447 --ros2-config {out}/ros2@{name}.json5",
            file=sys.stderr,
        )
    return 0
