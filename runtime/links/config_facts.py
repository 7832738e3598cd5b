"""What a user's zenoh configuration file decides for the launcher, read from one parse.

``umbra run --zenoh-config FILE`` lets the file set TLS, a password, a mode (peer, client,
router), zenoh access-control rules and endpoints; the launcher chooses credentials, endpoints
and rules by them. :func:`config_facts` parses the file once (``umbra.runtime.links.config``:
bounded, errors as ``FILE:LINE:COL: error:``) and keeps the parsed configuration, which
:func:`umbra.runtime.links.config.build_config` then completes instead of parsing the file again.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

import zenoh

from umbra.runtime.links.config import Endpoints, read_user_config


def setting(cfg: zenoh.Config, key: str) -> Any:
    """The JSON value of ``key`` (``a/b/c``) in ``cfg``; None when zenoh has no such key."""
    try:
        return json.loads(cfg.get_json(key))
    except Exception:  # zenoh raises ZError for an unknown key
        return None


def _endpoints(cfg: zenoh.Config) -> Endpoints:
    """The listen/connect endpoints ``cfg`` sets beyond zenoh's stock ones (empty when none)."""
    stock, found = zenoh.Config(), Endpoints()
    for key, attr in (("listen/endpoints", "listen"), ("connect/endpoints", "connect")):
        value = setting(cfg, key)
        if value != setting(stock, key):
            if isinstance(value, dict):  # per-mode form {"peer": [...], "router": [...]}
                value = value.get("peer", [])
            setattr(found, attr, list(value))
    return found


@dataclass
class ConfigFacts:
    """The settings of one zenoh configuration file that the launcher decides by."""

    #: a CA to verify peers with is set (TLS links)
    tls: bool = False
    #: a zenoh user name is set (password authentication)
    password: bool = False
    #: ``mode`` of the file (``peer`` when it sets none)
    mode: str = "peer"
    #: the file enables zenoh access control of its own
    access_control: bool = False
    endpoints: Endpoints = field(default_factory=Endpoints)
    #: the parsed file (TLS paths made absolute), for ``build_config``; None without a file
    config: zenoh.Config | None = field(default=None, repr=False)

    @property
    def authenticates(self) -> bool:
        """Whether the file authenticates sessions on its own (TLS or a password)."""
        return self.tls or self.password

    @property
    def routed_mode(self) -> str:
        """The file's mode when it is not ``peer`` (links then go through a zenoh router)."""
        return "" if self.mode == "peer" else self.mode


def config_facts(config_file: str | None) -> ConfigFacts:
    """Parse ``config_file`` once (UserError when zenoh cannot read it); no file: no facts."""
    if not config_file:
        return ConfigFacts()
    cfg = read_user_config(config_file)
    mode = setting(cfg, "mode")
    return ConfigFacts(
        tls=bool(setting(cfg, "transport/link/tls/root_ca_certificate")),
        password=bool(setting(cfg, "transport/auth/usrpwd/user")),
        mode=mode if isinstance(mode, str) and mode else "peer",
        access_control=bool(setting(cfg, "access_control/enabled")),
        endpoints=_endpoints(cfg),
        config=cfg,
    )
