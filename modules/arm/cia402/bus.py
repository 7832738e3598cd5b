"""The CAN bus of a CiA 402 arm: opening it with a watch on its health, and releasing it.

`open_bus` connects one canopen `Network` on python-can with `BusWatch` listening for error
frames and the death of the receive thread; `release_bus` stops SYNC, puts the drives back in
NMT PRE-OPERATIONAL and disconnects, logging (never raising) what fails on the way out.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable

import can
import canopen

from umbra.modules.arm.cia402.config import BusSpec, BusSpecError
from umbra.modules.arm.cia402.supervision import DriveRegisters

logger = logging.getLogger(__name__)

RECEIVE_POLL_S = 0.05  # receive thread's wait per poll: bounds how long closing the bus takes


class BusWatch(can.Listener):
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


def open_bus(
    spec: BusSpec,
    on_error_frame: Callable[[can.Message], None],
    on_dead: Callable[[Exception], None],
) -> canopen.Network:
    """A connected network on the bus `spec` names; BusSpecError when it cannot be opened."""
    network = canopen.Network()
    network.NOTIFIER_CYCLE = RECEIVE_POLL_S
    # canopen's list is inferred as list[MessageListener]; its Notifier takes any can.Listener
    network.listeners.append(BusWatch(on_error_frame, on_dead))  # type: ignore[arg-type]
    try:
        network.connect(interface=spec.interface, channel=spec.channel, bitrate=spec.bitrate)
    except Exception as exc:  # python-can raises many types here; all mean "no such bus"
        raise BusSpecError(
            f"cannot open CAN bus {spec.describe()}: {type(exc).__name__}: {exc}"
        ) from exc
    return network


def release_bus(network: canopen.Network, drives: Iterable[DriveRegisters]) -> None:
    """Stop SYNC, send the drives to NMT PRE-OPERATIONAL, disconnect (best effort)."""
    try:
        network.sync.stop()
        if network.bus is not None:
            for drive in drives:
                drive.node.nmt.state = "PRE-OPERATIONAL"
    except (can.CanError, OSError, RuntimeError) as exc:
        logger.warning("could not release the drives cleanly: %s", exc)
    try:
        network.disconnect()
    except (can.CanError, OSError, RuntimeError) as exc:
        logger.warning("closing the CAN bus: %s", exc)
