"""The simulated drive's watch on its master, on the drive's own clock (see drive_watchdog.py).

A mixin of `SimDrive` (sim_drive.py): it reads and changes the drive's state under the drive's
lock. When a deadline passes, the motion up to the deadline is integrated with the old target,
the reaction (0x6007) starts at the deadline, and the drive ramps down by itself even when no
SYNC comes (the watch thread runs the motion), or in one step when the whole process was
stopped and continues.
"""

from __future__ import annotations

import logging
import threading
import time
from typing import TYPE_CHECKING

from umbra.modules.arm.cia402 import objects as obj
from umbra.modules.arm.cia402.drive_watchdog import (
    ABORT_CONNECTION_OPTIONS,
    ABORT_DISABLE_VOLTAGE,
    ABORT_FAULT,
    ABORT_QUICK_STOP,
    ERROR_REGISTER_COMMUNICATION,
    ConsumerEntry,
    Expiry,
    MasterWatch,
    parse_consumer_entry,
)
from umbra.modules.arm.cia402.state_machine import Command, State, next_state

if TYPE_CHECKING:
    import canopen

logger = logging.getLogger(__name__)

ERROR_REGISTER_GENERIC = 0x01
WATCH_IDLE_S = 0.05  # the watch thread's longest sleep
FREE_RUN_PERIOD_S = 0.01  # drive cycle of the watch thread while it stops the drive alone
#: Outside NMT OPERATIONAL (no SYNC cycle, an SDO master) a drive quick-stopped at standstill
#: shows Quick stop active at least this long before transition 12 [s].
QUICK_STOP_SHOWN_S = 0.1


class MasterWatchMixin:
    """Heartbeat consumer, RPDO deadline and the 0x6007 reaction of a `SimDrive`."""

    # provided by SimDrive
    node: canopen.LocalNode
    network: canopen.Network | None
    _lock: threading.RLock
    _state: State
    _velocity: float
    _last_sync: float | None
    _silent: bool
    _watch: MasterWatch
    _master_losses: int
    _free_run: bool
    _quick_stop_cycles: int
    _closing: threading.Event

    @property
    def node_id(self) -> int:
        raise NotImplementedError

    def advance(self, dt_s: float) -> None:
        raise NotImplementedError

    def _param(self, index: int, subindex: int = 0) -> int:
        raise NotImplementedError

    def _operational(self) -> bool:
        raise NotImplementedError

    def _fault(self, error_code: int, register: int) -> None:
        raise NotImplementedError

    def _on_heartbeat(self, can_id: int, data: bytearray, timestamp: float) -> None:
        with self._lock:
            now = time.monotonic()
            self._check_watch(now)  # a producer heard again after its deadline: it fired first
            self._watch.heartbeat(can_id - obj.HEARTBEAT_COB_BASE, now)

    # -- the watch on the master -----------------------------------------------------

    def _consumers(self) -> list[ConsumerEntry]:
        count = self._param(obj.CONSUMER_HEARTBEAT_TIME, 0)
        entries = (
            parse_consumer_entry(self._param(obj.CONSUMER_HEARTBEAT_TIME, i))
            for i in range(1, count + 1)
        )
        return [e for e in entries if e is not None]

    def _check_watch(self, now: float) -> None:
        """React to every watch whose deadline is at or before ``now`` (caller holds the lock)."""
        if not self._operational():
            self._watch.reset_rpdo()  # deadline monitoring restarts in OPERATIONAL
        while True:
            expiry = self._next_expiry()
            if expiry is None or expiry.at > now:
                return
            self._watch.fired(expiry, self._consumers())
            self._lose_master(expiry)

    def _next_expiry(self) -> Expiry | None:
        rpdo_ms = 0
        if self._operational():
            rpdo_ms = self._param(obj.RPDO_COMM_FIRST, obj.PDO_EVENT_TIMER_SUBINDEX)
        return self._watch.next_expiry(self._consumers(), rpdo_ms / 1000.0)

    def _run_until(self, at: float) -> None:
        """Integrate the motion from the last drive cycle to ``at`` (drive clock)."""
        if not self._operational():
            return
        if self._last_sync is not None and at > self._last_sync:
            self.advance(at - self._last_sync)
        self._last_sync = at

    def _lose_master(self, expiry: Expiry) -> None:
        self._run_until(expiry.at)  # the old target held until the deadline, not beyond
        self._master_losses += 1
        action = self._param(obj.ABORT_CONNECTION_OPTION_CODE)
        logger.warning(
            "node %d: %s: %s (0x6007 = %d)",
            self.node_id,
            expiry.reason,
            ABORT_CONNECTION_OPTIONS.get(action, "?"),
            action,
        )
        register = ERROR_REGISTER_GENERIC | ERROR_REGISTER_COMMUNICATION
        if action == ABORT_FAULT and self._state is not State.FAULT:
            self._fault(expiry.emcy_code, register)
        else:
            if not self._silent and self.network is not None:
                self.node.emcy.send(expiry.emcy_code, register)
            if action == ABORT_DISABLE_VOLTAGE:
                self._state = next_state(self._state, Command.DISABLE_VOLTAGE)
            elif action == ABORT_QUICK_STOP:
                option = self._param(obj.QUICK_STOP_OPTION_CODE)
                self._state = next_state(self._state, Command.QUICK_STOP, option)
                self._quick_stop_cycles = 0
                if self._state is State.QUICK_STOP_ACTIVE and option == 0:
                    self._velocity = 0.0
        self._free_run = True

    def _watch_loop(self) -> None:
        """The drive's own clock: the watch's deadlines fire on time, and a drive stopping
        (quick stop, or after losing its master) runs its stop when no SYNC drives it."""
        wait = WATCH_IDLE_S
        quick_stop_seen: float | None = None  # first own cycle in Quick stop active
        while not self._closing.wait(wait):
            with self._lock:
                now = time.monotonic()
                self._check_watch(now)
                stopping = self._free_run or self._state is State.QUICK_STOP_ACTIVE
                if self._state is not State.QUICK_STOP_ACTIVE:
                    quick_stop_seen = None
                elif quick_stop_seen is None:
                    quick_stop_seen = now
                if stopping and self._operational():
                    if self._last_sync is None or now - self._last_sync >= 2 * FREE_RUN_PERIOD_S:
                        self._run_until(now)  # no SYNC: the drive cycles by itself
                elif (
                    quick_stop_seen is not None
                    and now - quick_stop_seen >= QUICK_STOP_SHOWN_S
                    and self._velocity == 0.0
                ):
                    self.advance(0.0)  # a cycle at standstill (motion here runs on `advance`)
                self._free_run = self._free_run and (
                    self._velocity != 0.0 or self._state is State.QUICK_STOP_ACTIVE
                )
                wait = FREE_RUN_PERIOD_S if stopping else WATCH_IDLE_S
                expiry = self._next_expiry()
                if expiry is not None:
                    wait = min(wait, max(0.001, expiry.at - now))
