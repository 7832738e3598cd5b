"""Filling and sending one drive's RPDOs: controlword and target velocity (counts/s).

Never blocks on SDO: called from the servo step, the trip path and the start's first frame,
always with the arm's lock held (the registers' mapped variables are shared with the bus
thread's callbacks).
"""

from __future__ import annotations

from umbra.modules.arm.cia402 import objects as obj
from umbra.modules.arm.cia402.supervision import DriveRegisters


def write_rpdo(drive: DriveRegisters, controlword: int, target_counts_s: int) -> None:
    """Fill every mapped RPDO variable of `drive` and transmit (nothing before its layout)."""
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
