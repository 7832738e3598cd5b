"""Load a DH table from a YAML file or a plain dict (the user edge: degrees allowed, named so).

Format::

    name: puma560            # optional, default "arm"
    joints:                  # in order from the base
      - name: j1             # required, unique
        type: revolute       # revolute (default) or prismatic
        d: 0.67183           # metres (default 0)
        a: 0.0               # metres (default 0)
        alpha_deg: 90        # link twist: alpha (rad) or alpha_deg
        theta_deg: 0         # constant joint angle offset: theta (rad) or theta_deg
        limits_deg: [-160, 160]   # limits (rad, or m for prismatic) or limits_deg (revolute)
        max_rate_deg: 80     # rate limit: max_rate (rad/s or m/s) or max_rate_deg (deg/s)

Every problem raises :class:`DHError` whose message names the place: ``FILE:LINE: error: ...``
for files, ``joints[2].alpha_deg: ...`` for dicts.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from umbra.connectors import safe_yaml, user_files
from umbra.connectors.errors import UserError
from umbra.connectors.yaml_lines import node_lines as _node_lines
from umbra.modules.arm.dh import DHError, DHJoint, DHTable

_JOINT_KEYS = {
    "name",
    "type",
    "d",
    "a",
    "alpha",
    "alpha_deg",
    "theta",
    "theta_deg",
    "limits",
    "limits_deg",
    "max_rate",
    "max_rate_deg",
}
_TOP_KEYS = {"name", "joints"}

Path_ = tuple[str | int, ...]


def _path_text(path: Path_) -> str:
    text = ""
    for part in path:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else part)
    return text or "<top level>"


class _Where:
    """Turns a key path into a location prefix (file line numbers when known)."""

    def __init__(self, source: str | None, lines: dict[Path_, int]) -> None:
        self.source = source
        self.lines = lines

    def error(self, path: Path_, message: str) -> DHError:
        if self.source is None:
            return DHError(f"{_path_text(path)}: {message}")
        probe = path
        while probe not in self.lines and probe:
            probe = probe[:-1]
        line = self.lines.get(probe, 1)
        return DHError(f"{self.source}:{line}: error: {_path_text(path)}: {message}")


def _number(where: _Where, path: Path_, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise where.error(path, f"expected a number, found {value!r}")
    if not math.isfinite(value):
        raise where.error(path, f"expected a finite number, found {value!r}")
    return float(value)


def _pick_angle(where: _Where, path: Path_, spec: Mapping[str, Any], key: str) -> float:
    if key in spec and f"{key}_deg" in spec:
        raise where.error((*path, key), f"give {key} (rad) or {key}_deg, not both")
    if f"{key}_deg" in spec:
        return math.radians(_number(where, (*path, f"{key}_deg"), spec[f"{key}_deg"]))
    return _number(where, (*path, key), spec.get(key, 0.0))


def _limits(where: _Where, path: Path_, spec: Mapping[str, Any], kind: str) -> tuple[float, float]:
    if "limits" in spec and "limits_deg" in spec:
        raise where.error((*path, "limits"), "give limits or limits_deg, not both")
    key = "limits_deg" if "limits_deg" in spec else "limits"
    if key not in spec:
        return -math.inf, math.inf
    if key == "limits_deg" and kind == "prismatic":
        raise where.error((*path, key), "a prismatic joint takes limits in metres (limits)")
    value = spec[key]
    if not isinstance(value, list | tuple) or len(value) != 2:
        raise where.error((*path, key), f"expected [min, max], found {value!r}")
    low, high = (_number(where, (*path, key, i), v) for i, v in enumerate(value))
    if not low < high:
        raise where.error((*path, key), f"expected min < max, found [{low}, {high}]")
    return (math.radians(low), math.radians(high)) if key == "limits_deg" else (low, high)


def _max_rate(where: _Where, path: Path_, spec: Mapping[str, Any], kind: str) -> float:
    if "max_rate" in spec and "max_rate_deg" in spec:
        raise where.error((*path, "max_rate"), "give max_rate or max_rate_deg, not both")
    if "max_rate_deg" in spec:
        if kind == "prismatic":
            raise where.error((*path, "max_rate_deg"), "a prismatic joint takes max_rate (m/s)")
        rate = math.radians(_number(where, (*path, "max_rate_deg"), spec["max_rate_deg"]))
    elif "max_rate" in spec:
        rate = _number(where, (*path, "max_rate"), spec["max_rate"])
    else:
        return math.inf
    if rate <= 0:
        raise where.error((*path, "max_rate"), f"expected a positive rate, found {rate}")
    return rate


def _joint(where: _Where, index: int, spec: Any) -> DHJoint:
    path: Path_ = ("joints", index)
    if not isinstance(spec, Mapping):
        raise where.error(path, f"expected a mapping of DH values, found {spec!r}")
    unknown = sorted(set(spec) - _JOINT_KEYS)
    if unknown:
        raise where.error(
            (*path, str(unknown[0])),
            f"unknown key {unknown[0]!r}; expected one of {sorted(_JOINT_KEYS)}",
        )
    name = spec.get("name")
    if not isinstance(name, str) or not name:
        raise where.error((*path, "name"), f"expected a joint name, found {name!r}")
    kind = spec.get("type", "revolute")
    if kind not in ("revolute", "prismatic"):
        raise where.error((*path, "type"), f"expected revolute or prismatic, found {kind!r}")
    q_min, q_max = _limits(where, path, spec, kind)
    return DHJoint(
        name=name,
        kind=kind,
        d=_number(where, (*path, "d"), spec.get("d", 0.0)),
        a=_number(where, (*path, "a"), spec.get("a", 0.0)),
        alpha=_pick_angle(where, path, spec, "alpha"),
        theta=_pick_angle(where, path, spec, "theta"),
        q_min=q_min,
        q_max=q_max,
        qd_max=_max_rate(where, path, spec, kind),
    )


def _table(data: Any, where: _Where) -> DHTable:
    if not isinstance(data, Mapping):
        raise where.error((), f"expected a mapping with 'joints', found {type(data).__name__}")
    unknown = sorted(set(data) - _TOP_KEYS)
    if unknown:
        raise where.error((str(unknown[0]),), f"unknown key; expected one of {sorted(_TOP_KEYS)}")
    name = data.get("name", "arm")
    if not isinstance(name, str) or not name:
        raise where.error(("name",), f"expected an arm name, found {name!r}")
    joints = data.get("joints")
    if not isinstance(joints, list) or not joints:
        raise where.error(("joints",), f"expected a non-empty list of joints, found {joints!r}")
    parsed = [_joint(where, i, spec) for i, spec in enumerate(joints)]
    seen: dict[str, int] = {}
    for i, joint in enumerate(parsed):
        if joint.name in seen:
            raise where.error(
                ("joints", i, "name"),
                f"joint name {joint.name!r} already used by joints[{seen[joint.name]}]",
            )
        seen[joint.name] = i
    try:
        return DHTable(joints=tuple(parsed), name=name)
    except DHError as exc:  # pragma: no cover - every case is caught above
        raise where.error(("joints",), str(exc)) from exc


def dh_table_from_dict(data: Mapping[str, Any]) -> DHTable:
    """Build a :class:`DHTable` from a dict in the format above; errors name the key path."""
    return _table(data, _Where(None, {}))


def load_dh_table(path: str | Path) -> DHTable:
    """Load a DH table from a YAML file; errors read ``FILE:LINE: error: ...``."""
    try:  # a regular file of bounded size, UTF-8
        text = user_files.read_text(path, "DH file")
    except UserError as exc:
        raise DHError(str(exc)) from None
    return dh_table_from_yaml_text(text, str(path))


def dh_table_from_yaml_text(text: str, source: str) -> DHTable:
    """Parse DH table YAML ``text``; errors read ``SOURCE:LINE: error: ...``."""
    try:  # bounded depth and aliases, no duplicate keys, bad values at their line
        node, data = safe_yaml.load(text, source)
    except UserError as exc:
        raise DHError(str(exc)) from None
    lines: dict[Path_, int] = {}
    if node is not None:
        _node_lines(node, (), lines)
    return _table(data, _Where(source, lines))
