"""The drives stop on their own when their master freezes.

The master (`Cia402Arm`) sets up each drive's watchdog at start: heartbeat consumer 0x1016 on
the master's own heartbeat (sent by its monitor thread) and the reaction 0x6007. Checked on a
python-can virtual bus against the simulated drive: a master frozen in place (its lock held:
no heartbeat, no command, no supervision, while SYNC goes on as the kernel's broadcast manager
sends it on socketcan), a master process stopped with SIGSTOP (drives and master in that
process, as with `simulate: true`), the RPDO deadline, and a drive with no SYNC at all.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import canopen
import numpy as np
import pytest

from tests.poll import wait_for
from umbra.modules.arm.cia402 import (
    ArmState,
    BusSpec,
    Cia402Arm,
    Cia402ArmConfig,
    Cia402ConfigError,
    JointDrive,
    SimDrive,
)
from umbra.modules.arm.cia402 import objects as obj
from umbra.modules.arm.cia402.config_yaml import load_canopen_settings
from umbra.modules.arm.cia402.drive_watchdog import consumer_entry
from umbra.modules.arm.cia402.state_machine import State

from .conftest import COUNTS_PER_RAD

MakeDrives = Callable[..., list[SimDrive]]
MakeArm = Callable[..., Cia402Arm]
RATE = 1.0  # rad/s: 10000 counts/s
QUICK_STOP_DECEL = 5.0  # rad/s^2: 50000 counts/s^2, a 0.2 s stop over 0.1 rad


@pytest.mark.timeout(20)
def test_start_sets_up_the_drives_watchdog_and_the_master_heartbeat(
    sim_drives: MakeDrives, make_arm: MakeArm
) -> None:
    drives = sim_drives(1, 2)
    # a watchdog of 0.5 s: a loaded machine (load 10) stalls the master's heartbeat thread for
    # a good part of 0.15 s now and then, which is the drive's business, not this test's
    arm = make_arm((1, 2), drive_heartbeat_timeout_s=0.5, abort_connection_option=2)
    arm.start()
    for drive in drives:
        assert drive.node.sdo[obj.CONSUMER_HEARTBEAT_TIME][1].raw == 127 << 16 | 500
        assert drive.node.sdo[obj.ABORT_CONNECTION_OPTION_CODE].raw == 2
    time.sleep(1.5)  # the master's heartbeat keeps the drives' watchdogs quiet
    assert [d.master_losses for d in drives] == [0, 0]
    assert arm.status().ok


def true_position(drive: SimDrive, at: float) -> float:
    """The drive's position (counts) at ``at`` while it runs at a constant speed: its position
    is integrated up to its last cycle (SYNC), and it moved on since."""
    with drive._lock:
        assert drive.position_time is not None
        return drive.position_counts + drive.velocity_counts_s * (at - drive.position_time)


@pytest.mark.timeout(20)
def test_a_frozen_master_leaves_drives_that_stop_by_themselves(
    sim_drives: MakeDrives, make_arm: MakeArm
) -> None:
    drives = sim_drives(1, 2)
    timeout_s = 0.2
    arm = make_arm(
        (1, 2),
        drive_heartbeat_timeout_s=timeout_s,
        quick_stop_deceleration_rad_s2=QUICK_STOP_DECEL,
        command_timeout_s=None,
    )
    arm.start()
    rates = np.array([RATE, -RATE])
    for _ in range(30):
        arm.set_velocities(rates)
        time.sleep(0.01)
    wait_for(lambda: drives[0].velocity_counts_s == RATE * COUNTS_PER_RAD, 1.0, "full speed")
    with arm._lock:  # the master freezes: no heartbeat, command or supervision; SYNC goes on
        frozen_at = time.monotonic()
        start = true_position(drives[0], frozen_at)
        wait_for(lambda: drives[0].velocity_counts_s == 0, 2.0, "the drive to stop alone")
        stopped_after = time.monotonic() - frozen_at
        # the other drive stops alone too (on its own bus thread, a moment apart), and both
        # end the quick stop disabled
        wait_for(
            lambda: (
                drives[1].velocity_counts_s == 0
                and all(d.state is State.SWITCH_ON_DISABLED for d in drives)
            ),
            2.0,
            lambda: f"both drives stopped and disabled; found {[d.state for d in drives]}",
        )
        travel_rad = (drives[0].position_counts - start) / COUNTS_PER_RAD
    # The target is held until the watchdog time, then the quick stop ramp (option code 2).
    ramp_s = RATE / QUICK_STOP_DECEL
    bound = RATE * (timeout_s + 0.02) + RATE**2 / (2 * QUICK_STOP_DECEL)  # 0.02: SYNC slack
    print(
        f"frozen master: drive stopped after {stopped_after:.3f} s, travel {travel_rad:.3f} rad "
        f"(bound {bound:.3f} rad; without its watchdog it ran on at {RATE} rad/s)"
    )
    assert travel_rad <= bound
    assert stopped_after <= timeout_s + ramp_s + 0.1
    assert all(d.state is State.SWITCH_ON_DISABLED for d in drives)
    assert [d.master_losses for d in drives] == [1, 1]
    assert drives[0].node.sdo[obj.COMMUNICATION_LOSS_COUNT].raw == 1
    # The master, running again, finds its drives stopped and trips (it does not restart them).
    wait_for(lambda: arm.status().state is ArmState.TRIPPED, 2.0, "the master's trip")
    assert "0x8130" in arm.status().message or "left operation enabled" in arm.status().message
    assert not arm.set_velocities(rates)


@pytest.mark.timeout(20)
def test_without_the_watchdog_a_frozen_master_leaves_the_drive_running(
    sim_drives: MakeDrives, make_arm: MakeArm
) -> None:
    """The control: the same freeze with no heartbeat consumer set up (null in the YAML)."""
    drives = sim_drives(1)
    arm = make_arm((1,), drive_heartbeat_timeout_s=None, command_timeout_s=None)
    arm.start()
    arm.set_velocities([RATE])
    wait_for(lambda: drives[0].velocity_counts_s == RATE * COUNTS_PER_RAD, 1.0, "full speed")
    with arm._lock:
        time.sleep(0.6)  # a window: longer than a watchdog would take
        assert drives[0].velocity_counts_s == RATE * COUNTS_PER_RAD
    assert drives[0].master_losses == 0


FREEZE_SCRIPT = """
import json, sys, time
from umbra.modules.arm.cia402 import BusSpec, Cia402Arm, Cia402ArmConfig, JointDrive, SimDrive
channel, timeout_s, run_s = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
drives = [SimDrive(n).connect(channel=channel) for n in (1, 2)]
joints = (JointDrive("a", 1, 10000.0), JointDrive("b", 2, 10000.0))
arm = Cia402Arm(Cia402ArmConfig(
    bus=BusSpec("virtual", channel), joints=joints, drive_heartbeat_timeout_s=timeout_s,
    heartbeat_timeout_s=0.5, feedback_timeout_s=0.5, quick_stop_deceleration_rad_s2=5.0))
