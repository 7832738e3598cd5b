"""The graph file's ``processes:`` (and their settings) and ``frames:`` sections."""

from __future__ import annotations

import math

import numpy as np

from umbra.connectors.errors import Location
from umbra.connectors.frames import NAME_RE, transform_from_xyz_rpy  # one rule for every graph name
from umbra.runtime.graph.located_yaml import YList, YMap
from umbra.runtime.graph.parse_base import ParserBase, _kind
from umbra.runtime.graph.spec import (
    GraphSpec,
    StaticFrameSpec,
)
from umbra.runtime.realtime import NO_CONSTRAINT_US, is_latency_us
from umbra.runtime.rt_priority import MAX_NICE, MAX_PRIORITY, MIN_PRIORITY, is_nice, is_priority

PROCESS_KEYS = ("cpu_latency_us", "realtime_priority", "nice")


class ProcessesParser(ParserBase):
    """``processes:`` and ``frames:``."""

    def processes(self, doc: YMap, spec: GraphSpec) -> dict[str, Location]:
        if "processes" not in doc:
            return {}
        section = self.expect_map(doc["processes"], doc.val_loc["processes"], "`processes`")
        if section is None:
            return {}
        out: dict[str, Location] = {}
        for name, body in section.items():
            if not isinstance(name, str) or not NAME_RE.match(name):
                self.error(
                    section.key_loc[name], f"process name must be an identifier, found {name!r}"
                )
                continue
            if body is not None and not isinstance(body, YMap):
                self.error(
                    section.val_loc[name],
                    f"process `{name}` must map to {{}} or its settings, found {_kind(body)}",
                )
            elif body is not None:
                self.process_settings(name, body, spec)
            out[name] = section.key_loc[name]
        return out

    def process_settings(self, name: str, body: YMap, spec: GraphSpec) -> None:
        self.unknown_keys(body, PROCESS_KEYS, f"process `{name}`")
        settings = (  # key, the check, what it must be, where the spec keeps it
            (
                "cpu_latency_us",
                is_latency_us,
                f"a whole number of microseconds from 0 to {NO_CONSTRAINT_US}",
                spec.cpu_latency_us,
            ),
            (
                "realtime_priority",
                is_priority,
                f"a whole number from {MIN_PRIORITY} to {MAX_PRIORITY} (SCHED_FIFO)",
                spec.realtime_priority,
            ),
            (
                "nice",
                is_nice,
                f"a whole number from 0 to {MAX_NICE} (the process gives way: SCHED_BATCH)",
                spec.nice,
            ),
        )
        for key, valid, expected, into in settings:
            if key not in body:
                continue
            value = body[key]
            if valid(value):
                into[name] = value
            else:
                self.error(
                    body.val_loc[key],
                    f"{key} of process `{name}` must be {expected}, found {value!r}",
                )

    def frames(self, doc: YMap) -> list[StaticFrameSpec]:
        if "frames" not in doc:
            return []
        section = self.expect_map(doc["frames"], doc.val_loc["frames"], "`frames`")
        if section is None:
            return []
        out = []
        for key, body in section.items():
            loc = section.key_loc[key]
            parts = str(key).split("->")
            if len(parts) != 2 or not all(NAME_RE.match(p.strip()) for p in parts):
                self.error(loc, f"a static frame is written `parent->child`, found `{key}`")
                continue
            body_map = self.expect_map(body, section.val_loc[key], f"frame `{key}`")
            if body_map is None:
                continue
            self.unknown_keys(body_map, ("xyz", "rpy_deg"), f"frame `{key}`")
            xyz = self.vector3(body_map, "xyz", f"frame `{key}`")
            rpy = self.vector3(body_map, "rpy_deg", f"frame `{key}`")
            if xyz is None or rpy is None:
                continue
            T = transform_from_xyz_rpy(xyz, list(np.radians(rpy)))
            out.append(StaticFrameSpec(parts[0].strip(), parts[1].strip(), T, loc))
        return out

    def vector3(self, body: YMap, key: str, what: str) -> list[float] | None:
        if key not in body:
            return [0.0, 0.0, 0.0]
        value = body[key]
        ok = (
            isinstance(value, YList)
            and len(value) == 3
            and all(
                isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
                for v in value
            )
        )
        if not ok:
            self.error(body.val_loc[key], f"`{key}` of {what} must be 3 numbers, found {value!r}")
            return None
        return [float(v) for v in value]
