"""The CANopen master against four simulated CiA 402 drives on a virtual bus."""

from __future__ import annotations

import time
from collections.abc import Callable

import can
import numpy as np
import pytest

from tests.poll import wait_for
from umbra.modules.arm.cia402 import ArmState, Cia402Arm, DriveStartError, SimDrive, TripCause
from umbra.modules.arm.cia402.state_machine import State

from .conftest import COUNTS_PER_RAD

NODES = (1, 2, 3, 4)
MakeDrives = Callable[..., list[SimDrive]]
MakeArm = Callable[..., Cia402Arm]


def drive_for(arm: Cia402Arm, rates: np.ndarray, duration_s: float) -> float:
    """Command `rates` every 10 ms for `duration_s`, then zero; return the time it ran."""
    start = time.monotonic()
    while time.monotonic() - start < duration_s:
        assert arm.set_velocities(rates)
        time.sleep(0.01)
    arm.set_velocities(np.zeros_like(rates))
    return time.monotonic() - start


def pre_operational(drives: list[SimDrive]) -> None:
    """Wait until every drive has taken the master's NMT PRE-OPERATIONAL (sent without answer)."""
    wait_for(
        lambda: all(d.nmt_state == "PRE-OPERATIONAL" for d in drives),
        2.0,
        lambda: f"NMT PRE-OPERATIONAL on every drive; found {[d.nmt_state for d in drives]}",
    )


def stopped(drives: list[SimDrive]) -> bool:
    return all(d.velocity_counts_s == 0 and d.state is not State.OPERATION_ENABLED for d in drives)


@pytest.mark.timeout(15)
def test_enable_drive_read_back_and_stop(sim_drives: MakeDrives, make_arm: MakeArm) -> None:
    drives = sim_drives(*NODES)
    arm = make_arm(NODES)
    arm.start()
    assert arm.status().ok
    assert all(d.state is State.OPERATION_ENABLED for d in drives)
    assert all(d.mode == 3 and d.nmt_state == "OPERATIONAL" for d in drives)
    assert arm.read().states == (State.OPERATION_ENABLED,) * 4

    rates = np.array([0.8, -0.5, 0.25, 0.0])
    before = arm.read().positions_rad
    # While moving, velocity actual comes back as commanded (after the drives' ramps).
    for _ in range(20):
        arm.set_velocities(rates)
        time.sleep(0.01)
    wait_for(
        lambda: arm.set_velocities(rates) and np.allclose(arm.read().velocities_rad_s, rates),
        2.0,
        "velocity actual to reach the commanded rates",
    )
    ran_s = 0.2 + drive_for(arm, rates, 0.4)
    wait_for(lambda: np.all(arm.read().velocities_rad_s == 0), 2.0, "standstill")
    still_at = time.monotonic()

    def fed_back_since_standstill() -> bool:  # one more TPDO from every drive after standstill
        now = time.monotonic()  # read() takes its own "now" after this one
        return bool(np.all(now - arm.read().ages_s > still_at))

    wait_for(fed_back_since_standstill, 2.0, "a TPDO from every drive after standstill")
    after = arm.read()
    travelled = after.positions_rad - before

    # Positions integrate the commanded rates (ramps up and down cancel: equal accel/decel);
    # the tolerance covers the SYNC/thread latencies at start and end of the motion.
    np.testing.assert_allclose(travelled, rates * ran_s, rtol=0.15, atol=0.01)
    assert travelled[3] == 0.0
    # The master reads exactly what the drives hold (to one count).
    truth = np.array([d.position_counts for d in drives]) / COUNTS_PER_RAD
    np.testing.assert_allclose(after.positions_rad, truth, atol=1.0 / COUNTS_PER_RAD)
    assert np.all(after.ages_s < 1.0)

    arm.stop()
    assert arm.status().state is ArmState.STOPPED and not arm.status().trips
    assert stopped(drives)
    # NMT has no answer: the drives take the command on their own bus thread, a moment later.
    pre_operational(drives)
    assert not arm.set_velocities(rates)


