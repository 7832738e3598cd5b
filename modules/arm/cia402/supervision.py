"""Supervision of a CANopen arm: the bus thread's callbacks, the monitor thread, and trips.

A mixin of `Cia402Arm` (network.py), sharing its lock and registers. TPDO, heartbeat and EMCY
callbacks (bus thread) and the monitor thread (every `monitor_period_s`: the master's own
heartbeat, heartbeat and feedback ages, the stale-command timeout, the bus's health) record
what went wrong as a `DriveTrip` and stop every joint (target 0 + quick stop).
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass

import can
import canopen
from canopen.emcy import EmcyError
from canopen.pdo import PdoMap

from umbra.modules.arm.cia402 import objects as obj
from umbra.modules.arm.cia402.bring_up import PdoLayout
from umbra.modules.arm.cia402.config import Cia402ArmConfig, JointDrive
from umbra.modules.arm.cia402.state_machine import (
    SW_FAULT,
    Command,
    State,
    StatuswordError,
    controlword_for,
    state_from_statusword,
)
from umbra.modules.arm.cia402.status import ArmState, DriveTrip, TripCause, describe_error_code

logger = logging.getLogger(__name__)

NMT_OPERATIONAL = 5
NMT_STATE_NAMES = {
    0: "boot-up (the drive reset)",
    4: "STOPPED",
    5: "OPERATIONAL",
    127: "PRE-OPERATIONAL",
}
CAN_ERR_BUSOFF = 0x40  # error class bit of a socketcan error frame


@dataclass
class DriveRegisters:
    """Master-side registers of one drive; guarded by the arm's lock."""

    joint: JointDrive
    node: canopen.RemoteNode
    layout: PdoLayout | None = None
    statusword: int | None = None
    position_counts: int | None = None
    velocity_counts_s: int | None = None
    mode_display: int | None = None
    error_code: int | None = None
    feedback_time: float | None = None
    heartbeat_time: float | None = None
    nmt_state: int | None = None

    @property
    def label(self) -> str:
        return f"joint {self.joint.name!r} (node {self.joint.node_id})"


