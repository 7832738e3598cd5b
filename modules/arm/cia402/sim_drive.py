"""Simulated CiA 402 servo drive: a canopen LocalNode on a real python-can bus.

The drive implements what a master needs to run it in profile velocity mode:

- the CiA 402 power state machine driven by the controlword (0x6040), reported in the
  statusword (0x6041), with quick stop (0x605A option codes 0, 1, 2, 5, 6) and
  fault / fault reset;
- modes of operation (0x6060, only 3 = profile velocity is accepted) and its display;
- a velocity loop with acceleration limits (0x6083, 0x6084, 0x6085): actual velocity
  (0x606C) slews to target velocity (0x60FF); position actual (0x6064) integrates it;
- PDOs as configured in its object dictionary (the master may rewrite the mapping by
  SDO; the drive follows): synchronous RPDOs are applied on the next SYNC, synchronous
  TPDOs are sent on SYNC after the motion step; PDOs only in NMT OPERATIONAL;
- producer heartbeat (0x1017), boot-up message, EMCY on faults;
- test hooks: `inject_fault` (error code in 0x603F, fault bit, EMCY) and `go_silent`
  (transmitter dead: no heartbeat, PDO, EMCY or SDO reply; it still receives).

Units are drive units: counts, counts/s, counts/s^2. Time is wall time measured between
SYNCs, or the `dt_s` given to `advance`.
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
from canopen.pdo import PdoMap, PdoMaps
from canopen.sdo import SdoAbortedError

from modules.arm.cia402 import objects as obj
from modules.arm.cia402.state_machine import (
    Command,
    State,
    command_from_controlword,
    next_state,
    statusword_for,
)

logger = logging.getLogger(__name__)

SDO_ABORT_VALUE_RANGE = 0x06090030
SDO_ABORT_DEVICE_STATE = 0x08000022

ERROR_REGISTER_GENERIC = 0x01

# Decelerations used by quick stop option codes: profile deceleration or quick stop one.
_QUICK_STOP_PROFILE_DECEL = frozenset({1, 5})
_QUICK_STOP_TO_DISABLED = frozenset({0, 1, 2, 3, 4})


class SimDrive:
    """One simulated CiA 402 drive (node `node_id`) for tests and hardware-free runs.

    Use as a context manager or call `connect` / `close`. Thread-safe: the bus thread
    (SDO, PDO, SYNC) and the caller (fault injection, inspection) share one lock.
    """

    def __init__(
        self, node_id: int, *, eds: str | Path = obj.EDS_PATH, position_counts: float = 0.0
    ) -> None:
        if not 1 <= node_id <= 127:
            raise ValueError(f"node id must be 1..127, got {node_id}")
        od = canopen.import_od(str(eds), node_id)
        self.node = canopen.LocalNode(node_id, od)
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
        self.node.add_read_callback(self._on_read)
        self.node.add_write_callback(self._on_write)
        for pdo_map in self.node.rpdo.map.values():
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
        self.network = network
        with self._lock:
            for maps in (self.node.rpdo.map, self.node.tpdo.map):
                for pdo_map in maps.values():
                    pdo_map.read(from_od=True)
            self.node.nmt.send_command(0x81)  # reset: boot-up message
            self.node.nmt.send_command(0x80)  # to PRE-OPERATIONAL, starts heartbeat
            self._state = State.SWITCH_ON_DISABLED  # power-up, transitions 0 and 1
        return self

    def close(self) -> None:
        """Stop the heartbeat and leave the bus."""
        if self.network is None:
            return
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
        return self.node.id

    @property
    def state(self) -> State:
        with self._lock:
            return self._state

    @property
    def position_counts(self) -> float:
        with self._lock:
            return self._position

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
            self._state = State.FAULT  # the fault reaction (stop at once) is immediate
            self._velocity = 0.0
            self._error_code = error_code & 0xFFFF
            self._error_register = ERROR_REGISTER_GENERIC
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
            target, decel_limit = self._velocity_goal()
            accel = self._param(obj.PROFILE_ACCELERATION)
            speeding_up = abs(target) > abs(v0) and (target * v0 >= 0)
            limit = accel if speeding_up else decel_limit
            step = limit * dt_s
            if limit <= 0 or abs(target - v0) <= step:
                v1 = float(target)
            else:
                v1 = v0 + step if target > v0 else v0 - step
            self._velocity = v1
            self._position += 0.5 * (v0 + v1) * dt_s
            if (
                self._state is State.QUICK_STOP_ACTIVE
                and v1 == 0.0
                and self._param(obj.QUICK_STOP_OPTION_CODE) in _QUICK_STOP_TO_DISABLED
            ):
                self._state = State.SWITCH_ON_DISABLED

    def _velocity_goal(self) -> tuple[float, float]:
        """Target velocity (counts/s) and deceleration limit (counts/s^2) for the state."""
        profile_decel = float(self._param(obj.PROFILE_DECELERATION))
        if self._state is State.OPERATION_ENABLED:
            if self._mode == obj.PROFILE_VELOCITY_MODE:
                return float(self._target_velocity), profile_decel
            return 0.0, profile_decel
        if self._state is State.QUICK_STOP_ACTIVE:
            option = self._param(obj.QUICK_STOP_OPTION_CODE)
            if option == 0:
                return 0.0, 0.0  # disable drive function: stop at once
            if option in _QUICK_STOP_PROFILE_DECEL:
                return 0.0, profile_decel
            return 0.0, float(self._param(obj.QUICK_STOP_DECELERATION))
        return 0.0, 0.0  # power stage off: the simulation holds the axis

    # -- object dictionary hooks -----------------------------------------------------

    def _param(self, index: int) -> int:
        """Current value of a plain parameter (stored by SDO/PDO or the EDS default)."""
        od_var = self.node.object_dictionary[index]
        assert isinstance(od_var, ODVariable)
        return int(od_var.decode_raw(self.node.get_data(index, 0)))

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
        if old is State.FAULT and self._state is State.SWITCH_ON_DISABLED:
            self._error_code = 0
            self._error_register = 0
            if not self._silent:
                self.node.emcy.reset()
        if self._state is State.QUICK_STOP_ACTIVE and option == 0:
            self._velocity = 0.0  # option 0: disable the drive function at once
        if (
            self._state is State.QUICK_STOP_ACTIVE
            and self._velocity == 0.0
            and option in _QUICK_STOP_TO_DISABLED
        ):
            self._state = State.SWITCH_ON_DISABLED  # already standing still
        if command is Command.ENABLE_OPERATION and old is not State.OPERATION_ENABLED:
            self._last_sync = None

    def _reload_pdo(self, index: int) -> None:
        offset = index & 0x1FF
        if index < obj.TPDO_COMM_FIRST:
            maps: PdoMaps = self.node.rpdo.map
        else:
            maps = self.node.tpdo.map
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
            if not self._operational():
                return
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
            if not self._operational():
                return
            now = time.monotonic()
            pending, self._pending_rpdos = self._pending_rpdos, []
            self._apply_values(pending)
            dt = 0.0 if self._last_sync is None else now - self._last_sync
            self._last_sync = now
            self.advance(dt)
            self._sync_count += 1
            if self._silent:
                return
            for pdo_map in self.node.tpdo.map.values():
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
