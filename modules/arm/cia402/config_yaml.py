"""Load a CANopen arm's settings from YAML (WOLVERINE_JNTS's `canopen_config` file).

Format (times in seconds, rates in rad/s; only `bus` and `joints` are required)::

    bus: {interface: socketcan, channel: can0, bitrate: 500000}
    simulate: false          # true: simulated CiA 402 drives in this process (virtual bus)
    eds: ""                  # drives' EDS, relative to this file; "" = the built-in minimal one;
                             # it must have the objects of eds_needs.py (checked at load)
    configure_pdos: true     # write the PDO mapping (true) or use the drives' own (false)
    sync_period: 0.01        # SYNC period = servo period of the drives
    heartbeat_period: 0.05   # written to each drive's 0x1017
    heartbeat_timeout: 0.2   # a drive whose heartbeat is older is lost
    feedback_timeout: 0.2    # a drive whose TPDO is older is lost
    command_timeout: 0.5     # targets drop to zero without a command for this long (null: never)
    master_node_id: 127      # the master's own heartbeat (0x700 + id)
    master_heartbeat_period: 0.02   # the master's heartbeat, sent by its monitor thread
    drive_heartbeat_timeout: 0.2    # drives' watchdog on that heartbeat (0x1016; null: none);
                             # 2 x the period .. 1 s
    abort_connection_option: 3      # what a drive does then (0x6007): 1 fault, 2 disable
                             # voltage, 3 quick stop
    acceleration: null       # rad/s^2: profile acceleration / deceleration written to the drives
    quick_stop_deceleration: null   # rad/s^2
    joints:                  # by the arm's joint names (any order)
      - {name: j1, node_id: 1, counts_per_rad: 10000}
      - {name: j2, node_id: 2, counts_per_turn: 131072, zero_counts: -5000}

`counts_per_rad` (or `counts_per_turn`, per joint revolution) includes the gear ratio; for a
prismatic joint `counts_per_rad` means counts per metre. `zero_counts` is the position actual
value at joint angle 0. Every problem raises `Cia402ConfigError` reading
`FILE:LINE: error: key.path: ...`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from umbra.connectors import safe_yaml, user_files
from umbra.connectors.errors import UserError
from umbra.connectors.yaml_lines import node_lines as _node_lines
from umbra.modules.arm.cia402.config import (
    BusSpec,
    Cia402ArmConfig,
    Cia402ConfigError,
    JointDrive,
)
from umbra.modules.arm.cia402.eds_needs import eds_file_problem
from umbra.modules.arm.cia402.objects import EDS_PATH

KeyPath = tuple[str | int, ...]

_TOP_KEYS = {
    "bus",
    "simulate",
    "eds",
    "configure_pdos",
    "sync_period",
    "heartbeat_period",
    "heartbeat_timeout",
    "feedback_timeout",
    "command_timeout",
    "acceleration",
    "quick_stop_deceleration",
    "master_node_id",
    "master_heartbeat_period",
    "drive_heartbeat_timeout",
    "abort_connection_option",
    "joints",
}
_BUS_KEYS = {"interface", "channel", "bitrate"}
_JOINT_KEYS = {"name", "node_id", "counts_per_rad", "counts_per_turn", "zero_counts"}
_TIMES = {
    "sync_period": "sync_period_s",
    "heartbeat_period": "heartbeat_period_s",
    "heartbeat_timeout": "heartbeat_timeout_s",
    "feedback_timeout": "feedback_timeout_s",
    "master_heartbeat_period": "master_heartbeat_period_s",
}


@dataclass(frozen=True)
class CanopenSettings:
    """The arm's settings, and whether to run simulated drives for it."""

    arm: Cia402ArmConfig
    simulate: bool = False


class _Where:
    """Key path to `FILE:LINE: error: path:` prefixes."""

    def __init__(self, source: str, lines: dict[KeyPath, int]) -> None:
        self.source = source
        self.lines = lines

    def error(self, path: KeyPath, message: str) -> Cia402ConfigError:
        probe = path
        while probe and probe not in self.lines:
            probe = probe[:-1]
        line = self.lines.get(probe, 1)
        text = ""
        for part in path:
            text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else part)
        return Cia402ConfigError(f"{self.source}:{line}: error: {text or '<top level>'}: {message}")


def _mapping(where: _Where, path: KeyPath, value: Any, keys: set[str], what: str) -> Mapping:
    if not isinstance(value, Mapping):
        raise where.error(path, f"expected a mapping ({what}), found {value!r}")
    unknown = sorted(str(k) for k in set(value) - keys)
    if unknown:
        raise where.error(
            (*path, unknown[0]), f"unknown key {unknown[0]!r}; expected one of {sorted(keys)}"
        )
    return value


def _number(where: _Where, path: KeyPath, value: Any, *, positive: bool = True) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise where.error(path, f"expected a finite number, found {value!r}")
    if positive and value <= 0:
        raise where.error(path, f"expected a positive number, found {value!r}")
    return float(value)