class ArmSupervision:
    """Trips, bus-thread callbacks and the monitor thread of `Cia402Arm`."""

    # provided by Cia402Arm
    config: Cia402ArmConfig
    _lock: threading.Lock
    _state: ArmState
    _trips: list[DriveTrip]
    _trip_keys: set[tuple[int | None, TripCause]]
    _network: canopen.Network | None
    _drives: list[DriveRegisters]
    _monitor: threading.Thread | None
    _monitor_stop: threading.Event
    _last_command: float
    _command_stale: bool
    _error_frames: int

    def _write_rpdo(self, drive: DriveRegisters, controlword: int, target_counts_s: int) -> None:
        raise NotImplementedError

    def _quick_stop_all_locked(self) -> None:
        raise NotImplementedError

    def _start_monitor(self) -> None:
        self._monitor_stop.clear()
        self._last_heartbeat_sent: float | None = None
        self._monitor = threading.Thread(
            target=self._monitor_loop, name="cia402-monitor", daemon=True
        )
        self._monitor.start()

    def _send_heartbeat_locked(self, now: float) -> None:
        """The master's heartbeat (NMT state OPERATIONAL) when its period is due. Sent from
        this thread, never by a kernel or library timer, so it stops when the process does."""
        last = self._last_heartbeat_sent
        if last is not None and now - last < self.config.master_heartbeat_period_s:
            return
        network = self._network
        if network is None:
            return
        self._last_heartbeat_sent = now
        cob_id = obj.HEARTBEAT_COB_BASE + self.config.master_node_id
        try:
            network.send_message(cob_id, bytes([NMT_OPERATIONAL]))
        except (can.CanError, OSError, RuntimeError) as exc:
            if self._state in (ArmState.RUNNING, ArmState.TRIPPED):
                self._trip_locked(
                    DriveTrip(TripCause.BUS_ERROR, f"sending the heartbeat failed: {exc}")
                )

    # -- trips -----------------------------------------------------------------------

    def _record_locked(self, trip: DriveTrip) -> None:
        key = (trip.node_id, trip.cause)
        if key in self._trip_keys:
            return
        self._trip_keys.add(key)
        self._trips.append(trip)
        logger.warning("CANopen arm: %s", trip)

    def _trip_locked(self, trip: DriveTrip) -> None:
        """Record why, and stop every joint (target 0 + quick stop) if still running."""
        self._record_locked(trip)
        if self._state is ArmState.RUNNING:
            self._state = ArmState.TRIPPED
            self._quick_stop_all_locked()

    def _drive_trip(
        self, drive: DriveRegisters, cause: TripCause, detail: str, code: int | None = None
    ) -> DriveTrip:
        return DriveTrip(cause, detail, drive.joint.name, drive.joint.node_id, code)

    # -- bus thread callbacks --------------------------------------------------------

    def _on_tpdo(self, drive: DriveRegisters, pdo_map: PdoMap) -> None:
        values = {var.index: var.raw for var in pdo_map.map if var.length}
        with self._lock:
            drive.feedback_time = time.monotonic()
            if obj.STATUSWORD in values:
                drive.statusword = int(values[obj.STATUSWORD])
            if obj.POSITION_ACTUAL in values:
                drive.position_counts = int(values[obj.POSITION_ACTUAL])
            if obj.VELOCITY_ACTUAL in values:
                drive.velocity_counts_s = int(values[obj.VELOCITY_ACTUAL])
            if obj.MODES_OF_OPERATION_DISPLAY in values:
                drive.mode_display = int(values[obj.MODES_OF_OPERATION_DISPLAY])
            if values.get(obj.ERROR_CODE):
                drive.error_code = int(values[obj.ERROR_CODE])
            if self._state not in (ArmState.RUNNING, ArmState.TRIPPED):
                return
            word = drive.statusword
            if word is not None and word & SW_FAULT:
                code = drive.error_code
                detail = f"fault bit set in statusword 0x{word:04X}"
                if code is not None:
                    detail += f", error code {describe_error_code(code)}"
                self._trip_locked(self._drive_trip(drive, TripCause.FAULT, detail, code))
                return
            if self._state is not ArmState.RUNNING:
                return
            if word is not None and state_or_none(word) is not State.OPERATION_ENABLED:
                state = state_or_none(word)
                name = state.value if state is not None else "an undefined state"
                self._trip_locked(
                    self._drive_trip(
                        drive, TripCause.STATE_LOST, f"now in {name} (statusword 0x{word:04X})"
                    )
                )
            elif drive.mode_display is not None and drive.mode_display != obj.PROFILE_VELOCITY_MODE:
                self._trip_locked(
                    self._drive_trip(
                        drive,
                        TripCause.STATE_LOST,
                        f"mode of operation display is {drive.mode_display}, expected "
                        f"{obj.PROFILE_VELOCITY_MODE} (profile velocity)",
                    )
                )

    def _on_heartbeat(self, drive: DriveRegisters, nmt_state: int) -> None:
        with self._lock:
            drive.heartbeat_time = time.monotonic()
            drive.nmt_state = nmt_state
            if self._state is ArmState.RUNNING and nmt_state != NMT_OPERATIONAL:
                name = NMT_STATE_NAMES.get(nmt_state, f"state {nmt_state}")
                self._trip_locked(
                    self._drive_trip(drive, TripCause.NMT_STATE, f"drive reports NMT {name}")
                )

    def _on_emcy(self, drive: DriveRegisters, emcy: EmcyError) -> None:
        if emcy.code & 0xFF00 == 0:
            return  # error reset / no error
        with self._lock:
            drive.error_code = emcy.code
            if self._state in (ArmState.RUNNING, ArmState.TRIPPED):
                detail = (
                    f"error code {describe_error_code(emcy.code)}, "
                    f"error register 0x{emcy.register:02X}"
                )
                self._trip_locked(self._drive_trip(drive, TripCause.EMERGENCY, detail, emcy.code))

    def _on_error_frame(self, msg: can.Message) -> None:
        with self._lock:
            self._error_frames += 1
            if msg.arbitration_id & CAN_ERR_BUSOFF and self._state in (
                ArmState.RUNNING,
                ArmState.TRIPPED,
            ):
                self._trip_locked(
                    DriveTrip(TripCause.BUS_ERROR, "the CAN controller reports bus-off")
                )

    def _on_receive_dead(self, exc: Exception) -> None:
        with self._lock:
            if self._state in (ArmState.RUNNING, ArmState.TRIPPED):
                self._trip_locked(
                    DriveTrip(
                        TripCause.BUS_ERROR, f"receiving stopped: {type(exc).__name__}: {exc}"
                    )
                )

    # -- monitor thread --------------------------------------------------------------

    def _monitor_loop(self) -> None:
        cfg = self.config
        while not self._monitor_stop.wait(cfg.monitor_period_s):
            now = time.monotonic()
            with self._lock:
                self._send_heartbeat_locked(now)
                if self._state not in (ArmState.RUNNING, ArmState.TRIPPED):
                    continue
                self._check_bus_locked()
                for drive in self._drives:
                    self._check_drive_locked(drive, now)
                if (
                    self._state is ArmState.RUNNING
                    and cfg.command_timeout_s is not None
                    and not self._command_stale
                    and now - self._last_command > cfg.command_timeout_s
                ):
                    self._command_stale = True
                    enable = controlword_for(Command.ENABLE_OPERATION)
                    try:
                        for drive in self._drives:
                            self._write_rpdo(drive, enable, 0)
                    except (can.CanError, OSError, RuntimeError) as exc:
                        self._trip_locked(
                            DriveTrip(TripCause.BUS_ERROR, f"sending targets failed: {exc}")
                        )

    def _check_bus_locked(self) -> None:
        network = self._network
        if network is None:
            return
        notifier = network.notifier
        if notifier is not None and notifier.exception is not None:
            exc = notifier.exception
            self._trip_locked(
                DriveTrip(TripCause.BUS_ERROR, f"receiving stopped: {type(exc).__name__}: {exc}")
            )
        bus = network.bus
        if bus is not None and bus.state is can.BusState.ERROR:
            self._trip_locked(
                DriveTrip(TripCause.BUS_ERROR, "the CAN interface reports an error state")
            )

    def _check_drive_locked(self, drive: DriveRegisters, now: float) -> None:
        cfg = self.config
        for since, timeout_s, cause, what in (
            (drive.heartbeat_time, cfg.heartbeat_timeout_s, TripCause.HEARTBEAT_LOST, "heartbeat"),
            (drive.feedback_time, cfg.feedback_timeout_s, TripCause.FEEDBACK_LOST, "TPDO"),
        ):
            silent = None if since is None else now - since
            if silent is not None and silent > timeout_s:
                message = f"no {what} for {silent:.3f} s (timeout {timeout_s} s)"
                self._trip_locked(self._drive_trip(drive, cause, message))


def state_or_none(statusword: int | None) -> State | None:
    if statusword is None:
        return None
    try:
        return state_from_statusword(statusword)
    except StatuswordError:
        return None
