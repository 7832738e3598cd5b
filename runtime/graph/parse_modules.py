"""The graph file's ``modules:`` and ``connections:`` sections."""

from __future__ import annotations

import re
from typing import Any

from umbra.connectors.errors import Location
from umbra.connectors.frames import NAME_RE  # one rule for every graph name
from umbra.connectors.safe_yaml import boolean_hint
from umbra.runtime.graph.located_yaml import YList, YMap
from umbra.runtime.graph.parse_base import ParserBase, _kind, _plain
from umbra.runtime.graph.spec import (
    DEFAULT_PROCESS,
    ConnectionSpec,
    Endpoint,
    ModuleSpec,
)
from umbra.runtime.hints import did_you_mean

MODULE_KEYS = ("type", "process", "rate", "trigger", "params", "description")
CONNECTION_RE = re.compile(
    r"^\s*(?P<sm>[^.\s]+)\.(?P<sp>[^\s]+)\s*(?P<arrow>->|~>)\s*(?P<dm>[^.\s]+)\.(?P<dp>[^\s]+)\s*$"
)


class ModulesParser(ParserBase):
    """``modules:`` and ``connections:``."""

    def modules(self, doc: YMap, processes: dict[str, Location]) -> dict[str, ModuleSpec]:
        if "modules" not in doc:
            self.error(doc.loc, "missing `modules:` (a mapping of module name -> {type: ..., ...})")
            return {}
        section = self.expect_map(doc["modules"], doc.val_loc["modules"], "`modules`")
        if section is None:
            return {}
        if not section:
            self.error(
                doc.val_loc["modules"], "`modules` is empty: a graph needs at least one module"
            )
        out: dict[str, ModuleSpec] = {}
        for name, body in section.items():
            key_loc = section.key_loc[name]
            if not isinstance(name, str) or not NAME_RE.match(name):
                self.error(key_loc, f"module name must be an identifier, found {name!r}")
                continue
            body_map = self.expect_map(body, section.val_loc[name], f"module `{name}`")
            module = None if body_map is None else self.module(name, body_map, key_loc, processes)
            if module is not None:
                out[name] = module
            else:
                self.broken.add(str(name))
        return out

    def module(
        self, name: str, body: YMap, key_loc: Location, processes: dict[str, Location]
    ) -> ModuleSpec | None:
        self.unknown_keys(body, MODULE_KEYS, f"module `{name}`")
        if "type" not in body or not isinstance(body["type"], str):
            self.error(
                body.val_loc.get("type", key_loc),
                f"module `{name}` needs `type: TYPE_NAME`{boolean_hint(body.get('type'))}",
            )
            return None
        process = DEFAULT_PROCESS
        process_loc = body.val_loc.get("process", key_loc)
        if "process" in body:
            process = str(body["process"])
            if isinstance(body["process"], bool):
                self.error(
                    process_loc,
                    f"process of module `{name}` must be a process name, found "
                    f"{body['process']!r}{boolean_hint(body['process'])}",
                )
            elif process not in processes:
                known = list(processes) or [DEFAULT_PROCESS]
                extra = "" if processes else " (the graph declares no `processes:`)"
                self.error(
                    process_loc,
                    f"unknown process `{process}` for module `{name}`{extra}"
                    f"{did_you_mean(process, known)}",
                )
        elif processes:
            self.error(key_loc, f"module `{name}` needs `process:` (one of {', '.join(processes)})")
        rate = None
        if "rate" in body:
            rate = self.rate(body["rate"], body.val_loc["rate"], name)
        trigger = None
        trigger_loc = body.val_loc.get("trigger", key_loc)
        if "trigger" in body:
            value = body["trigger"]
            if isinstance(value, str):
                trigger = [value]
            elif isinstance(value, YList) and all(isinstance(v, str) for v in value) and value:
                trigger = list(value)
            else:
                self.error(
                    trigger_loc, f"`trigger` must name input(s) of `{name}`, found {value!r}"
                )
        params: dict[str, Any] = {}
        params_loc = body.val_loc.get("params", key_loc)
        key_locs: dict[str, Location] = {}
        val_locs: dict[str, Location] = {}
        if "params" in body and body["params"] is not None:
            pm = self.expect_map(body["params"], params_loc, f"`params` of module `{name}`")
            if pm is not None:
                params = {str(k): _plain(v) for k, v in pm.items()}
                key_locs = {str(k): pm.key_loc[k] for k in pm}
                val_locs = {str(k): pm.val_loc[k] for k in pm}
        return ModuleSpec(
            name=name,
            type=body["type"],
            process=process,
            rate=rate,
            trigger=trigger,
            params=params,
            loc=key_loc,
            type_loc=body.val_loc["type"],
            process_loc=process_loc,
            trigger_loc=trigger_loc,
            params_loc=params_loc,
            rate_loc=body.val_loc.get("rate"),
            param_key_loc=key_locs,
            param_val_loc=val_locs,
        )

    def connections(self, doc: YMap) -> list[ConnectionSpec]:
        if "connections" not in doc or doc["connections"] is None:
            return []
        section = doc["connections"]
        if not isinstance(section, YList):
            self.error(
                doc.val_loc["connections"], f"`connections` must be a list, found {_kind(section)}"
            )
            return []
        out = []
        for item, loc in zip(section, section.item_loc, strict=True):
            conn = self.connection(item, loc)
            if conn is not None:
                out.append(conn)
        return out

    def connection(self, item: Any, loc: Location) -> ConnectionSpec | None:
        if isinstance(item, YMap):
            self.unknown_keys(item, ("from", "to", "delayed"), "a connection")
            src = self.endpoint(item.get("from"), item.val_loc.get("from", loc), "from")
            dst = self.endpoint(item.get("to"), item.val_loc.get("to", loc), "to")
            delayed = item.get("delayed", False)
            if not isinstance(delayed, bool):
                self.error(
                    item.val_loc["delayed"], f"`delayed` must be true or false, found {delayed!r}"
                )
                delayed = False
            if src is None or dst is None:
                return None
            return ConnectionSpec(src, dst, delayed, loc)
        if not isinstance(item, str):
            self.error(
                loc, f"a connection is written `module.output -> module.input`, found {_kind(item)}"
            )
            return None
        match = CONNECTION_RE.match(item)
        if match is None:
            self.error(
                loc,
                f"a connection is written `module.output -> module.input` "
                f"(or `~>` when delayed), found `{item}`",
            )
            return None
        lead = len(item) - len(item.lstrip())
        src = Endpoint(
            match["sm"], match["sp"], self.col_of(loc, lead), self.col_of(loc, match.start("sp"))
        )
        dst = Endpoint(
            match["dm"],
            match["dp"],
            self.col_of(loc, match.start("dm")),
            self.col_of(loc, match.start("dp")),
        )
        return ConnectionSpec(src, dst, match["arrow"] == "~>", loc)

    def endpoint(self, value: Any, loc: Location, what: str) -> Endpoint | None:
        if not isinstance(value, str) or value.count(".") != 1 or not all(value.split(".")):
            self.error(loc, f"`{what}` must be `module.port`, found {value!r}")
            return None
        module, port = value.split(".")
        return Endpoint(module, port, loc, self.col_of(loc, len(module) + 1))
