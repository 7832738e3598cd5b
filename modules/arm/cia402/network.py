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

Beside it: `bus.py` opens and releases the bus, `drive_setup.py` brings one drive up,
`rpdo.py` fills and sends its RPDOs, `supervision.py` holds the callbacks, monitor and trips.
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

from umbra.modules.arm.cia402 import bring_up
from umbra.modules.arm.cia402.bring_up import DriveStartError
from umbra.modules.arm.cia402.bus import open_bus, release_bus
from umbra.modules.arm.cia402.config import Cia402ArmConfig, JointDrive
from umbra.modules.arm.cia402.drive_setup import set_up_drive, wait_until
from umbra.modules.arm.cia402.rpdo import write_rpdo
from umbra.modules.arm.cia402.state_machine import (
    Command,
    State,
    controlword_for,
)
from umbra.modules.arm.cia402.status import ArmState, ArmStatus, DriveTrip, JointFeedback, TripCause
from umbra.modules.arm.cia402.supervision import ArmSupervision, DriveRegisters, state_or_none
from umbra.modules.arm.cia402.units import counts_s_to_rates, counts_to_angles, rates_to_counts_s

logger = logging.getLogger(__name__)


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
                set_up_drive(drive, self.config, self._lock, self._wait_for, self._on_tpdo)
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
        network = open_bus(self.config.bus, self._on_error_frame, self._on_receive_dead)
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
        wait_until(self._lock, predicate, timeout_s, message, self.config.monitor_period_s)

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
        if network is not None:
            release_bus(network, self._drives)

    # -- RPDO ------------------------------------------------------------------------

    def _write_rpdo(self, drive: DriveRegisters, controlword: int, target_counts_s: int) -> None:
        """Fill and send the drive's RPDOs (caller holds the lock)."""
        write_rpdo(drive, controlword, target_counts_s)

    def _quick_stop_all_locked(self) -> None:
        quick_stop = controlword_for(Command.QUICK_STOP)
        for drive in self._drives:
            try:
                self._write_rpdo(drive, quick_stop, 0)
            except (can.CanError, OSError, RuntimeError) as exc:
                self._record_locked(
                    DriveTrip(TripCause.BUS_ERROR, f"could not send the quick stop: {exc}")
                )
