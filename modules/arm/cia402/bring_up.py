"""Bringing one CiA 402 drive up by SDO: identity, PDO mapping, mode, power state machine.

These steps block (each SDO is a request and a reply) and run only while the arm starts,
never in the servo step. Every failure raises `DriveStartError` naming the drive and the
step.

PDO layout written when the master configures the PDOs (all synchronous, type 1):

    RPDO1  controlword 0x6040 (16) | target velocity 0x60FF (32)
    TPDO1  statusword 0x6041 (16) | position actual 0x6064 (32) | error code 0x603F (16)
    TPDO2  velocity actual 0x606C (32) | modes of operation display 0x6061 (8)

Other PDOs of the drive are disabled. Objects absent from the drive's object dictionary
(0x603F, 0x6061) are left out.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TypeVar

import canopen
from canopen.pdo import PdoMap
from canopen.sdo import SdoAbortedError, SdoCommunicationError

from umbra.modules.arm.cia402 import objects as obj
from umbra.modules.arm.cia402.canopen_types import maps_of, node_id_of
from umbra.modules.arm.cia402.drive_watchdog import consumer_entry
from umbra.modules.arm.cia402.state_machine import (
    Command,
    State,
    StatuswordError,
    command_towards_operation_enabled,
    controlword_for,
    state_from_statusword,
)
from umbra.modules.arm.cia402.status import describe_error_code

T = TypeVar("T")

RPDO_OBJECTS_FILLED = frozenset({obj.CONTROLWORD, obj.TARGET_VELOCITY, obj.MODES_OF_OPERATION})
TPDO_OBJECTS_REQUIRED = (obj.STATUSWORD, obj.POSITION_ACTUAL, obj.VELOCITY_ACTUAL)
SYNCHRONOUS_EVERY_SYNC = 1


class DriveStartError(RuntimeError):
    """A drive could not be brought to Operation enabled in profile velocity mode."""


@dataclass(frozen=True)
class PdoLayout:
    """The PDOs a running drive is served with: RPDOs to fill, TPDOs to listen to."""

    rpdos: tuple[PdoMap, ...]
    tpdos: tuple[PdoMap, ...]


def sdo_step(label: str, what: str, action: Callable[[], T]) -> T:
    """Run one SDO action; turn SDO failures into a DriveStartError naming drive and step."""
    try:
        return action()
    except SdoCommunicationError as exc:
        raise DriveStartError(
            f"{label}: no SDO answer while trying to {what} ({exc}); is the drive powered, "
            f"on this bus, and is its node id right?"
        ) from exc
    except SdoAbortedError as exc:
        raise DriveStartError(f"{label}: drive refused to {what}: {exc}") from exc


def check_identity(node: canopen.RemoteNode, label: str) -> None:
    """The node must be a CiA 402 device that supports profile velocity mode."""
    device_type = sdo_step(label, "read device type 0x1000", lambda: node.sdo[obj.DEVICE_TYPE].raw)
    if device_type & 0xFFFF != obj.DEVICE_PROFILE_402:
        raise DriveStartError(
            f"{label}: not a CiA 402 drive: device type 0x{device_type:08X} "
            f"(expected profile {obj.DEVICE_PROFILE_402} in the low 16 bits)"
        )
    if obj.SUPPORTED_DRIVE_MODES in node.object_dictionary:
        modes = sdo_step(
            label,
            "read supported drive modes 0x6502",
            lambda: node.sdo[obj.SUPPORTED_DRIVE_MODES].raw,
        )
        if not modes & obj.SUPPORTED_MODE_PV_BIT:
            raise DriveStartError(
                f"{label}: drive does not support profile velocity mode "
                f"(supported drive modes 0x{modes:08X})"
            )


def configure_pdos(node: canopen.RemoteNode, label: str) -> PdoLayout:
    """Write the layout of the module docstring to the drive (NMT PRE-OPERATIONAL)."""
    od = node.object_dictionary
    rpdo_maps, tpdo_maps = maps_of(node.rpdo), maps_of(node.tpdo)
    if len(rpdo_maps) < 1 or len(tpdo_maps) < 2:
        raise DriveStartError(
            f"{label}: object dictionary has {len(rpdo_maps)} RPDO(s) and "
            f"{len(tpdo_maps)} TPDO(s); the master needs at least 1 and 2"
        )
    node.rpdo.read(from_od=True)
    node.tpdo.read(from_od=True)
    for pdo_map in (*rpdo_maps.values(), *tpdo_maps.values()):
        pdo_map.clear()
        pdo_map.enabled = False
    rpdo1, tpdo1, tpdo2 = rpdo_maps[1], tpdo_maps[1], tpdo_maps[2]
    layout: tuple[tuple[PdoMap, int, tuple[int, ...]], ...] = (
        (rpdo1, 0x200, (obj.CONTROLWORD, obj.TARGET_VELOCITY)),
        (tpdo1, 0x180, (obj.STATUSWORD, obj.POSITION_ACTUAL, obj.ERROR_CODE)),
        (tpdo2, 0x280, (obj.VELOCITY_ACTUAL, obj.MODES_OF_OPERATION_DISPLAY)),
    )
    for pdo_map, cob_base, indexes in layout:
        for index in indexes:
            if index in od:
                pdo_map.add_variable(index)
        pdo_map.cob_id = cob_base + node_id_of(node)
        pdo_map.trans_type = SYNCHRONOUS_EVERY_SYNC
        pdo_map.inhibit_time = None
        pdo_map.event_timer = None
        pdo_map.enabled = True
    sdo_step(label, "write its RPDO configuration", node.rpdo.save)
    sdo_step(label, "write its TPDO configuration", node.tpdo.save)
    return PdoLayout(rpdos=(rpdo1,), tpdos=(tpdo1, tpdo2))


def read_pdos(node: canopen.RemoteNode, label: str) -> PdoLayout:
    """Use the drive's own PDO mapping (read by SDO); check it carries what the master needs."""
    sdo_step(label, "read its RPDO configuration", node.rpdo.read)
    sdo_step(label, "read its TPDO configuration", node.tpdo.read)
    rpdos = tuple(
        m
        for m in maps_of(node.rpdo).values()
        if m.enabled and {v.index for v in m.map if v.length} & RPDO_OBJECTS_FILLED
    )
    tpdos = tuple(m for m in maps_of(node.tpdo).values() if m.enabled and m.map)
    rx = {v.index for m in rpdos for v in m.map if v.length}
    tx = {v.index for m in tpdos for v in m.map if v.length}
    missing_rx = [i for i in (obj.CONTROLWORD, obj.TARGET_VELOCITY) if i not in rx]
    missing_tx = [i for i in TPDO_OBJECTS_REQUIRED if i not in tx]
    if missing_rx or missing_tx:
        names = ", ".join(f"0x{i:04X}" for i in (*missing_rx, *missing_tx))
        raise DriveStartError(
            f"{label}: the drive's PDO mapping lacks {names}; map them or set configure_pdos"
        )
    extra = sorted(rx - RPDO_OBJECTS_FILLED)
    if extra:
        raise DriveStartError(
            f"{label}: its RPDOs also map {', '.join(f'0x{i:04X}' for i in extra)}, which the "
            f"master cannot fill; map only 0x6040, 0x60FF, 0x6060 or set configure_pdos"
        )
    return PdoLayout(rpdos=rpdos, tpdos=tpdos)


