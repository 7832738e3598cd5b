"""Simulated CiA 402 servo drive: a canopen LocalNode on a real python-can bus.

The drive implements what a master needs to run it in profile velocity mode:

- the CiA 402 power state machine driven by the controlword (0x6040), reported in the
  statusword (0x6041), with fault / fault reset and quick stop for every option code of
  0x605A: 0 stop at once (drive function disabled), 1 / 5 profile deceleration (0x6084),
  2 / 6 quick stop deceleration (0x6085), 3 / 7 current limit and 4 / 8 voltage limit (the
  simulation has no motor model: both brake at max deceleration, 0x60C6); 0..4 end in
  Switch on disabled, 5..8 stay in Quick stop active. The drive leaves Quick stop active
  only in a drive cycle (SYNC, `advance`) that starts at standstill after a whole cycle in
  it, so every quick stop is reported in at least one TPDO, even from standstill (outside
  NMT OPERATIONAL, for SDO masters, for 0.1 s at least);
- modes of operation (0x6060, only 3 = profile velocity is accepted) and its display;
- a velocity loop with acceleration limits (0x6083, 0x6084, 0x6085): actual velocity
  (0x606C) slews to target velocity (0x60FF); position actual (0x6064) integrates it;
- PDOs as configured in its object dictionary (the master may rewrite the mapping by
  SDO; the drive follows): synchronous RPDOs are applied on the next SYNC, synchronous
  TPDOs are sent on SYNC after the motion step; PDOs only in NMT OPERATIONAL;
- producer heartbeat (0x1017), boot-up message, EMCY on faults;
- its own watch on the master (drive_watchdog.py, sim_drive_watch.py): heartbeat consumer
  (0x1016) and RPDO deadline (0x1400 sub 5); when one fires the drive acts as 0x6007 says,
  on its own clock, even when no SYNC comes or the whole process was stopped;
- test hooks: `inject_fault` (error code in 0x603F, fault bit, EMCY) and `go_silent`
  (transmitter dead: no heartbeat, PDO, EMCY or SDO reply; it still receives).

Units are drive units: counts, counts/s, counts/s^2. Time is wall time measured between
SYNCs (or the drive's own cycles while it stops with no SYNC), or the `dt_s` given to
`advance`.
"""

from __future__ import annotations

import logging
import threading
import time
from pathlib import Path
from types import TracebackType
from typing import Any

import canopen
from canopen.objectdictionary import ODVariable
from canopen.objectdictionary.datatypes import UNSIGNED_TYPES
from canopen.pdo import PdoMap, PdoMaps
from canopen.sdo import SdoAbortedError

from umbra.modules.arm.cia402 import objects as obj
from umbra.modules.arm.cia402.canopen_types import maps_of, node_id_of
from umbra.modules.arm.cia402.config import Cia402ConfigError
from umbra.modules.arm.cia402.drive_motion import (
    QUICK_STOP_DECELERATION,
    QUICK_STOP_TO_DISABLED,
    ramp,
)
from umbra.modules.arm.cia402.drive_watchdog import ABORT_CONNECTION_OPTIONS, MasterWatch
from umbra.modules.arm.cia402.eds_needs import SIM, EdsUnreadableError, eds_problem, load_od
from umbra.modules.arm.cia402.sim_drive_watch import ERROR_REGISTER_GENERIC, MasterWatchMixin
from umbra.modules.arm.cia402.state_machine import (
    Command,
    State,
    command_from_controlword,
    next_state,
    statusword_for,
)

logger = logging.getLogger(__name__)

SDO_ABORT_VALUE_RANGE = 0x06090030
SDO_ABORT_DEVICE_STATE = 0x08000022


