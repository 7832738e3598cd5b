"""The graph file's ``links:`` section: key prefix, endpoints, zenoh file, dispatch."""

from __future__ import annotations

from umbra.runtime.graph.located_yaml import YMap
from umbra.runtime.graph.names import (
    endpoint_problem,
    key_prefix_problem,
    plain_beyond_host,
)
from umbra.runtime.graph.parse_base import ParserBase, _kind
from umbra.runtime.graph.spec import (
    LinkSettings,
)

LINK_KEYS = ("prefix", "listen", "connect", "zenoh_config", "dispatch")
DISPATCH_MODES = ("inline", "loop")


class LinksParser(ParserBase):
    """``links:``."""

    def links(self, doc: YMap) -> LinkSettings:
        if "links" not in doc:
            return LinkSettings()
        section = self.expect_map(doc["links"], doc.val_loc["links"], "`links`")
        if section is None:
            return LinkSettings()
        self.unknown_keys(section, LINK_KEYS, "`links`")
        settings = LinkSettings(loc=section.loc)
        for key in ("listen", "connect"):
            value = section.get(key, [])
            if isinstance(value, str):
                value = [value]
            if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
                self.error(
                    section.val_loc[key],
                    f"`links.{key}` must be endpoint strings "
                    f"like `tcp/127.0.0.1:7447`, found {_kind(value)}",
                )
                continue
            where = section.val_loc.get(key, section.loc)
            item_locs = getattr(value, "item_loc", None) or [where] * len(value)
            bad = [(v, loc) for v, loc in zip(value, item_locs, strict=True) if endpoint_problem(v)]
            for endpoint, loc in bad:
                self.error(loc, f"`links.{key}`: {endpoint_problem(endpoint)}")
            exposed = [
                (v, loc)
                for v, loc in zip(value, item_locs, strict=True)
                if not endpoint_problem(v) and plain_beyond_host(v)
            ]
            for endpoint, loc in exposed:
                self.error(
                    loc,
                    f"`links.{key}`: `{endpoint}` is reachable beyond this host without TLS, "
                    "where anyone who reaches it could drive the graph",
                    "use `tls/` endpoints with the keys of `umbra keys GRAPH --out keys/` "
                    "(`links.zenoh_config: keys/`); plain TCP beyond loopback only on the "
                    "command line, with --listen/--connect and --insecure",
                )
            bad += exposed
            if not bad:
                setattr(settings, key, list(value))
        for key in ("prefix", "zenoh_config"):
            if key in section:
                if not isinstance(section[key], str):
                    self.error(section.val_loc[key], f"`links.{key}` must be a string")
                elif key == "prefix" and key_prefix_problem(section[key]):
                    self.error(
                        section.val_loc[key], f"`links.prefix`: {key_prefix_problem(section[key])}"
                    )
                else:
                    setattr(settings, key, section[key])
                    if key == "zenoh_config":
                        settings.zenoh_config_loc = section.val_loc[key]
        if "dispatch" in section:
            value = section["dispatch"]
            if value not in DISPATCH_MODES:
                self.error(
                    section.val_loc["dispatch"],
                    f"`links.dispatch` must be one of {', '.join(DISPATCH_MODES)}, "
                    f"found {_kind(value)}",
                )
            else:
                settings.dispatch = value
        return settings
