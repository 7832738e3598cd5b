"""Zenoh sessions for the ROS 2 side: our end (a client of a router) and, when no router runs at
the endpoint, a router of our own standing in for ``rmw_zenohd``. Both are built by the links'
configuration rules (``umbra.runtime.links.config.build_config``): explicit endpoints, multicast
and gossip scouting off.

Our end is a zenoh **client** by default. rmw_zenoh's nodes are peers that find each other by the
router's gossip and then talk directly; with gossip off on our side (and no listen endpoint), a
router routes to and from a client but not between two peers it takes to be meshed, so a peer of
ours would see the tokens of the domain yet none of its data. ``peer`` is kept for a user's
configuration that meshes by other means (explicit endpoints between the hosts)."""

from __future__ import annotations

import json

import zenoh

from umbra.runtime.graph.spec_ros2 import DEFAULT_ROS2_ROUTER as DEFAULT_ROUTER
from umbra.runtime.links.config import Endpoints, build_config, check_endpoint, read_user_config
from umbra.runtime.links.session import open_session

#: Zenoh modes our end of the ROS 2 side may take.
MODES = ("client", "peer")


def session_config(
    router: str = DEFAULT_ROUTER, mode: str = "client", config_file: str | None = None
) -> zenoh.Config:
    """The configuration of our end: ``mode`` (``client`` or ``peer``) connecting to ``router``;
    ``config_file`` (JSON5: TLS, access control) first when given, its mode kept if it sets one."""
    if mode not in MODES:
        raise ValueError(f"expected a zenoh mode among {', '.join(MODES)}, found {mode!r}")
    check_endpoint(router, "ROS 2 router endpoint")
    cfg = read_user_config(config_file) if config_file else zenoh.Config()
    if cfg.get_json("mode") == zenoh.Config().get_json("mode"):
        cfg.insert_json5("mode", json.dumps(mode))
    return build_config(Endpoints(connect=[router]), parsed=cfg)


def router_config(listen: str = DEFAULT_ROUTER, config_file: str | None = None) -> zenoh.Config:
    """The configuration of a zenoh router listening on ``listen`` (as ``rmw_zenohd`` does)."""
    check_endpoint(listen, "ROS 2 router endpoint")
    cfg = read_user_config(config_file) if config_file else zenoh.Config()
    cfg.insert_json5("mode", json.dumps("router"))
    return build_config(Endpoints(listen=[listen]), parsed=cfg)


def open_router(listen: str = DEFAULT_ROUTER, config_file: str | None = None) -> zenoh.Session:
    """A zenoh router session listening on ``listen``; UserError when the endpoint is taken."""
    return open_session(router_config(listen, config_file))