@pytest.mark.timeout(15)
def test_fault_on_one_drive_stops_all_and_names_it(
    sim_drives: MakeDrives, make_arm: MakeArm
) -> None:
    drives = sim_drives(*NODES)
    arm = make_arm(NODES)
    arm.start()
    rates = np.array([0.5, 0.5, -0.5, 0.5])
    drive_for(arm, rates, 0.1)
    for _ in range(5):
        arm.set_velocities(rates)
    wait_for(lambda: all(d.velocity_counts_s != 0 for d in drives), 2.0, "motion")

    drives[2].inject_fault(0x2310)
    wait_for(lambda: arm.status().state is ArmState.TRIPPED, 2.0, "the trip")
    wait_for(
        lambda: any(t.cause is TripCause.FAULT for t in arm.status().trips), 2.0, "the fault bit"
    )
    status = arm.status()
    assert {t.node_id for t in status.trips} == {3}
    assert {t.joint for t in status.trips} == {"j3"}
    assert {t.cause for t in status.trips} <= {TripCause.FAULT, TripCause.EMERGENCY}
    assert all(t.error_code == 0x2310 for t in status.trips)
    assert "joint 'j3' (node 3)" in status.message and "0x2310" in status.message

    wait_for(lambda: stopped(drives), 2.0, "every drive to stop")
    # Each drive takes the master's quick stop (target 0) on a SYNC of its own bus thread: the
    # faulted drive stood still at once and may take it after the others have stopped.
    wait_for(
        lambda: all(d.target_velocity_counts_s == 0 for d in drives),
        2.0,
        lambda: f"target 0 on every drive; found {[d.target_velocity_counts_s for d in drives]}",
    )
    assert drives[2].state is State.FAULT
    assert not arm.set_velocities(rates)
    # Nothing was sent: two more SYNCs on every drive (pending RPDOs apply on SYNC) keep target 0.
    syncs = [d.sync_count for d in drives]
    wait_for(
        lambda: all(d.sync_count >= n + 2 for d, n in zip(drives, syncs, strict=True)),
        2.0,
        "two more SYNCs on every drive",
    )
    assert all(d.target_velocity_counts_s == 0 for d in drives)


@pytest.mark.timeout(15)
def test_lost_heartbeat_is_detected_and_stops_all(
    sim_drives: MakeDrives, make_arm: MakeArm
) -> None:
    drives = sim_drives(*NODES)
    timeout_s = 0.25
    arm = make_arm(NODES, heartbeat_period_s=0.05, heartbeat_timeout_s=timeout_s)
    arm.start()
    rates = np.array([0.3, 0.3, 0.3, 0.3])
    drive_for(arm, rates, 0.3)
    for _ in range(3):
        arm.set_velocities(rates)
    assert arm.status().ok  # healthy heartbeats never tripped it

    silenced_at = time.monotonic()
    drives[1].go_silent(heartbeat_only=True)  # PDOs and SDO still work: only the heartbeat
    while arm.status().state is ArmState.RUNNING:
        arm.set_velocities(rates)
        if time.monotonic() - silenced_at > timeout_s + 2.0:
            pytest.fail("the lost heartbeat was not detected")
        time.sleep(0.005)
    detected_after = time.monotonic() - silenced_at

    (trip,) = arm.status().trips
    assert (trip.cause, trip.node_id, trip.joint) == (TripCause.HEARTBEAT_LOST, 2, "j2")
    assert "no heartbeat for" in trip.detail
    # Judged by the heartbeat timeout, not by one missed period (the last heartbeat may
    # predate the silence by a period or more when threads are late, hence the margin).
    assert detected_after > 0.5 * timeout_s
    wait_for(lambda: stopped(drives), 2.0, "every drive to stop")


@pytest.mark.timeout(15)
def test_dead_transmitter_is_detected_and_stops_all(
    sim_drives: MakeDrives, make_arm: MakeArm
) -> None:
    drives = sim_drives(*NODES)
    arm = make_arm(NODES, heartbeat_timeout_s=0.2, feedback_timeout_s=0.2)
    arm.start()
    drive_for(arm, np.full(4, 0.2), 0.1)
    drives[3].go_silent()
    wait_for(lambda: arm.status().state is ArmState.TRIPPED, 2.0, "the trip")
    wait_for(
        lambda: any(t.cause is TripCause.HEARTBEAT_LOST for t in arm.status().trips),
        2.0,
        "the heartbeat loss",
    )
    # The silent drive still receives: it got the quick stop too.
    wait_for(lambda: stopped(drives), 2.0, "every drive to stop")
    arm.stop()  # does not hang on the silent drive
    status = arm.status()
    assert status.state is ArmState.STOPPED  # and the reasons are kept for the operator
    assert {t.node_id for t in status.trips} == {4}
    assert {t.cause for t in status.trips} <= {TripCause.HEARTBEAT_LOST, TripCause.FEEDBACK_LOST}


