"""Setting up one drive of the arm while it starts (blocking, SDO): from NMT PRE-OPERATIONAL
to Operation enabled in profile velocity mode.

The steps, in order: identity check, producer heartbeat (0x1017) and waiting for it, the
drive's watchdog on the master (0x1016, 0x6007), PDO mapping (written, or read and checked)
with the TPDO callbacks attached, profile acceleration and quick-stop deceleration (rad/s²
turned into counts/s²), mode 3, NMT OPERATIONAL and waiting for the heartbeat to say so, the
power state machine to Operation enabled, the mode display check.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from functools import partial

from canopen.pdo import PdoMap

from umbra.modules.arm.cia402 import bring_up
from umbra.modules.arm.cia402 import objects as obj
from umbra.modules.arm.cia402.bring_up import DriveStartError
from umbra.modules.arm.cia402.config import Cia402ArmConfig
from umbra.modules.arm.cia402.supervision import NMT_OPERATIONAL, DriveRegisters

#: `wait(predicate, timeout_s, message)`: see `wait_until`.
Wait = Callable[[Callable[[], bool], float, "str | Callable[[], str]"], None]


def wait_until(
    lock: threading.Lock,
    predicate: Callable[[], bool],
    timeout_s: float,
    message: str | Callable[[], str],
    poll_s: float,
) -> None:
    """Poll `predicate` under `lock` every `poll_s` (s, at most 5 ms); DriveStartError(message)
    after `timeout_s` (s). A callable `message` is built under the lock when it is needed."""
    deadline = time.monotonic() + timeout_s
    while True:
        with lock:
            if predicate():
                return
        if time.monotonic() > deadline:
            with lock:
                text = message if isinstance(message, str) else message()
            raise DriveStartError(text)
        time.sleep(min(0.005, poll_s))


def set_up_drive(
    drive: DriveRegisters,
    cfg: Cia402ArmConfig,
    lock: threading.Lock,
    wait: Wait,
    on_tpdo: Callable[[DriveRegisters, PdoMap], None],
) -> None:
    """Bring `drive` to Operation enabled (see the module docstring); DriveStartError naming
    the drive and the step when one fails. `drive.layout` is set under `lock`."""
    node, label = drive.node, drive.label
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
    wait(
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
        pdo_map.add_callback(partial(on_tpdo, drive))
    with lock:
        drive.layout = layout
    _write_profile(drive, cfg)
    bring_up.set_profile_velocity_mode(node, label)
    node.nmt.state = "OPERATIONAL"
    wait(
        lambda: drive.nmt_state == NMT_OPERATIONAL,
        cfg.heartbeat_timeout_s + cfg.heartbeat_period_s,
        f"{label}: its heartbeat did not report NMT OPERATIONAL after the start command",
    )
    bring_up.enable_operation(node, label, cfg.enable_timeout_s)
    bring_up.check_mode_display(node, label)


def _write_profile(drive: DriveRegisters, cfg: Cia402ArmConfig) -> None:
    """Profile acceleration/deceleration and quick-stop deceleration, where configured and the
    drive has the object (rad/s² -> counts/s², at least 1)."""
    node, label = drive.node, drive.label
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