def read_state(node: canopen.RemoteNode, label: str) -> tuple[State, int]:
    """Power state and statusword, read by SDO."""
    word = sdo_step(label, "read statusword 0x6041", lambda: node.sdo[obj.STATUSWORD].raw)
    try:
        return state_from_statusword(word), word
    except StatuswordError as exc:
        raise DriveStartError(f"{label}: {exc}") from exc


def write_controlword(node: canopen.RemoteNode, label: str, command: Command) -> None:
    word = controlword_for(command)
    sdo_step(
        label,
        f"accept controlword 0x{word:04X} ({command.value})",
        lambda: setattr(node.sdo[obj.CONTROLWORD], "raw", word),
    )


def enable_operation(node: canopen.RemoteNode, label: str, timeout_s: float) -> None:
    """Walk the power state machine to Operation enabled (fault reset first if needed)."""
    deadline = time.monotonic() + timeout_s
    while True:
        state, word = read_state(node, label)
        if state is State.OPERATION_ENABLED:
            return
        if time.monotonic() > deadline:
            detail = ""
            if state in (State.FAULT, State.FAULT_REACTION_ACTIVE) and obj.ERROR_CODE in (
                node.object_dictionary
            ):
                code = sdo_step(
                    label, "read error code 0x603F", lambda: node.sdo[obj.ERROR_CODE].raw
                )
                detail = f", error code {describe_error_code(code)}"
            raise DriveStartError(
                f"{label}: did not reach operation enabled within {timeout_s} s: stuck in "
                f"{state.value!r} (statusword 0x{word:04X}{detail})"
            )
        command = command_towards_operation_enabled(state)
        if command is Command.FAULT_RESET:
            write_controlword(node, label, Command.DISABLE_VOLTAGE)  # bit 7 low before its edge
        if command is None:
            time.sleep(0.005)
        else:
            write_controlword(node, label, command)


