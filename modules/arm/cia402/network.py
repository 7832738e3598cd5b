"""CANopen master for an arm of CiA 402 drives in profile velocity mode.

`Cia402Arm` owns one canopen `Network` on one python-can bus:

- `start()` (blocking, SDO): opens the bus, starts the master's own heartbeat, and for
  each drive: NMT PRE-OPERATIONAL, identity check, producer heartbeat (0x1017), the
  drive's watchdog on the master (heartbeat consumer 0x1016 on the master's heartbeat,
  reaction 0x6007), PDO mapping (written, or read and checked), mode 3 (profile
  velocity), NMT OPERATIONAL, power state machine to Operation enabled. Then SYNC starts
  at `sync_period_s` (python-can's periodic send: the kernel's broadcast manager on
  socketcan, which goes on while the process is stopped: the drives' heartbeat consumer
  is what stops them then).
- `set_velocities(rad/s)` (never blocks on SDO): converts to counts/s and sends one RPDO
  per drive (controlword "enable operation" + target velocity); drives apply it on SYNC.
- `read()`: latest feedback, filled by TPDO callbacks on the bus thread (registers).
- Supervision: a statusword fault bit, an EMCY, a drive leaving Operation enabled or NMT
  OPERATIONAL (TPDO / heartbeat callbacks), a heartbeat or TPDO older than its timeout,
  a dead receive thread, a failed send, a bus-off error frame (monitor thread) each trip
  the arm: every drive gets target velocity 0 with a quick stop, later commands are
  ignored, and `status()` names the drive and the cause. With no command for
  `command_timeout_s`, targets drop to zero (not a trip).
- `stop()`: quick stop, wait (bounded) for the drives to stand still, stop SYNC, NMT
  PRE-OPERATIONAL, release the bus.

Units at this interface: rad, rad/s, seconds; the drives see counts and counts/s.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from functools import partial
from types import TracebackType

import can
import canopen
import numpy as np
from numpy.typing import ArrayLike

from modules.arm.cia402 import bring_up
from modules.arm.cia402 import objects as obj
from modules.arm.cia402.bring_up import DriveStartError
from modules.arm.cia402.config import BusSpecError, Cia402ArmConfig, JointDrive
from modules.arm.cia402.state_machine import (
    Command,
    State,
    controlword_for,
)
from modules.arm.cia402.status import ArmState, ArmStatus, DriveTrip, JointFeedback, TripCause
from modules.arm.cia402.supervision import (
    NMT_OPERATIONAL,
    ArmSupervision,
    DriveRegisters,
    state_or_none,
)
from modules.arm.cia402.units import counts_s_to_rates, counts_to_angles, rates_to_counts_s

logger = logging.getLogger(__name__)

RECEIVE_POLL_S = 0.05  # receive thread's wait per poll: bounds how long closing the bus takes


class _BusWatch(can.Listener):
    """Sees error frames and the death of the receive thread."""

    def __init__(
        self, on_error_frame: Callable[[can.Message], None], on_dead: Callable[[Exception], None]
    ):
        self._on_error_frame = on_error_frame
        self._on_dead = on_dead

    def on_message_received(self, msg: can.Message) -> None:
        if msg.is_error_frame:
            self._on_error_frame(msg)

    def on_error(self, exc: Exception) -> None:
        self._on_dead(exc)

    def stop(self) -> None:
        pass


class Cia402Arm(ArmSupervision):
    """N joints on CiA 402 drives over one CAN bus (see the module docstring)."""

    def __init__(self, config: Cia402ArmConfig) -> None:
        self.config = config
        self._lock = threading.Lock()
        self._state = ArmState.IDLE
        self._trips: list[DriveTrip] = []
        self._trip_keys: set[tuple[int | None, TripCause]] = set()
        self._network: canopen.Network | None = None
        self._drives: list[DriveRegisters] = []
        self._monitor: threading.Thread | None = None
        self._monitor_stop = threading.Event()
        self._last_command = 0.0
        self._command_stale = False
        self._error_frames = 0
        cpr = [j.counts_per_rad for j in config.joints]
        self._counts_per_rad = np.asarray(cpr, dtype=float)
        self._zero_counts = np.asarray([j.zero_counts for j in config.joints], dtype=float)

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(j.name for j in self.config.joints)

    # -- lifecycle -------------------------------------------------------------------

    def start(self) -> None:
        """Open the bus and bring every drive to Operation enabled (blocks; SDO)."""
        with self._lock:
            if self._state is ArmState.RUNNING or self._state is ArmState.TRIPPED:
                raise RuntimeError("the arm is already started; stop() it first")
            self._trips = []
            self._trip_keys = set()
            self._command_stale = False
            self._error_frames = 0
        self._drives = []
        network = self._open_bus()
        self._start_monitor()  # the master's heartbeat from now on
        try:
            self._drives = [self._add_drive(network, joint) for joint in self.config.joints]
            for drive in self._drives:
                self._bring_up(drive)
            self._go_running(network)
        except BaseException:
            self._abort_start()
            self._close_bus()
            raise

    def stop(self) -> None:
        """Quick stop every drive, wait for standstill (bounded), release the bus."""
        with self._lock:
            if self._network is None:
                self._state = ArmState.STOPPED if self._state is not ArmState.IDLE else self._state
                return
            if self._state is ArmState.RUNNING:
                self._quick_stop_all_locked()
            self._state = ArmState.STOPPED
        self._wait_standstill()
        self._close_bus()

    def __enter__(self) -> Cia402Arm:
        self.start()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()

    # -- servo interface (never blocks on SDO) ---------------------------------------

    def set_velocities(self, rates_rad_s: ArrayLike) -> bool:
        """Command joint rates (rad/s, joint order). False if not running (tripped, stopped)."""
        rates = np.asarray(rates_rad_s, dtype=float)
        if rates.shape != (len(self.config.joints),):
            raise ValueError(
                f"expected {len(self.config.joints)} joint rates {self.joint_names}, "
                f"got shape {rates.shape}"
            )
        with self._lock:
            if self._state is not ArmState.RUNNING:
                return False
            bad = [self.config.joints[i].name for i in np.flatnonzero(~np.isfinite(rates))]
            if bad:
                self._trip_locked(
                    DriveTrip(TripCause.BAD_COMMAND, f"non-finite joint rate for {bad}")
                )
                return False
            counts = rates_to_counts_s(rates, self._counts_per_rad)
            self._last_command = time.monotonic()
            self._command_stale = False
            enable = controlword_for(Command.ENABLE_OPERATION)
            try:
                for drive, target in zip(self._drives, counts, strict=True):
                    self._write_rpdo(drive, enable, int(target))
            except (can.CanError, OSError, RuntimeError) as exc:
                self._trip_locked(DriveTrip(TripCause.BUS_ERROR, f"sending targets failed: {exc}"))
                return False
        return True

    def read(self) -> JointFeedback:
        """Latest joint angles (rad), rates (rad/s), their ages (s) and drive states."""
        now = time.monotonic()
        with self._lock:
            drives = list(self._drives)
            pos = [np.nan if d.position_counts is None else d.position_counts for d in drives]
            vel = [np.nan if d.velocity_counts_s is None else d.velocity_counts_s for d in drives]
            ages = [np.inf if d.feedback_time is None else now - d.feedback_time for d in drives]
            words = [d.statusword for d in drives]
        if not drives:
            n = len(self.config.joints)
            pos, vel, ages, words = [np.nan] * n, [np.nan] * n, [np.inf] * n, [None] * n
        return JointFeedback(
            positions_rad=counts_to_angles(pos, self._counts_per_rad, self._zero_counts),
            velocities_rad_s=counts_s_to_rates(vel, self._counts_per_rad),
            ages_s=np.asarray(ages, dtype=float),
            states=tuple(state_or_none(w) for w in words),
        )

    def status(self) -> ArmStatus:
        with self._lock:
            return ArmStatus(
                state=self._state,
                trips=tuple(self._trips),
                command_stale=self._command_stale,
                error_frames=self._error_frames,
            )

    # -- bring-up (blocking) ---------------------------------------------------------

    def _open_bus(self) -> canopen.Network:
        spec = self.config.bus
        network = canopen.Network()
        network.NOTIFIER_CYCLE = RECEIVE_POLL_S
        network.listeners.append(_BusWatch(self._on_error_frame, self._on_receive_dead))
        try:
            network.connect(interface=spec.interface, channel=spec.channel, bitrate=spec.bitrate)
        except Exception as exc:  # python-can raises many types here; all mean "no such bus"
            raise BusSpecError(
                f"cannot open CAN bus {spec.describe()}: {type(exc).__name__}: {exc}"
            ) from exc
        self._network = network
        return network

    def _add_drive(self, network: canopen.Network, joint: JointDrive) -> DriveRegisters:
        od = canopen.import_od(str(self.config.eds), joint.node_id)
        node = network.add_node(joint.node_id, od)
        node.sdo.RESPONSE_TIMEOUT = self.config.sdo_timeout_s
        drive = DriveRegisters(joint=joint, node=node)
        node.nmt.add_heartbeat_callback(partial(self._on_heartbeat, drive))
        node.emcy.add_callback(partial(self._on_emcy, drive))
        return drive

    def _bring_up(self, drive: DriveRegisters) -> None:
        cfg, node, label = self.config, drive.node, drive.label
        node.nmt.state = "PRE-OPERATIONAL"
        bring_up.check_identity(node, label)
        heartbeat_ms = round(cfg.heartbeat_period_s * 1000)
        bring_up.write_parameter(node, label, obj.PRODUCER_HEARTBEAT_TIME, heartbeat_ms)
        if cfg.drive_heartbeat_timeout_s is not None:
            bring_up.configure_master_watch(
                node,
                label,
                cfg.master_node_id,
                cfg.drive_heartbeat_timeout_s,
                cfg.abort_connection_option,
            )
        self._wait_for(
            lambda: drive.heartbeat_time is not None,
            cfg.heartbeat_timeout_s,
            f"{label}: no heartbeat within {cfg.heartbeat_timeout_s} s after setting its "
            f"producer heartbeat time (0x1017) to {heartbeat_ms} ms",
        )
        if cfg.configure_pdos:
            layout = bring_up.configure_pdos(node, label)
        else:
            layout = bring_up.read_pdos(node, label)
        for pdo_map in layout.tpdos:
            pdo_map.add_callback(partial(self._on_tpdo, drive))
        with self._lock:
            drive.layout = layout
        cpr = abs(drive.joint.counts_per_rad)
        od = node.object_dictionary
        if cfg.acceleration_rad_s2 is not None:
            counts = max(1, round(cfg.acceleration_rad_s2 * cpr))
            for index in (obj.PROFILE_ACCELERATION, obj.PROFILE_DECELERATION):
                if index in od:
                    bring_up.write_parameter(node, label, index, counts)
        if cfg.quick_stop_deceleration_rad_s2 is not None and obj.QUICK_STOP_DECELERATION in od:
            counts = max(1, round(cfg.quick_stop_deceleration_rad_s2 * cpr))
            bring_up.write_parameter(node, label, obj.QUICK_STOP_DECELERATION, counts)
        bring_up.set_profile_velocity_mode(node, label)
        node.nmt.state = "OPERATIONAL"
        self._wait_for(
            lambda: drive.nmt_state == NMT_OPERATIONAL,
            cfg.heartbeat_timeout_s + cfg.heartbeat_period_s,
            f"{label}: its heartbeat did not report NMT OPERATIONAL after the start command",
        )
        bring_up.enable_operation(node, label, cfg.enable_timeout_s)
        bring_up.check_mode_display(node, label)

    def _abort_start(self) -> None:
        """Start failed: quick stop (by SDO) the drives already set up, best effort."""
        for drive in self._drives:
            if drive.layout is None:
                continue
            try:
                bring_up.write_controlword(drive.node, drive.label, Command.QUICK_STOP)
            except DriveStartError as exc:
                logger.warning("while aborting the start: %s", exc)

    def _wait_for(
        self, predicate: Callable[[], bool], timeout_s: float, message: str | Callable[[], str]
    ) -> None:
        """Poll `predicate` under the lock; DriveStartError(message) after `timeout_s`."""
        deadline = time.monotonic() + timeout_s
        while True:
            with self._lock:
                if predicate():
                    return
            if time.monotonic() > deadline:
                with self._lock:
                    text = message if isinstance(message, str) else message()
                raise DriveStartError(text)
            time.sleep(min(0.005, self.config.monitor_period_s))

    def _go_running(self, network: canopen.Network) -> None:
        enable = controlword_for(Command.ENABLE_OPERATION)
        with self._lock:
            for drive in self._drives:
                drive.statusword = drive.position_counts = drive.velocity_counts_s = None
                drive.feedback_time = None
                self._write_rpdo(drive, enable, 0)
        network.sync.start(self.config.sync_period_s)
        self._wait_for(
            lambda: all(
                d.statusword is not None
                and d.position_counts is not None
                and d.velocity_counts_s is not None
                for d in self._drives
            ),
            self.config.feedback_timeout_s,
            lambda: (
                "no feedback (TPDO with statusword, position and velocity) from "
                + ", ".join(d.label for d in self._drives if d.position_counts is None)
                + f" within {self.config.feedback_timeout_s} s of the first SYNC"
            ),
        )
        with self._lock:
            self._last_command = time.monotonic()
            self._state = ArmState.RUNNING

    def _wait_standstill(self) -> None:
        deadline = time.monotonic() + self.config.stop_timeout_s
        while time.monotonic() < deadline:
            now = time.monotonic()
            with self._lock:
                moving = [
                    d
                    for d in self._drives
                    if d.feedback_time is not None
                    and now - d.feedback_time < self.config.feedback_timeout_s
                    and (
                        d.velocity_counts_s != 0
                        or state_or_none(d.statusword) is State.OPERATION_ENABLED
                    )
                ]
            if not moving:
                return
            time.sleep(self.config.monitor_period_s)
        logger.warning("drives still moving %s s after the quick stop", self.config.stop_timeout_s)

    def _close_bus(self) -> None:
        self._monitor_stop.set()
        if self._monitor is not None and self._monitor is not threading.current_thread():
            self._monitor.join(timeout=1.0)
        self._monitor = None
        network, self._network = self._network, None
        if network is None:
            return
        try:
            network.sync.stop()
            if network.bus is not None:
                for drive in self._drives:
                    drive.node.nmt.state = "PRE-OPERATIONAL"
        except (can.CanError, OSError, RuntimeError) as exc:
            logger.warning("could not release the drives cleanly: %s", exc)
        try:
            network.disconnect()
        except (can.CanError, OSError, RuntimeError) as exc:
            logger.warning("closing the CAN bus: %s", exc)

    # -- RPDO ------------------------------------------------------------------------

    def _write_rpdo(self, drive: DriveRegisters, controlword: int, target_counts_s: int) -> None:
        """Fill and send the drive's RPDOs (caller holds the lock)."""
        if drive.layout is None:
            return
        for pdo_map in drive.layout.rpdos:
            for var in pdo_map.map:
                if not var.length:
                    continue
                if var.index == obj.CONTROLWORD:
                    var.raw = controlword
                elif var.index == obj.TARGET_VELOCITY:
                    var.raw = target_counts_s
                elif var.index == obj.MODES_OF_OPERATION:
                    var.raw = obj.PROFILE_VELOCITY_MODE
            pdo_map.transmit()

    def _quick_stop_all_locked(self) -> None:
        quick_stop = controlword_for(Command.QUICK_STOP)
        for drive in self._drives:
            try:
                self._write_rpdo(drive, quick_stop, 0)
            except (can.CanError, OSError, RuntimeError) as exc:
                self._record_locked(
                    DriveTrip(TripCause.BUS_ERROR, f"could not send the quick stop: {exc}")
                )