@pytest.mark.timeout(15)
def test_bus_off_error_frame_stops_all(
    channel: str, sim_drives: MakeDrives, make_arm: MakeArm
) -> None:
    drives = sim_drives(1, 2)
    arm = make_arm((1, 2))
    arm.start()
    drive_for(arm, np.array([0.4, -0.4]), 0.1)
    with can.Bus(interface="virtual", channel=channel) as other:
        other.send(can.Message(is_error_frame=True, arbitration_id=0x40, data=bytes(8)))
    wait_for(lambda: arm.status().state is ArmState.TRIPPED, 2.0, "the trip")
    (trip,) = arm.status().trips
    assert trip.cause is TripCause.BUS_ERROR and trip.node_id is None
    assert "bus-off" in trip.detail and arm.status().error_frames == 1
    wait_for(lambda: stopped(drives), 2.0, "every drive to stop")


@pytest.mark.timeout(15)
def test_drives_own_pdo_mapping_and_command_watchdog(
    sim_drives: MakeDrives, make_arm: MakeArm
) -> None:
    drives = sim_drives(1, 2)
    arm = make_arm((1, 2), configure_pdos=False, command_timeout_s=0.1)
    arm.start()
    arm.set_velocities([0.5, 0.5])
    wait_for(lambda: np.allclose(arm.read().velocities_rad_s, 0.5), 2.0, "motion")
    # No further command: after the command timeout the targets drop to zero, no trip.
    wait_for(lambda: arm.status().command_stale, 2.0, "the command watchdog")
    wait_for(lambda: all(d.velocity_counts_s == 0 for d in drives), 2.0, "standstill")
    assert arm.status().state is ArmState.RUNNING and not arm.status().trips
    assert all(d.state is State.OPERATION_ENABLED for d in drives)
    assert arm.set_velocities([-0.2, 0.1]) and not arm.status().command_stale


@pytest.mark.timeout(15)
def test_non_finite_rate_trips(sim_drives: MakeDrives, make_arm: MakeArm) -> None:
    drives = sim_drives(1, 2)
    arm = make_arm((1, 2))
    arm.start()
    with pytest.raises(ValueError, match=r"expected 2 joint rates \('j1', 'j2'\)"):
        arm.set_velocities([0.1, 0.2, 0.3])
    assert not arm.set_velocities([0.1, np.nan])
    (trip,) = arm.status().trips
    assert trip.cause is TripCause.BAD_COMMAND and "j2" in trip.detail
    wait_for(lambda: stopped(drives), 2.0, "every drive to stop")


@pytest.mark.timeout(15)
def test_restart_after_a_fault_resets_the_drive(sim_drives: MakeDrives, make_arm: MakeArm) -> None:
    drives = sim_drives(1, 2)
    arm = make_arm((1, 2))
    arm.start()
    drives[0].inject_fault(0x4310)  # overtemperature
    wait_for(lambda: arm.status().state is ArmState.TRIPPED, 2.0, "the trip")
    arm.stop()
    arm.start()  # fault reset, state machine again
    assert arm.status().ok
    assert all(d.state is State.OPERATION_ENABLED for d in drives)
    assert drives[0].error_code == 0


@pytest.mark.timeout(15)
def test_failed_start_names_the_drive_and_disables_the_others(
    sim_drives: MakeDrives, make_arm: MakeArm
) -> None:
    drives = sim_drives(1, 2)
    arm = make_arm((1, 2, 9), sdo_timeout_s=0.05)
    with pytest.raises(DriveStartError, match=r"joint 'j9' \(node 9\): no SDO answer"):
        arm.start()
    assert arm.status().state is ArmState.IDLE
    # quick-stopped by SDO at standstill: Quick stop active for a drive cycle, then disabled
    wait_for(lambda: all(d.state is State.SWITCH_ON_DISABLED for d in drives), 1.0, "transition 12")
    pre_operational(drives)


@pytest.mark.timeout(15)
def test_drive_leaving_nmt_operational_stops_all(sim_drives: MakeDrives, make_arm: MakeArm) -> None:
    drives = sim_drives(1, 2)
    arm = make_arm((1, 2))
    arm.start()
    drive_for(arm, np.array([0.3, 0.3]), 0.05)
    drives[0].node.nmt.state = "PRE-OPERATIONAL"  # as after a drive-side NMT change
    wait_for(lambda: arm.status().state is ArmState.TRIPPED, 2.0, "the trip")
    (trip,) = arm.status().trips
    assert (trip.cause, trip.node_id) == (TripCause.NMT_STATE, 1)
    assert "PRE-OPERATIONAL" in trip.detail
    # The drive in PRE-OPERATIONAL ignores PDOs: only the other one is quick-stopped by PDO.
    wait_for(lambda: stopped(drives[1:]), 2.0, "the other drive to stop")