def set_profile_velocity_mode(node: canopen.RemoteNode, label: str) -> None:
    """Zero target velocity, then modes of operation = 3 (profile velocity)."""
    sdo_step(
        label,
        "set target velocity 0x60FF to 0",
        lambda: setattr(node.sdo[obj.TARGET_VELOCITY], "raw", 0),
    )
    sdo_step(
        label,
        "switch to profile velocity mode (0x6060 = 3)",
        lambda: setattr(node.sdo[obj.MODES_OF_OPERATION], "raw", obj.PROFILE_VELOCITY_MODE),
    )


def check_mode_display(node: canopen.RemoteNode, label: str) -> None:
    """Modes of operation display (0x6061) must read profile velocity."""
    if obj.MODES_OF_OPERATION_DISPLAY not in node.object_dictionary:
        return
    mode = sdo_step(
        label,
        "read modes of operation display 0x6061",
        lambda: node.sdo[obj.MODES_OF_OPERATION_DISPLAY].raw,
    )
    if mode != obj.PROFILE_VELOCITY_MODE:
        raise DriveStartError(
            f"{label}: drive reports mode of operation {mode}, expected "
            f"{obj.PROFILE_VELOCITY_MODE} (profile velocity)"
        )


def configure_master_watch(
    node: canopen.RemoteNode, label: str, master_id: int, timeout_s: float, abort_option: int
) -> None:
    """The drive's watchdog on the master: heartbeat consumer entry 1 (0x1016) on the
    master's heartbeat, and its reaction (0x6007, where the drive has it) when that stops.
    The EDS has 0x1016 sub 1: the settings were refused without it (eds_needs.py)."""
    od = node.object_dictionary
    entry = consumer_entry(master_id, timeout_s)
    sdo_step(
        label,
        f"write heartbeat consumer 0x1016 sub 1 = 0x{entry:08X} "
        f"(node {master_id}, {round(timeout_s * 1000)} ms)",
        lambda: setattr(node.sdo[obj.CONSUMER_HEARTBEAT_TIME][1], "raw", entry),
    )
    if obj.ABORT_CONNECTION_OPTION_CODE in od:
        sdo_step(
            label,
            f"write abort connection option code 0x6007 = {abort_option}",
            lambda: setattr(node.sdo[obj.ABORT_CONNECTION_OPTION_CODE], "raw", abort_option),
        )


def write_parameter(node: canopen.RemoteNode, label: str, index: int, value: int) -> None:
    """Write an unsigned parameter such as an acceleration (counts/s^2)."""
    sdo_step(
        label,
        f"write 0x{index:04X} = {value}",
        lambda: setattr(node.sdo[index], "raw", value),
    )
