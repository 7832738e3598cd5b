"""``umbra run``'s ROS 2 options (``--ros2``, ``--ros2-domain N``, ``--ros2-router ENDPOINT``,
``--ros2-config FILE|DIR``), what they make of a graph's ``ros2:`` section, and the router a run
starts when none answers.

The domain and router are the command line's, else the section's, else domain 0 and
``tcp/127.0.0.1:7447`` (where ``rmw_zenohd`` listens). The run that ``umbra run`` starts (one
process, or the launcher of a split run, or a process started by hand) looks for a router at the
endpoint first; when nothing answers there it opens one itself (a zenoh router session standing
in for ``rmw_zenohd``, :func:`umbra.runtime.ros2.router.open_router`) and says so. Processes the
launcher starts never do: they connect to the launcher's.
"""

from __future__ import annotations

import argparse
import socket
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from umbra.connectors.errors import UserError
from umbra.runtime.graph.names import endpoint_problem
from umbra.runtime.graph.spec_ros2 import DEFAULT_ROS2_ROUTER

if TYPE_CHECKING:  # imported where used: `umbra --help` loads this file without them
    from umbra.runtime.graph.plan import GraphPlan
    from umbra.runtime.ros2.run_bridge import Ros2RunOptions

#: How long to wait for a router's port to accept a connection [s].
ANSWER_TIMEOUT_S = 0.5


def add_ros2_args(parser: argparse.ArgumentParser) -> None:
    """``--ros2`` and its settings."""
    parser.add_argument(
        "--ros2",
        action="store_true",
        help="the ports the graph's `ros2:` section maps appear to ROS 2 as an rmw_zenoh node's "
        "would (outputs published, inputs fed from ROS 2 topics); starts a zenoh router when "
        "none answers at the endpoint",
    )
    parser.add_argument(
        "--ros2-domain",
        type=int,
        metavar="N",
        help="ROS 2 domain id (ROS_DOMAIN_ID; default: the section's `domain`, else 0); implies "
        "--ros2",
    )
    parser.add_argument(
        "--ros2-router",
        metavar="ENDPOINT",
        help=f"the ROS 2 zenoh router (default: the section's `router`, else "
        f"{DEFAULT_ROS2_ROUTER}, where rmw_zenohd listens); implies --ros2",
    )
    parser.add_argument(
        "--ros2-config",
        metavar="FILE|DIR",
        help="zenoh JSON5 configuration of the ROS 2 session, read as --zenoh-config reads it "
        "(a folder gives each process its own PROCESS.json5); for a TLS router endpoint with "
        "the graph's CA: the ros2@NAME.json5 `umbra keys GRAPH --ros2 NAME` writes (a "
        "process's own file carries the graph's access rules, which deny every ROS 2 key); "
        "implies --ros2",
    )


def wants_ros2(args: argparse.Namespace) -> bool:
    """True when any ROS 2 option is given."""
    return bool(
        getattr(args, "ros2", False)
        or getattr(args, "ros2_domain", None) is not None
        or getattr(args, "ros2_router", None)
        or getattr(args, "ros2_config", None)
    )


def ros2_options(plan: GraphPlan, args: argparse.Namespace) -> Ros2RunOptions | None:
    """The run's ROS 2 settings (None without ``--ros2``); UserError for a bad option or a graph
    that maps no port to ROS 2."""
    from umbra.runtime.ros2.run_bridge import Ros2RunOptions

    if not wants_ros2(args):
        return None
    section = plan.spec.ros2
    router = getattr(args, "ros2_router", None) or section.router
    if endpoint_problem(router):
        raise UserError(f"--ros2-router: error: {endpoint_problem(router)}")
    if not plan.ros2:
        raise UserError(
            f"--ros2: expected a `ros2:` section mapping ports of graph `{plan.spec.name}` to "
            f"ROS 2 topics, found none in {plan.spec.file} (docs/ros2.md)"
        )
    config = getattr(args, "ros2_config", None)
    if config:
        _check_config(str(config))
    domain = getattr(args, "ros2_domain", None)
    return Ros2RunOptions(
        domain=section.domain if domain is None else domain,
        router=router,
        config_file=str(config) if config else None,
    )


def _check_config(path: str) -> None:
    """UserError before anything starts when ``path`` is neither a folder nor a zenoh
    configuration file (the links' rule: ``check_config_file``)."""
    from umbra.runtime.links.config import check_config_file

    if not Path(path).is_dir():
        check_config_file(path)


def child_args(options: Ros2RunOptions | None) -> list[str]:
    """The options a launcher passes on to its processes."""
    if options is None:
        return []
    config = ["--ros2-config", options.config_file] if options.config_file else []
    return [
        "--ros2",
        "--ros2-domain",
        str(options.domain),
        "--ros2-router",
        options.router,
        *config,
    ]


def router_answers(endpoint: str, timeout_s: float = ANSWER_TIMEOUT_S) -> bool:
    """True when something accepts a TCP connection at ``endpoint``'s address (``tcp/`` and
    ``tls/`` endpoints; others are taken to answer: zenoh will say when they do not)."""
    protocol, _, rest = endpoint.partition("/")
    if protocol not in ("tcp", "tls"):
        return True
    host, _, port = rest.split("?")[0].split("#")[0].rpartition(":")
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=timeout_s):
            return True
    except (OSError, ValueError):
        return False


def start_router(options: Ros2RunOptions | None, supervised: bool) -> Any:
    """A router session of this process when ``--ros2`` finds none at its endpoint (None when one
    answers, without ``--ros2``, or in a process the launcher started); says so on stderr."""
    from umbra.runtime.ros2.router import open_router

    if options is None or supervised or router_answers(options.router):
        return None
    config = options.config_file
    router = open_router(options.router, config if config and Path(config).is_file() else None)
    print(
        f"umbra run: ros2: no router answered at {options.router}; started one in this process "
        "(a zenoh router session standing in for rmw_zenohd), which ends with the run",
        file=sys.stderr,
        flush=True,
    )
    return router
