"""Settings of a CANopen arm: the bus, the joints' drives, the timing.

Everything is validated when built, before any bus is touched; mistakes raise
`Cia402ConfigError` / `BusSpecError` (both `UserError`: the CLI prints them, exit 2).
Times in seconds, angles in radians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import can

from umbra.connectors.errors import UserError
from umbra.connectors.limits import MAX_COMMAND_AGE_S
from umbra.modules.arm.cia402.drive_watchdog import ABORT_CONNECTION_OPTIONS, ABORT_NO_ACTION
from umbra.modules.arm.cia402.eds_needs import eds_file_problem
from umbra.modules.arm.cia402.objects import EDS_PATH

# Bit rates of the CiA 301 / CiA 102 table (bit/s).
CANOPEN_BITRATES = (10_000, 20_000, 50_000, 125_000, 250_000, 500_000, 800_000, 1_000_000)


class Cia402ConfigError(UserError):
    """Settings of the CANopen arm that cannot work."""


class BusSpecError(Cia402ConfigError):
    """A CAN bus that is misspelled or cannot be opened."""


@dataclass(frozen=True)
class BusSpec:
    """Which CAN bus: python-can interface name, channel, bit rate (bit/s).

    Examples: ("socketcan", "can0", 500000), ("pcan", "PCAN_USBBUS1", 1000000),
    ("virtual", "any-name", 500000) for simulated drives in the same process.
    """

    interface: str
    channel: str
    bitrate: int = 500_000

    def __post_init__(self) -> None:
        if not isinstance(self.interface, str) or self.interface not in can.VALID_INTERFACES:
            raise BusSpecError(
                f"CAN bus {self.describe()}: unknown interface {self.interface!r}; expected one of "
                f"python-can's interfaces: {', '.join(sorted(can.VALID_INTERFACES))}"
            )
        if not isinstance(self.channel, str) or not self.channel.strip():
            raise BusSpecError(
                f"CAN bus {self.describe()}: channel must be a non-empty name "
                f"(e.g. 'can0'), got {self.channel!r}"
            )
        if isinstance(self.bitrate, bool) or self.bitrate not in CANOPEN_BITRATES:
            raise BusSpecError(
                f"CAN bus {self.describe()}: bit rate must be one of the CANopen rates "
                f"{', '.join(str(b) for b in CANOPEN_BITRATES)} bit/s, got {self.bitrate!r}"
            )

    def describe(self) -> str:
        return f"interface={self.interface!r} channel={self.channel!r} bitrate={self.bitrate!r}"


@dataclass(frozen=True)
class JointDrive:
    """One joint driven by one CiA 402 drive.

    Attributes:
        name: joint name (as in the arm's joint list).
        node_id: CANopen node id of the drive, 1..127.
        counts_per_rad: drive position counts per joint radian (encoder counts times gear
            ratio / 2 pi); negative when the drive turns the other way.
        zero_counts: position actual value (counts) at joint angle 0.
    """

    name: str
    node_id: int
    counts_per_rad: float
    zero_counts: int = 0

    def __post_init__(self) -> None:
        if not self.name:
            raise Cia402ConfigError("joint name must not be empty")
        if isinstance(self.node_id, bool) or not isinstance(self.node_id, int):
            raise Cia402ConfigError(
                f"joint {self.name!r}: node id must be an integer 1..127, got {self.node_id!r}"
            )
        if not 1 <= self.node_id <= 127:
            raise Cia402ConfigError(
                f"joint {self.name!r}: node id must be 1..127, got {self.node_id}"
            )
        if not math.isfinite(self.counts_per_rad) or self.counts_per_rad == 0:
            raise Cia402ConfigError(
                f"joint {self.name!r}: counts_per_rad must be finite and non-zero, "
                f"got {self.counts_per_rad!r}"
            )


@dataclass(frozen=True)
class Cia402ArmConfig:
    """A CANopen arm: bus, drives, timing (seconds) and drive setup.

    Attributes:
        bus: the CAN bus.
        joints: one drive per joint, in the arm's joint order.
        sync_period_s: SYNC period, the servo rate at which drives apply targets and
            report feedback.
        heartbeat_period_s: producer heartbeat time written to each drive (0x1017).
        heartbeat_timeout_s: a drive whose last heartbeat is older is lost (consumer side).
        monitor_period_s: how often heartbeats, feedback age and commands are checked.
        feedback_timeout_s: a drive whose last TPDO is older is lost.
        command_timeout_s: targets drop to zero when no command came for this long
            (None: keep the last command).
        eds: object dictionary of the drives (vendor EDS for real drives).
        configure_pdos: write the PDO mapping to the drives by SDO (True) or use the
            drives' own mapping read back by SDO (False).
        sdo_timeout_s: SDO response timeout during start.
        enable_timeout_s: time a drive may take to reach Operation enabled.
        stop_timeout_s: time stop() waits for the drives to stand still.
        acceleration_rad_s2: if given, written as profile acceleration and deceleration.
        quick_stop_deceleration_rad_s2: if given, written as quick stop deceleration.
        master_node_id: node id of the master's own heartbeat (0x700 + id), 1..127, no drive's.
        master_heartbeat_period_s: the master sends its heartbeat this often (from its
            monitor thread: a frozen master process sends none).
        drive_heartbeat_timeout_s: the drives' watchdog: written to each drive's heartbeat
            consumer (0x1016 sub 1); a drive that hears no master heartbeat for this long stops
            by itself as ``abort_connection_option`` says (None: not configured).
        abort_connection_option: written to 0x6007: 1 fault, 2 disable voltage, 3 quick stop.
    """

    bus: BusSpec
    joints: tuple[JointDrive, ...]
    sync_period_s: float = 0.01
    heartbeat_period_s: float = 0.05
    heartbeat_timeout_s: float = 0.2
    monitor_period_s: float = 0.005
    feedback_timeout_s: float = 0.2
    command_timeout_s: float | None = 0.5
    eds: Path = field(default=EDS_PATH)
    configure_pdos: bool = True
    sdo_timeout_s: float = 0.3
    enable_timeout_s: float = 1.0
    stop_timeout_s: float = 0.5
    acceleration_rad_s2: float | None = None
    quick_stop_deceleration_rad_s2: float | None = None
    master_node_id: int = 127
    master_heartbeat_period_s: float = 0.02
    drive_heartbeat_timeout_s: float | None = 0.2
    abort_connection_option: int = 3

    def __post_init__(self) -> None:
        object.__setattr__(self, "joints", tuple(self.joints))
        object.__setattr__(self, "eds", Path(self.eds))
        if not self.joints:
            raise Cia402ConfigError("a CANopen arm needs at least one joint")
        ids = [j.node_id for j in self.joints]
        duplicates = sorted({i for i in ids if ids.count(i) > 1})
        if duplicates:
            raise Cia402ConfigError(f"node ids used by more than one joint: {duplicates}")
        names = [j.name for j in self.joints]
        if len(set(names)) != len(names):
            raise Cia402ConfigError(f"joint names must be unique, got {names}")
        for name in (
            "sync_period_s",
            "heartbeat_period_s",
            "heartbeat_timeout_s",
            "monitor_period_s",
            "feedback_timeout_s",
            "sdo_timeout_s",
            "enable_timeout_s",
            "stop_timeout_s",
            "master_heartbeat_period_s",
        ):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise Cia402ConfigError(
                    f"{name} must be a positive number of seconds, got {value!r}"
                )
        if round(self.heartbeat_period_s * 1000) < 1 or self.heartbeat_period_s > 65.535:
            raise Cia402ConfigError(
                f"heartbeat_period_s must be 0.001..65.535 s (0x1017 is in ms), "
                f"got {self.heartbeat_period_s}"
            )
        if self.heartbeat_timeout_s <= self.heartbeat_period_s:
            raise Cia402ConfigError(
                f"heartbeat_timeout_s ({self.heartbeat_timeout_s}) must exceed "
                f"heartbeat_period_s ({self.heartbeat_period_s})"
            )
        if self.feedback_timeout_s <= self.sync_period_s:
            raise Cia402ConfigError(
                f"feedback_timeout_s ({self.feedback_timeout_s}) must exceed "
                f"sync_period_s ({self.sync_period_s})"
            )
        self._check_master_watch(ids)
        if self.command_timeout_s is not None and not self.command_timeout_s > 0:
            raise Cia402ConfigError(
                f"command_timeout_s must be positive or None, got {self.command_timeout_s}"
            )
        for name in ("acceleration_rad_s2", "quick_stop_deceleration_rad_s2"):
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value > 0):
                raise Cia402ConfigError(f"{name} must be positive or None, got {value!r}")
        if not self.eds.is_file():
            raise Cia402ConfigError(f"{self.eds}: error: object dictionary (EDS) file not found")
        self.check_eds(simulated=False)

    def check_eds(self, *, simulated: bool) -> None:
        """``Cia402ConfigError`` unless the EDS has every object the master needs with these
        settings, and the simulated drives too when ``simulated`` (eds_needs.py)."""
        problem = eds_file_problem(
            self.eds,
            simulated=simulated,
            configure_pdos=self.configure_pdos,
            drive_watch=self.drive_heartbeat_timeout_s is not None,
        )
        if problem:
            raise Cia402ConfigError(problem)

    def _check_master_watch(self, drive_ids: list[int]) -> None:
        master = self.master_node_id
        if isinstance(master, bool) or not isinstance(master, int) or not 1 <= master <= 127:
            raise Cia402ConfigError(f"master_node_id must be an integer 1..127, got {master!r}")
        if master in drive_ids:
            raise Cia402ConfigError(
                f"master_node_id {master} is also a drive's node id; pick a free one (e.g. 127)"
            )
        if round(self.master_heartbeat_period_s * 1000) < 1:
            raise Cia402ConfigError(
                f"master_heartbeat_period_s must be at least 0.001 s, "
                f"got {self.master_heartbeat_period_s}"
            )
        timeout = self.drive_heartbeat_timeout_s
        if timeout is not None:
            if not (isinstance(timeout, (int, float)) and math.isfinite(timeout)):
                raise Cia402ConfigError(
                    f"drive_heartbeat_timeout_s must be a number of seconds or None, "
                    f"got {timeout!r}"
                )
            if not 2 * self.master_heartbeat_period_s <= timeout <= MAX_COMMAND_AGE_S:
                raise Cia402ConfigError(
                    f"drive_heartbeat_timeout_s must be 2 x master_heartbeat_period_s "
                    f"({2 * self.master_heartbeat_period_s:g} s) .. {MAX_COMMAND_AGE_S:g} s, "
                    f"got {timeout}"
                )
        options = {k: v for k, v in ABORT_CONNECTION_OPTIONS.items() if k != ABORT_NO_ACTION}
        if self.abort_connection_option not in options:
            raise Cia402ConfigError(
                f"abort_connection_option must be one of "
                f"{', '.join(f'{k} ({v})' for k, v in options.items())}, "
                f"got {self.abort_connection_option!r}"
            )
