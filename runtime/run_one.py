"""``umbra run GRAPH --process NAME``: one process of a split graph with its links, started by
hand or by the launcher (``umbra.runtime.launcher``)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from umbra.connectors.errors import UserError
from umbra.runtime.graph.plan import GraphPlan
from umbra.runtime.hints import did_you_mean
from umbra.runtime.link_settings import checked_endpoints, graph_links_origin, zenoh_config_file
from umbra.runtime.links.config import Endpoints, default_mesh
from umbra.runtime.links.config_facts import config_facts
from umbra.runtime.links.exposure import check_exposure, config_for
from umbra.runtime.links.host_auth import host_credentials
from umbra.runtime.links.runs import BY_HAND
from umbra.runtime.links.stats import link_lines
from umbra.runtime.realtime import latency_limit
from umbra.runtime.ros2.run_args import ros2_options
from umbra.runtime.ros2.run_bridge import ros2_lines

#: Seconds a supervised process waits for its consumers before it gives up.
READY_TIMEOUT = 30.0


def run_one(
    plan: GraphPlan, args: argparse.Namespace, clock: str, duration: float | None, out: Path
) -> int:
    """``umbra run GRAPH --process NAME``: one process with its links (by hand or supervised).

    Endpoints: ``--listen``/``--connect`` when given, else the graph's ``links:``, else those of
    the zenoh configuration file, else a fixed loopback mesh (process i of the graph listens on
    tcp/127.0.0.1:7447+i and connects to the ones before it), so processes started by hand on one
    host find each other with no flags.

    Credentials: the launcher's (``--link-auth``), else those of the zenoh configuration file when
    it authenticates on its own (TLS, a password), else, unless ``--insecure``, those derived
    from this user's secret (``umbra.runtime.links.host_auth``), shared by every process of the
    graph this user starts by hand on this host."""
    import logging

    from umbra.runtime.links.process import ProcessOptions, run_linked_process

    name = args.process
    have = plan.populated_processes
    if name not in have:
        raise UserError(
            f"--process: graph `{plan.spec.name}` has no process `{name}` with "
            f"modules (processes: {', '.join(have)}){did_you_mean(name, have)}"
        )
    config_file = zenoh_config_file(plan, args)
    if config_file:
        config_file = config_for(config_file, name)
    facts = config_facts(config_file)  # the one parse of the file
    endpoints = Endpoints(
        checked_endpoints(args.listen, "--listen"), checked_endpoints(args.connect, "--connect")
    )
    origin = "--listen/--connect"
    if endpoints.empty:
        endpoints = Endpoints(
            checked_endpoints(plan.spec.links.listen, "links.listen"),
            checked_endpoints(plan.spec.links.connect, "links.connect"),
        )
        origin = graph_links_origin(plan)
    if endpoints.empty and config_file:
        endpoints = facts.endpoints
        origin = config_file
    if endpoints.empty:
        endpoints = default_mesh(have)[name]
    insecure = bool(getattr(args, "insecure", False))
    check_exposure(endpoints.listen, endpoints.connect, insecure, origin)
    supervised = bool(getattr(args, "supervised", False))
    link_auth = getattr(args, "link_auth", None)
    auth = None
    routed = facts.routed_mode
    if routed and not (link_auth or insecure or facts.authenticates):
        logging.getLogger("umbra").warning(
            "process `%s`: %s: mode `%s` links through a zenoh router, which does not hold the "
            "graph's credentials: links are not authenticated (set TLS or usrpwd up in that file)",
            name,
            config_file,
            routed,
        )
    elif not (link_auth or insecure or facts.authenticates):
        auth = host_credentials(plan, name)
        logging.getLogger("umbra").info(
            "process `%s`: links authenticated with this user's secret %s (only the graph's "
            "processes this user starts on this host can join; --insecure: anyone)",
            name,
            auth["secret_file"],
        )
    options = ProcessOptions(
        process=name,
        output_dir=out,
        endpoints=endpoints,
        clock=clock,
        duration=duration,
        zenoh_config=config_file,
        zenoh_facts=facts,
        link_auth=link_auth,
        auth=auth,
        link_checks=not getattr(args, "unchecked_links", False),
        ready_timeout=READY_TIMEOUT if supervised else None,
        quiet=args.quiet,
        cpu_latency_us=latency_limit(
            plan.spec.cpu_latency_us, name, getattr(args, "cpu_latency_us", None)
        ),
        publish_all=bool(getattr(args, "publish_all", False)),
        attended=bool(getattr(args, "attended", False)),
        run_id=getattr(args, "run_id", None) or BY_HAND,  # checked by ``launcher.run_identity``
        run_started=getattr(args, "run_started", None) or 0.0,
        ros2=ros2_options(plan, args),
    )
    result = run_linked_process(
        plan, options, control=sys.stdin if supervised else None, log=logging.getLogger("umbra")
    )
    if not args.quiet:
        print(result.table(), file=sys.stderr)
        for line in link_lines(result.extra.get("links", {})):
            print(line, file=sys.stderr)
        for line in ros2_lines(result.extra.get("ros2")):
            print(line, file=sys.stderr)
        print(f"summary written to {out / f'summary-{name}.json'}", file=sys.stderr)
    return result.exit_code