arm.start()
print("ready", flush=True)
end = time.monotonic() + run_s
while time.monotonic() < end:
    arm.set_velocities([1.0, -1.0])
    with drives[0]._lock:  # position integrated up to position_time, speed since
        row = [time.monotonic(), drives[0].position_counts, drives[0].velocity_counts_s,
               arm.status().state.value, drives[0].position_time]
    print(json.dumps(row), flush=True)
    time.sleep(0.01)
arm.stop()
for d in drives:
    d.close()
"""


@pytest.mark.timeout(120)
@pytest.mark.parametrize("stop_s", [1.0, pytest.param(5.0, marks=pytest.mark.slow)])
def test_sigstop_of_the_master_process_stops_its_drives_within_their_watchdog(
    channel: str, stop_s: float
) -> None:
    """Master and simulated drives in one real process (as `simulate: true` runs them), the
    process stopped with SIGSTOP: when it continues, the drives have held their target for
    their watchdog time only (their own clock went on), then quick-stopped."""
    timeout_s = 0.2
    proc = subprocess.Popen(
        [sys.executable, "-c", FREEZE_SCRIPT, channel, str(timeout_s), str(2.0 + stop_s)],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
        cwd=Path(__file__).parents[2],
    )
    assert proc.stdout is not None
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(proc.stdout), daemon=True)
    try:
        assert proc.stdout.readline().strip() == "ready"
        reader.start()

        def at_full_speed() -> bool:  # the latest row: the drive at full speed, the arm running
            row = json.loads(lines[-1]) if lines else None
            return row is not None and row[2] == 10000 and row[3] == "running"

        wait_for(at_full_speed, 10.0, lambda: f"the drive at full speed; rows {lines[-3:]}")
        stopped_at = time.monotonic()  # CLOCK_MONOTONIC: the same clock in both processes
        proc.send_signal(signal.SIGSTOP)
        time.sleep(stop_s)
        proc.send_signal(signal.SIGCONT)
        assert proc.wait(timeout=60) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    reader.join(timeout=5)
    rows = [json.loads(line) for line in lines]
    t = np.array([r[0] for r in rows])
    position = np.array([r[1] for r in rows]) / 10000.0  # rad
    i = int(np.argmax(np.diff(t)))
    assert t[i + 1] - t[i] >= 0.9 * stop_s
    assert rows[i][2] == 10000 and rows[i][3] == "running", (
        "the arm had stopped before the SIGSTOP: on this machine the process went without the "
        f"CPU for longer than its watchdog ({timeout_s} s) while running; rerun when less loaded"
    )
    after = int(np.searchsorted(t, t[i + 1] + 0.3))  # the drives stand still by then
    # where the drive was when the process stopped: at full speed since its last cycle
    at_stop = position[i] + RATE * (stopped_at - rows[i][4])
    travel = position[after] - at_stop
    bound = RATE * (timeout_s + 0.02) + RATE**2 / (2 * QUICK_STOP_DECEL)
    print(
        f"master process stopped {t[i + 1] - t[i]:.2f} s: drive travel {travel:.3f} rad "
        f"(bound {bound:.3f} rad; without its watchdog {RATE * stop_s:.1f} rad)"
    )
    near = [[round(r[0] - t[i], 3), *r[1:]] for r in rows[max(0, i - 3) : after + 1]]
    assert travel <= bound, near
    assert rows[-1][2] == 0 and rows[-1][3] == "tripped"  # stopped, and the master knows


@pytest.fixture
def raw_master(
    channel: str, sim_drives: MakeDrives
) -> Iterator[tuple[SimDrive, canopen.RemoteNode, canopen.Network]]:
    (drive,) = sim_drives(3)
    network = canopen.Network()
    network.NOTIFIER_CYCLE = 0.05
    network.connect(interface="virtual", channel=channel)
    node = network.add_node(3, canopen.import_od(str(obj.EDS_PATH), 3))
    yield drive, node, network
    network.disconnect()


def enable(node: canopen.RemoteNode, network: canopen.Network) -> None:
    node.nmt.state = "OPERATIONAL"
    node.sdo[obj.MODES_OF_OPERATION].raw = obj.PROFILE_VELOCITY_MODE
    node.sdo[obj.QUICK_STOP_DECELERATION].raw = 50_000
    node.sdo[obj.ABORT_CONNECTION_OPTION_CODE].raw = 3
    for word in (0x06, 0x07, 0x0F):
        node.sdo[obj.CONTROLWORD].raw = word


@pytest.mark.timeout(20)
def test_rpdo_deadline_stops_the_drive_when_commands_stop(
    raw_master: tuple[SimDrive, canopen.RemoteNode, canopen.Network],
) -> None:
    drive, node, network = raw_master
    node.sdo[obj.RPDO_COMM_FIRST][obj.PDO_EVENT_TIMER_SUBINDEX].raw = 200  # ms
    node.rpdo.read(from_od=True)
    enable(node, network)
    emcy = []
    node.emcy.add_callback(emcy.append)
    network.sync.start(0.01)
    rpdo = node.rpdo[1]
    rpdo[obj.CONTROLWORD].raw = 0x0F
    rpdo[obj.TARGET_VELOCITY].raw = 10_000
    for _ in range(30):  # commands every 10 ms: the deadline holds
        rpdo.transmit()
        time.sleep(0.01)
    assert drive.velocity_counts_s == 10_000 and drive.master_losses == 0
    wait_for(lambda: drive.velocity_counts_s == 0, 1.0, "the stop on the RPDO deadline")
    wait_for(lambda: [e.code for e in emcy] == [0x8250], 1.0, "EMCY 0x8250 RPDO timeout")
    wait_for(lambda: drive.state is State.SWITCH_ON_DISABLED, 1.0, "transition 12")
    assert drive.master_losses == 1
    network.sync.stop()


@pytest.mark.timeout(20)
def test_a_drive_without_sync_still_ramps_down_on_its_own_clock(
    raw_master: tuple[SimDrive, canopen.RemoteNode, canopen.Network],
) -> None:
    drive, node, network = raw_master
    node.sdo[obj.CONSUMER_HEARTBEAT_TIME][1].raw = consumer_entry(100, 0.1)
    enable(node, network)
    node.sdo[obj.TARGET_VELOCITY].raw = 10_000
    network.sync.transmit()
    time.sleep(0.05)  # pacing: the second SYNC a cycle after the first
    network.sync.transmit()  # two SYNCs: the drive runs at its target
    wait_for(lambda: drive.velocity_counts_s == 10_000, 1.0, "the target speed")
    network.send_message(0x700 + 100, bytes([5]))  # one heartbeat arms the consumer, then none
    start = true_position(drive, time.monotonic())
    wait_for(lambda: drive.velocity_counts_s == 0, 1.0, "the stop without SYNC")
    # 0.1 s at 10000 counts/s at most (from the last SYNC), then 10000^2 / (2 x 50000)
    assert drive.position_counts - start <= 10_000 * 0.1 + 1_000 + 50  # 50: the clock read
    wait_for(lambda: drive.state is State.SWITCH_ON_DISABLED, 1.0, "transition 12")


def test_watchdog_settings_from_yaml(tmp_path: Path) -> None:
    path = tmp_path / "arm.yaml"
    path.write_text(
        "bus: {interface: virtual, channel: x}\n"
        "master_node_id: 100\nmaster_heartbeat_period: 0.01\n"
        "drive_heartbeat_timeout: 0.05\nabort_connection_option: 1\n"
        "joints: [{name: a, node_id: 1, counts_per_rad: 1000}]\n"
    )
    arm = load_canopen_settings(path).arm
    assert (arm.master_node_id, arm.master_heartbeat_period_s) == (100, 0.01)
    assert (arm.drive_heartbeat_timeout_s, arm.abort_connection_option) == (0.05, 1)
    path.write_text(path.read_text().replace("0.05", "null"))
    assert load_canopen_settings(path).arm.drive_heartbeat_timeout_s is None
    path.write_text(path.read_text().replace("null", "0.015"))
    with pytest.raises(Cia402ConfigError, match=r"arm.yaml:\d+: error: .*drive_heartbeat"):
        load_canopen_settings(path)


def test_watchdog_settings_are_checked() -> None:
    joints = (JointDrive("a", 1, COUNTS_PER_RAD),)
    bus = BusSpec("virtual", "x")
    for settings, message in (
        ({"master_node_id": 1}, "also a drive's node id"),
        ({"master_node_id": 128}, "1..127"),
        ({"drive_heartbeat_timeout_s": 0.03}, r"2 x master_heartbeat_period_s \(0.04 s\)"),
        ({"drive_heartbeat_timeout_s": 2.0}, r"\.\. 1 s"),
        ({"abort_connection_option": 0}, "1 \\(fault signal\\), 2 \\(disable voltage\\)"),
    ):
        with pytest.raises(Cia402ConfigError, match=message):
            Cia402ArmConfig(bus=bus, joints=joints, **settings)


def test_a_drive_that_cannot_watch_its_master_is_refused(tmp_path: Path) -> None:
    """An EDS without a heartbeat consumer: refused when the settings are made, before any bus
    (eds_needs.py); without the drives' watchdog the same EDS is fine for the master."""
    text = obj.EDS_PATH.read_text()
    sections = [s for s in text.split("\n\n") if not s.lstrip().startswith("[1016")]
    eds = tmp_path / "no_1016.eds"
    eds.write_text("\n\n".join(sections).replace("1=0x1016\n", ""))
    joints = (JointDrive("a", 1, COUNTS_PER_RAD),)
    with pytest.raises(Cia402ConfigError) as caught:
        Cia402ArmConfig(bus=BusSpec("virtual", "x"), joints=joints, eds=eds)
    message = str(caught.value)
    assert f"EDS file {eds} lacks 1 object(s)" in message
    assert "0x1016 sub 1 Consumer heartbeat time (master with drive_heartbeat_timeout)" in message
    assert "drive_heartbeat_timeout: null runs without" in message
    config = Cia402ArmConfig(
        bus=BusSpec("virtual", "x"), joints=joints, eds=eds, drive_heartbeat_timeout_s=None
    )
    assert config.eds == eds
