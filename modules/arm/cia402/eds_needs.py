"""The objects the CANopen master and the simulated drive need in a drive's object dictionary
(EDS), declared once, and the check of an EDS against them.

The master (network.py, bring_up.py, drive_setup.py) reads and writes these objects by SDO and
PDO through the EDS; the simulated drive (sim_drive.py, sim_drive_watch.py) serves them and reads
its own parameters from them in its bus and watch threads. An EDS that lacks one would fail deep
in a thread, or with a drive's "object does not exist" abort; :func:`eds_problem` says so when
the settings are made instead (config.py), naming every missing object and the file. Objects
used only where present (0x603F, 0x6061, 0x6502, the master's profile accelerations) are not
listed. Every object an EDS maps in its default PDO mappings must be in it too (both read them).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import canopen
from canopen.objectdictionary import ObjectDictionary, ODArray, ODVariable

from umbra.modules.arm.cia402 import objects as obj

MASTER = "master"
MASTER_PDOS = "master with configure_pdos"
MASTER_WATCH = "master with drive_heartbeat_timeout"
SIM = "simulated drive"


@dataclass(frozen=True)
class Needed:
    """An object (``subindex`` 0 for a variable) and who needs it."""

    index: int
    subindex: int
    name: str
    users: tuple[str, ...]

    def text(self) -> str:
        return f"0x{self.index:04X} sub {self.subindex} {self.name}"


def _entries(index: int, name: str, subs: range, users: tuple[str, ...]) -> tuple[Needed, ...]:
    return tuple(Needed(index, s, f"{name} sub {s}", users) for s in subs)


NEEDED: tuple[Needed, ...] = (
    Needed(obj.DEVICE_TYPE, 0, "Device type", (MASTER, SIM)),
    Needed(obj.PRODUCER_HEARTBEAT_TIME, 0, "Producer heartbeat time", (MASTER, SIM)),
    Needed(obj.CONSUMER_HEARTBEAT_TIME, 0, "Consumer heartbeat time (count)", (SIM,)),
    Needed(obj.CONSUMER_HEARTBEAT_TIME, 1, "Consumer heartbeat time", (MASTER_WATCH, SIM)),
    Needed(obj.ABORT_CONNECTION_OPTION_CODE, 0, "Abort connection option code", (SIM,)),
    Needed(obj.CONTROLWORD, 0, "Controlword", (MASTER, SIM)),
    Needed(obj.STATUSWORD, 0, "Statusword", (MASTER, SIM)),
    Needed(obj.QUICK_STOP_OPTION_CODE, 0, "Quick stop option code", (SIM,)),
    Needed(obj.MODES_OF_OPERATION, 0, "Modes of operation", (MASTER, SIM)),
    Needed(obj.POSITION_ACTUAL, 0, "Position actual value", (MASTER, SIM)),
    Needed(obj.VELOCITY_ACTUAL, 0, "Velocity actual value", (MASTER, SIM)),
    Needed(obj.PROFILE_ACCELERATION, 0, "Profile acceleration", (SIM,)),
    Needed(obj.PROFILE_DECELERATION, 0, "Profile deceleration", (SIM,)),
    Needed(obj.QUICK_STOP_DECELERATION, 0, "Quick stop deceleration", (SIM,)),
    Needed(obj.MAX_DECELERATION, 0, "Max deceleration", (SIM,)),
    Needed(obj.TARGET_VELOCITY, 0, "Target velocity", (MASTER, SIM)),
    Needed(obj.RPDO_COMM_FIRST, 1, "RPDO1 COB-ID", (MASTER_PDOS, SIM)),
    Needed(obj.RPDO_COMM_FIRST, 2, "RPDO1 transmission type", (MASTER_PDOS, SIM)),
    Needed(obj.RPDO_COMM_FIRST, obj.PDO_EVENT_TIMER_SUBINDEX, "RPDO1 event timer", (SIM,)),
    *_entries(obj.RPDO_MAP_FIRST, "RPDO1 mapping", range(3), (MASTER_PDOS, SIM)),
    Needed(obj.TPDO_COMM_FIRST, 1, "TPDO1 COB-ID", (MASTER_PDOS, SIM)),
    Needed(obj.TPDO_COMM_FIRST, 2, "TPDO1 transmission type", (MASTER_PDOS, SIM)),
    Needed(obj.TPDO_COMM_FIRST + 1, 1, "TPDO2 COB-ID", (MASTER_PDOS, SIM)),
    Needed(obj.TPDO_COMM_FIRST + 1, 2, "TPDO2 transmission type", (MASTER_PDOS, SIM)),
    *_entries(obj.TPDO_MAP_FIRST, "TPDO1 mapping", range(4), (MASTER_PDOS, SIM)),
    *_entries(obj.TPDO_MAP_FIRST + 1, "TPDO2 mapping", range(3), (MASTER_PDOS, SIM)),
)
"""What the master and the simulated drive read or write (mappings: the entries the master's
layout of bring_up.py fills; the simulated drive is set up by that master)."""


def users_of(*, simulated: bool, configure_pdos: bool, drive_watch: bool) -> frozenset[str]:
    """Who will use the EDS: the master always, with its optional parts, and the simulated
    drives when ``simulated``."""
    users = {MASTER}
    if configure_pdos:
        users.add(MASTER_PDOS)
    if drive_watch:
        users.add(MASTER_WATCH)
    if simulated:
        users.add(SIM)
    return frozenset(users)


def has_object(od: ObjectDictionary, index: int, subindex: int) -> bool:
    """Whether ``od`` has the object (an array's sub-indexes past its template count too)."""
    if index not in od:
        return False
    entry = od[index]
    if isinstance(entry, ODVariable):
        return subindex == 0
    if subindex in entry.subindices:
        return True
    return isinstance(entry, ODArray) and 0 < subindex < 256 and 1 in entry.subindices


def missing_objects(od: ObjectDictionary, users: frozenset[str]) -> list[str]:
    """The needed objects ``od`` lacks for ``users`` (index, subindex, name, who needs it),
    then the objects its own PDO mappings name that it lacks (and no need listed)."""
    missing = [
        need
        for need in NEEDED
        if set(need.users) & users and not has_object(od, need.index, need.subindex)
    ]
    listed = {(need.index, need.subindex) for need in missing}
    texts = [f"{n.text()} ({', '.join(u for u in n.users if u in users)})" for n in missing]
    for (index, subindex), where in _unmapped(od).items():
        if (index, subindex) not in listed:
            texts.append(f"0x{index:04X} sub {subindex} (mapped by {where})")
    return texts


def _unmapped(od: ObjectDictionary) -> dict[tuple[int, int], str]:
    """Objects named by the EDS's own default PDO mappings but absent from it: (index,
    subindex) -> the first mapping entry that names it."""
    absent: dict[tuple[int, int], str] = {}
    for first in (obj.RPDO_MAP_FIRST, obj.TPDO_MAP_FIRST):
        for index in range(first, first + 0x200):
            entry = od.get(index)
            if entry is None or isinstance(entry, ODVariable):
                continue
            entries = entry.subindices
            for sub in range(1, _default(entries.get(0)) + 1):
                value = _default(entries.get(sub))
                mapped = (value >> 16, (value >> 8) & 0xFF)
                if value and not has_object(od, *mapped):
                    absent.setdefault(mapped, f"0x{index:04X} sub {sub}")
    return absent


def _default(var: ODVariable | None) -> int:
    if var is None:
        return 0
    value = var.value if var.value is not None else var.default
    return value if isinstance(value, int) else 0


def eds_file_problem(eds: Path, *, simulated: bool, configure_pdos: bool, drive_watch: bool) -> str:
    """Why the EDS file ``eds`` cannot serve the master with these settings (and the
    simulated drives when ``simulated``); empty when it can (see :func:`users_of`)."""
    try:
        od = load_od(eds)
    except EdsUnreadableError as exc:
        return str(exc)
    users = users_of(simulated=simulated, configure_pdos=configure_pdos, drive_watch=drive_watch)
    return eds_problem(od, eds, users)


class EdsUnreadableError(ValueError):
    """An EDS file canopen cannot parse (the message names the file)."""


def load_od(eds: Path, node_id: int = 1) -> ObjectDictionary:
    """The object dictionary of ``eds``; ``EdsUnreadableError`` naming the file if unreadable."""
    quiet = logging.getLogger("canopen.objectdictionary")
    level = quiet.level
    quiet.setLevel(logging.ERROR)  # unknown data types of unrelated objects: not our concern
    try:
        return canopen.import_od(str(eds), node_id)
    except Exception as exc:  # canopen raises whatever its parser meets: name the file instead
        raise EdsUnreadableError(
            f"cannot read EDS file {eds}: {type(exc).__name__}: {exc}"
        ) from None
    finally:
        quiet.setLevel(level)


def eds_problem(od: ObjectDictionary, eds: Path, users: frozenset[str]) -> str:
    """Why ``eds`` (read as ``od``) cannot serve ``users``: every object it lacks, the file
    and what to do; empty when it can."""
    missing = missing_objects(od, users)
    if not missing:
        return ""
    hint = (
        "Simulated drives run from this EDS: leave eds empty for the built-in one, or give an "
        "EDS that has these objects."
        if SIM in users
        else "Give the drives' own EDS, or a copy with these objects."
    )
    if MASTER_WATCH in users and not has_object(od, obj.CONSUMER_HEARTBEAT_TIME, 1):
        hint += " drive_heartbeat_timeout: null runs without the drives' watchdog on the master."
    return (
        f"EDS file {eds} lacks {len(missing)} object(s) needed by the master"
        f"{' and the simulated drives' if SIM in users else ''}: "
        + "; ".join(missing)
        + f". {hint}"
    )
