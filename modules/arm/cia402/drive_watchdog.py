"""A CiA 402 drive's watch on its master: heartbeat consumer and RPDO deadline.

A real drive does not trust its master to stay alive. Two standard watches (CiA 301) tell it
that the master froze (process stopped with SIGSTOP or Ctrl-Z, hung, unplugged):

- heartbeat consumer (0x1016 sub 1..n): ``node id << 16 | time in ms``; monitoring of that
  producer starts with its first heartbeat after the entry is set, and fires when no heartbeat
  came for the time;
- RPDO deadline monitoring (0x1400 sub 5, the event timer of a receive PDO, in ms): fires when
  no RPDO came for the time, counted from the first one in NMT OPERATIONAL.

On either, the drive sends an EMCY (0x8130 heartbeat error, 0x8250 RPDO timeout) and acts as
its abort connection option code (0x6007, CiA 402) says: 0 nothing, 1 fault, 2 disable voltage,
3 quick stop (0x605A's ramp). This module keeps the watch's times (drive clock, seconds); the
drive (sim_drive.py) asks it for the next deadline and reacts.
"""

from __future__ import annotations

from dataclasses import dataclass

EMCY_HEARTBEAT_ERROR = 0x8130
EMCY_RPDO_TIMEOUT = 0x8250
ERROR_REGISTER_COMMUNICATION = 0x10  # error register (0x1001) bit 4

#: Abort connection option codes (0x6007) the simulated drive implements.
ABORT_NO_ACTION = 0
ABORT_FAULT = 1
ABORT_DISABLE_VOLTAGE = 2
ABORT_QUICK_STOP = 3
ABORT_CONNECTION_OPTIONS = {
    ABORT_NO_ACTION: "no action",
    ABORT_FAULT: "fault signal",
    ABORT_DISABLE_VOLTAGE: "disable voltage",
    ABORT_QUICK_STOP: "quick stop",
}


@dataclass(frozen=True)
class ConsumerEntry:
    """One heartbeat consumer entry: watch node ``node_id``, at most ``time_s`` between beats."""

    node_id: int
    time_s: float


def consumer_entry(node_id: int, time_s: float) -> int:
    """The 0x1016 sub-index value for watching ``node_id`` with ``time_s`` (whole ms, 1..65535)."""
    ms = round(time_s * 1000)
    if not 1 <= node_id <= 127:
        raise ValueError(f"heartbeat producer node id must be 1..127, got {node_id}")
    if not 1 <= ms <= 0xFFFF:
        raise ValueError(f"heartbeat consumer time must be 0.001..65.535 s, got {time_s} s")
    return node_id << 16 | ms


def parse_consumer_entry(value: int) -> ConsumerEntry | None:
    """The entry a 0x1016 value holds; None when it is unused (node 0 or time 0)."""
    node_id = (value >> 16) & 0xFF
    ms = value & 0xFFFF
    if not 1 <= node_id <= 127 or ms == 0:
        return None
    return ConsumerEntry(node_id, ms / 1000.0)


@dataclass(frozen=True)
class Expiry:
    """A watch that fired: when (drive clock, s), the EMCY code, and why in words."""

    at: float
    emcy_code: int
    reason: str


class MasterWatch:
    """Last heartbeat of each producer and last RPDO (drive clock, s) and their deadlines."""

    def __init__(self) -> None:
        self._heartbeats: dict[int, float] = {}
        self._rpdo: float | None = None

    def heartbeat(self, node_id: int, at: float) -> None:
        """A heartbeat (or boot-up) of ``node_id`` arrived at ``at``."""
        self._heartbeats[node_id] = at

    def rpdo(self, at: float) -> None:
        """An RPDO arrived at ``at`` (in NMT OPERATIONAL)."""
        self._rpdo = at

    def reset_rpdo(self) -> None:
        """Deadline monitoring restarts with the next RPDO (NMT state change)."""
        self._rpdo = None

    def next_expiry(self, consumers: list[ConsumerEntry], rpdo_timeout_s: float) -> Expiry | None:
        """The earliest deadline of the armed watches (None: nothing armed)."""
        found: list[Expiry] = []
        for entry in consumers:
            last = self._heartbeats.get(entry.node_id)
            if last is not None:
                found.append(
                    Expiry(
                        last + entry.time_s,
                        EMCY_HEARTBEAT_ERROR,
                        f"no heartbeat of node {entry.node_id} for {entry.time_s:g} s",
                    )
                )
        if self._rpdo is not None and rpdo_timeout_s > 0:
            found.append(
                Expiry(
                    self._rpdo + rpdo_timeout_s,
                    EMCY_RPDO_TIMEOUT,
                    f"no RPDO for {rpdo_timeout_s:g} s",
                )
            )
        return min(found, key=lambda e: e.at, default=None)

    def fired(self, expiry: Expiry, consumers: list[ConsumerEntry]) -> None:
        """Disarm the watch that fired until its producer is heard again."""
        if expiry.emcy_code == EMCY_RPDO_TIMEOUT:
            self._rpdo = None
            return
        for entry in consumers:
            last = self._heartbeats.get(entry.node_id)
            if last is not None and last + entry.time_s <= expiry.at:
                del self._heartbeats[entry.node_id]