class SimDrive(MasterWatchMixin):
    """One simulated CiA 402 drive (node `node_id`) for tests and hardware-free runs.

    Use as a context manager or call `connect` / `close`. Thread-safe: the bus thread
    (SDO, PDO, SYNC) and the caller (fault injection, inspection) share one lock. An `eds`
    without the objects the drive needs (eds_needs.py) is a `Cia402ConfigError` naming them.
    """

    def __init__(
        self, node_id: int, *, eds: str | Path = obj.EDS_PATH, position_counts: float = 0.0
    ) -> None:
        if not 1 <= node_id <= 127:
            raise ValueError(f"node id must be 1..127, got {node_id}")
        try:
            od = load_od(Path(eds), node_id)
        except EdsUnreadableError as exc:
            raise Cia402ConfigError(str(exc)) from None
        problem = eds_problem(od, Path(eds), frozenset({SIM}))
        if problem:  # refused here, before a bus or watch thread could trip over it
            raise Cia402ConfigError(problem)
        self.node = canopen.LocalNode(node_id, od)
        loss = od.get(obj.COMMUNICATION_LOSS_COUNT)
        # another vendor's EDS may use 0x2000 for something else: serve the count only as ours
        self._serves_loss_count = isinstance(loss, ODVariable) and loss.data_type in UNSIGNED_TYPES
        self.network: canopen.Network | None = None
        self._lock = threading.RLock()
        self._state = State.NOT_READY_TO_SWITCH_ON
        self._controlword = 0
        self._mode = 0
        self._target_velocity = 0
        self._velocity = 0.0  # counts/s
        self._position = float(position_counts)  # counts
        self._error_code = 0
        self._error_register = 0
        self._silent = False
        self._last_sync: float | None = None
        self._sync_count = 0
        self._pending_rpdos: list[tuple[int, int, bytes]] = []
        self._watch = MasterWatch()
        self._master_losses = 0
        self._free_run = False  # the watch fired: the drive runs its motion without SYNC
        self._quick_stop_cycles = 0  # drive cycles ended in Quick stop active
        self._closing = threading.Event()
        self._watch_thread: threading.Thread | None = None
        self.node.add_read_callback(self._on_read)
        self.node.add_write_callback(self._on_write)
        for pdo_map in maps_of(self.node.rpdo).values():
            pdo_map.add_callback(self._on_rpdo)

    # -- lifecycle -------------------------------------------------------------------

    def connect(
        self, *, interface: str = "virtual", channel: str = "umbra-cia402", bitrate: int = 500_000
    ) -> SimDrive:
        """Join the bus, boot (boot-up message, PRE-OPERATIONAL) and power the drive up."""
        network = canopen.Network()
        network.NOTIFIER_CYCLE = 0.05  # bounds how long close() waits for the receive thread
        network.connect(interface=interface, channel=channel, bitrate=bitrate)
        network.add_node(self.node)
        network.subscribe(obj.SYNC_COB_ID, self._on_sync)
        for node_id in range(1, 128):
            if node_id != self.node.id:
                network.subscribe(obj.HEARTBEAT_COB_BASE + node_id, self._on_heartbeat)
        self.network = network
        with self._lock:
            for maps in (maps_of(self.node.rpdo), maps_of(self.node.tpdo)):
                for pdo_map in maps.values():
                    pdo_map.read(from_od=True)
            self.node.nmt.send_command(0x81)  # reset: boot-up message
            self.node.nmt.send_command(0x80)  # to PRE-OPERATIONAL, starts heartbeat
            self._state = State.SWITCH_ON_DISABLED  # power-up, transitions 0 and 1
        self._closing.clear()
        self._watch_thread = threading.Thread(
            target=self._watch_loop, name=f"sim-drive-{self.node.id}-watch", daemon=True
        )
        self._watch_thread.start()
        return self

    def close(self) -> None:
        """Stop the heartbeat and leave the bus."""
        if self.network is None:
            return
        self._closing.set()
        if self._watch_thread is not None:
            self._watch_thread.join(timeout=1.0)
            self._watch_thread = None
        self.node.nmt.stop_heartbeat()
        self.network.disconnect()
        self.network = None

    def __enter__(self) -> SimDrive:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    # -- inspection (drive units) ----------------------------------------------------

    @property
    def node_id(self) -> int:
        return node_id_of(self.node)

    @property
    def state(self) -> State:
        with self._lock:
            return self._state

    @property
    def position_counts(self) -> float:
        with self._lock:
            return self._position

    @property
    def position_time(self) -> float | None:
        """Drive clock (time.monotonic, s) up to which `position_counts` is integrated: the last
        drive cycle in NMT OPERATIONAL (None before the first); the drive moves on between."""
        with self._lock:
            return self._last_sync

    @property
    def velocity_counts_s(self) -> float:
        with self._lock:
            return self._velocity

    @property
    def target_velocity_counts_s(self) -> int:
        with self._lock:
            return self._target_velocity

    @property
    def mode(self) -> int:
        with self._lock:
            return self._mode

    @property
    def error_code(self) -> int:
        with self._lock:
            return self._error_code

    @property
    def sync_count(self) -> int:
        with self._lock:
            return self._sync_count

    @property
    def nmt_state(self) -> str:
        return self.node.nmt.state

    @property
    def master_losses(self) -> int:
        """How many times the drive's watch on its master fired (also object 0x2000)."""
        with self._lock:
            return self._master_losses

    def statusword(self) -> int:
        with self._lock:
            return statusword_for(
                self._state,
                target_reached=self._state is State.OPERATION_ENABLED
                and self._velocity == self._target_velocity,
            )

    # -- test hooks ------------------------------------------------------------------

    def inject_fault(self, error_code: int = 0x2310) -> None:
        """Trip the drive: fault reaction (stop), Fault state, error code, EMCY.

        0x2310 is CiA 402's "continuous over current"; any 16-bit code is accepted.
        """
        with self._lock:
            self._fault(error_code, ERROR_REGISTER_GENERIC)

    def _fault(self, error_code: int, register: int) -> None:
        self._state = State.FAULT  # the fault reaction (stop at once) is immediate
        self._velocity = 0.0
        self._error_code = error_code & 0xFFFF
        self._error_register = register
        if not self._silent and self.network is not None:
            self.node.emcy.send(self._error_code, self._error_register)

    def go_silent(self, *, heartbeat_only: bool = False) -> None:
        """Stop the heartbeat; unless `heartbeat_only`, the whole transmitter dies too
        (no PDO, EMCY or SDO reply). The drive still receives (and obeys) the bus."""
        with self._lock:
            self.node.nmt.stop_heartbeat()
            if heartbeat_only:
                return
            self._silent = True
            if self.network is not None:
                self.network.unsubscribe(self.node.sdo.rx_cobid, self.node.sdo.on_request)

    # -- motion ----------------------------------------------------------------------

    def advance(self, dt_s: float) -> None:
        """Run the drive for `dt_s` seconds: velocity slews to its target, position integrates."""
        if dt_s < 0:
            raise ValueError(f"dt_s must be >= 0, got {dt_s}")
        with self._lock:
            v0 = self._velocity
            if (
                self._state is State.QUICK_STOP_ACTIVE
                and v0 == 0.0
                and self._quick_stop_cycles > 0
                and self._param(obj.QUICK_STOP_OPTION_CODE) in QUICK_STOP_TO_DISABLED
            ):
                self._state = State.SWITCH_ON_DISABLED  # transition 12: stood still a cycle
            target, decel_limit = self._velocity_goal()
            accel = self._param(obj.PROFILE_ACCELERATION)
            speeding_up = abs(target) > abs(v0) and (target * v0 >= 0)
            limit = accel if speeding_up else decel_limit
            v1, travel = ramp(v0, target, limit, dt_s)
            self._position += travel
            self._velocity = v1
            quick_stop = self._state is State.QUICK_STOP_ACTIVE
            self._quick_stop_cycles = self._quick_stop_cycles + 1 if quick_stop else 0

    def _velocity_goal(self) -> tuple[float, float]:
        """Target velocity (counts/s) and deceleration limit (counts/s^2) for the state."""
        profile_decel = float(self._param(obj.PROFILE_DECELERATION))
        if self._state is State.OPERATION_ENABLED:
            if self._mode == obj.PROFILE_VELOCITY_MODE:
                return float(self._target_velocity), profile_decel
            return 0.0, profile_decel
        if self._state is State.QUICK_STOP_ACTIVE:
            decel = QUICK_STOP_DECELERATION[self._param(obj.QUICK_STOP_OPTION_CODE)]
            return 0.0, 0.0 if decel is None else float(self._param(decel))
        return 0.0, 0.0  # power stage off (0: stop at once): the simulation holds the axis

    # -- object dictionary hooks -----------------------------------------------------

    def _param(self, index: int, subindex: int = 0) -> int:
        """Current value of a parameter (stored by SDO/PDO or the EDS default)."""
        entry = self.node.object_dictionary[index]
        od_var = entry if isinstance(entry, ODVariable) else entry[subindex]
        assert isinstance(od_var, ODVariable)
        return int(od_var.decode_raw(self.node.get_data(index, subindex)))

    def _on_read(self, index: int, subindex: int, od: ODVariable, **_: Any) -> int | None:
        with self._lock:
            if index == obj.STATUSWORD:
                return self.statusword()
            if index == obj.POSITION_ACTUAL:
                return _clamp_int32(round(self._position))
            if index == obj.VELOCITY_ACTUAL:
                return _clamp_int32(round(self._velocity))
            if index == obj.MODES_OF_OPERATION_DISPLAY:
                return self._mode
            if index == obj.ERROR_CODE:
                return self._error_code
            if index == obj.ERROR_REGISTER:
                return self._error_register
            if index == obj.CONTROLWORD:
                return self._controlword
            if index == obj.MODES_OF_OPERATION:
                return self._mode
            if index == obj.TARGET_VELOCITY:
                return self._target_velocity
            if index == obj.COMMUNICATION_LOSS_COUNT and self._serves_loss_count:
                return min(self._master_losses, 0xFFFF)
        return None

    def _on_write(self, index: int, subindex: int, od: ODVariable, data: bytes) -> None:
        with self._lock:
            if index == obj.CONTROLWORD:
                self._apply_controlword(int(od.decode_raw(data)))
            elif index == obj.MODES_OF_OPERATION:
                mode = int(od.decode_raw(data))
                if mode != obj.PROFILE_VELOCITY_MODE:
                    raise SdoAbortedError(SDO_ABORT_VALUE_RANGE)
                self._mode = mode
            elif index == obj.TARGET_VELOCITY:
                self._target_velocity = int(od.decode_raw(data))
            elif index == obj.QUICK_STOP_OPTION_CODE:
                if int(od.decode_raw(data)) not in QUICK_STOP_DECELERATION:
                    raise SdoAbortedError(SDO_ABORT_VALUE_RANGE)  # 0..8 are implemented
            elif index == obj.ABORT_CONNECTION_OPTION_CODE:
                if int(od.decode_raw(data)) not in ABORT_CONNECTION_OPTIONS:
                    raise SdoAbortedError(SDO_ABORT_VALUE_RANGE)  # 0..3 are implemented
            elif obj.is_pdo_parameter(index):
                # Callbacks run before the value is stored: store it first, then re-read.
                self.node.data_store.setdefault(index, {})[subindex] = bytes(data)
                self._reload_pdo(index)

    def _apply_controlword(self, controlword: int) -> None:
        command = command_from_controlword(controlword, self._controlword)
        self._controlword = controlword
        old = self._state
        option = self._param(obj.QUICK_STOP_OPTION_CODE)
        self._state = next_state(old, command, option)
        if self._state is not old:
            self._quick_stop_cycles = 0
        if old is State.FAULT and self._state is State.SWITCH_ON_DISABLED:
            self._error_code = 0
            self._error_register = 0
            if not self._silent:
                self.node.emcy.reset()
        if self._state is State.QUICK_STOP_ACTIVE and option == 0:
            self._velocity = 0.0  # option 0: disable the drive function at once
        if command is Command.ENABLE_OPERATION and old is not State.OPERATION_ENABLED:
            self._last_sync = None

    def _reload_pdo(self, index: int) -> None:
        offset = index & 0x1FF
        if index < obj.TPDO_COMM_FIRST:
            maps: PdoMaps = maps_of(self.node.rpdo)
        else:
            maps = maps_of(self.node.tpdo)
        number = offset + 1
        if number not in maps:
            return
        pdo_map = maps[number]
        if pdo_map.enabled and pdo_map.cob_id is not None and self.network is not None:
            callbacks = self.network.subscribers.get(pdo_map.cob_id, [])
            if pdo_map.on_message in callbacks:
                self.network.unsubscribe(pdo_map.cob_id, pdo_map.on_message)
        pdo_map.read(from_od=False)

    # -- bus handlers (bus thread) ---------------------------------------------------

    def _operational(self) -> bool:
        return self.node.nmt.state == "OPERATIONAL"

    def _on_rpdo(self, pdo_map: PdoMap) -> None:
        with self._lock:
            now = time.monotonic()
            self._check_watch(now)
            if not self._operational():
                return
            self._watch.rpdo(now)
            values = [(v.index, v.subindex, bytes(v.get_data())) for v in pdo_map.map if v.length]
            if pdo_map.trans_type is not None and pdo_map.trans_type <= 240:
                self._pending_rpdos.extend(values)
            else:
                self._apply_values(values)

    def _apply_values(self, values: list[tuple[int, int, bytes]]) -> None:
        for index, subindex, data in values:
            try:
                self.node.set_data(index, subindex, data)
            except SdoAbortedError as exc:
                logger.info("node %d: RPDO value for 0x%04X refused: %s", self.node_id, index, exc)

    def _on_sync(self, can_id: int, data: bytearray, timestamp: float) -> None:
        with self._lock:
            now = time.monotonic()
            self._check_watch(now)
            if not self._operational():
                return
            pending, self._pending_rpdos = self._pending_rpdos, []
            self._apply_values(pending)
            dt = 0.0 if self._last_sync is None else now - self._last_sync
            self._last_sync = now
            self.advance(dt)
            self._sync_count += 1
            if self._silent:
                return
            for pdo_map in maps_of(self.node.tpdo).values():
                trans_type = pdo_map.trans_type
                if not pdo_map.enabled or trans_type is None or not 1 <= trans_type <= 240:
                    continue
                if self._sync_count % trans_type:
                    continue
                for var in pdo_map.map:
                    if var.length:
                        var.set_data(self.node.get_data(var.index, var.subindex)[: var.length // 8])
                pdo_map.transmit()


def _clamp_int32(value: int) -> int:
    return max(obj.INT32_MIN, min(obj.INT32_MAX, value))