def _integer(where: _Where, path: KeyPath, value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise where.error(path, f"expected an integer, found {value!r}")
    return value


def _joint(where: _Where, index: int, spec: Any) -> JointDrive:
    path: KeyPath = ("joints", index)
    spec = _mapping(where, path, spec, _JOINT_KEYS, "name, node_id, counts_per_rad")
    for key in ("name", "node_id"):
        if key not in spec:
            raise where.error(path, f"missing {key!r}")
    if ("counts_per_rad" in spec) == ("counts_per_turn" in spec):
        raise where.error(path, "give exactly one of 'counts_per_rad' and 'counts_per_turn'")
    if "counts_per_rad" in spec:
        scale = _number(where, (*path, "counts_per_rad"), spec["counts_per_rad"], positive=False)
    else:
        turn = _number(where, (*path, "counts_per_turn"), spec["counts_per_turn"], positive=False)
        scale = turn / (2 * math.pi)
    name = spec["name"]
    if not isinstance(name, str) or not name:
        raise where.error((*path, "name"), f"expected a joint name, found {name!r}")
    try:
        return JointDrive(
            name=name,
            node_id=_integer(where, (*path, "node_id"), spec["node_id"]),
            counts_per_rad=scale,
            zero_counts=_integer(where, (*path, "zero_counts"), spec.get("zero_counts", 0)),
        )
    except Cia402ConfigError as exc:
        raise where.error(path, str(exc)) from None


def settings_from_yaml_text(text: str, source: str, base_dir: Path) -> CanopenSettings:
    """Parse the format above; `source` names the file in errors; `eds` is under `base_dir`."""
    where = _Where(source, {})
    try:  # bounded depth and aliases, no duplicate keys, every bad value at its line
        node, data = safe_yaml.load(text, source)
    except UserError as exc:
        raise Cia402ConfigError(str(exc)) from None
    if node is not None:
        _node_lines(node, (), where.lines)
    data = _mapping(where, (), data, _TOP_KEYS, "bus, joints, ...")
    for key in ("bus", "joints"):
        if key not in data:
            raise where.error((), f"missing {key!r}")
    bus = _mapping(where, ("bus",), data["bus"], _BUS_KEYS, "interface, channel, bitrate")
    try:
        bus_spec = BusSpec(
            interface=bus.get("interface", ""),
            channel=str(bus.get("channel", "")),
            bitrate=bus.get("bitrate", 500_000),
        )
    except Cia402ConfigError as exc:
        raise where.error(("bus",), str(exc)) from None
    joints = data["joints"]
    if not isinstance(joints, list) or not joints:
        raise where.error(("joints",), f"expected a non-empty list of joints, found {joints!r}")
    settings: dict[str, Any] = {
        "bus": bus_spec,
        "joints": tuple(_joint(where, i, spec) for i, spec in enumerate(joints)),
    }
    for key, field_name in _TIMES.items():
        if key in data:
            settings[field_name] = _number(where, (key,), data[key])
    if data.get("command_timeout", 0.5) is not None:
        settings["command_timeout_s"] = _number(
            where, ("command_timeout",), data.get("command_timeout", 0.5)
        )
    else:
        settings["command_timeout_s"] = None
    if "drive_heartbeat_timeout" in data:
        value = data["drive_heartbeat_timeout"]
        settings["drive_heartbeat_timeout_s"] = (
            None if value is None else _number(where, ("drive_heartbeat_timeout",), value)
        )
    for key in ("master_node_id", "abort_connection_option"):
        if key in data:
            settings[key] = _integer(where, (key,), data[key])
    for key in ("acceleration", "quick_stop_deceleration"):
        if data.get(key) is not None:
            settings[f"{key}_rad_s2"] = _number(where, (key,), data[key])
    for key in ("configure_pdos", "simulate"):
        if not isinstance(data.get(key, False), bool):
            raise where.error((key,), f"expected true or false, found {data[key]!r}")
    settings["configure_pdos"] = data.get("configure_pdos", True)
    eds = data.get("eds") or ""
    if not isinstance(eds, str):
        raise where.error(("eds",), f"expected a file name, found {eds!r}")
    settings["eds"] = (base_dir / eds) if eds else EDS_PATH
    if eds and not settings["eds"].is_file():
        raise where.error(("eds",), f"EDS file {settings['eds']} not found")
    simulate = bool(data.get("simulate", False))
    if simulate and bus_spec.interface != "virtual":
        raise where.error(
            ("simulate",),
            f"simulated drives need bus interface 'virtual', found {bus_spec.interface!r}",
        )
    watch = settings.get("drive_heartbeat_timeout_s", Cia402ArmConfig.drive_heartbeat_timeout_s)
    problem = eds_file_problem(
        settings["eds"],
        simulated=simulate,
        configure_pdos=settings["configure_pdos"],
        drive_watch=watch is not None,
    )
    if problem:
        raise where.error(("eds",) if eds else ("simulate",), problem)
    try:
        arm = Cia402ArmConfig(**settings)
    except Cia402ConfigError as exc:
        raise where.error((), str(exc)) from None
    return CanopenSettings(arm=arm, simulate=simulate)


def load_canopen_settings(path: str | Path) -> CanopenSettings:
    """Load the YAML file at `path`; errors read `FILE:LINE: error: ...`."""
    file = Path(path)
    try:
        text = user_files.read_text(file, "CANopen settings file")
    except UserError as exc:
        raise Cia402ConfigError(str(exc)) from None
    return settings_from_yaml_text(text, str(file), file.parent)
