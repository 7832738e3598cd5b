"""The simulated drive, driven by a bare canopen master (RemoteNode) on a virtual bus."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator

import canopen
import pytest
from canopen.nmt import NmtError
from canopen.sdo import SdoAbortedError, SdoCommunicationError

from tests.poll import wait_for
from umbra.modules.arm.cia402 import SimDrive
from umbra.modules.arm.cia402 import objects as obj
from umbra.modules.arm.cia402.state_machine import State, state_from_statusword

NODE = 5


@pytest.fixture
def bus(
    channel: str, sim_drives: Callable[..., list[SimDrive]]
) -> Iterator[tuple[SimDrive, canopen.RemoteNode, canopen.Network]]:
    """One simulated drive and a bare canopen master for it on the same virtual channel."""
    (drive,) = sim_drives(NODE)
    network = canopen.Network()
    network.NOTIFIER_CYCLE = 0.05
    network.connect(interface="virtual", channel=channel)
    node = network.add_node(NODE, canopen.import_od(str(obj.EDS_PATH), NODE))
    yield drive, node, network
    network.disconnect()


def sdo_state(node: canopen.RemoteNode) -> State:
    return state_from_statusword(node.sdo[obj.STATUSWORD].raw)


def enable_velocity_mode(node: canopen.RemoteNode, settings: dict[int, int] | None = None) -> None:
    """By SDO: profile velocity mode, then ``settings`` (index: value), then operation enabled."""
    node.sdo[obj.MODES_OF_OPERATION].raw = obj.PROFILE_VELOCITY_MODE
    for index, value in (settings or {}).items():
        node.sdo[index].raw = value
    for word in (0x06, 0x07, 0x0F):
        node.sdo[obj.CONTROLWORD].raw = word


@pytest.mark.timeout(10)
def test_state_machine_and_mode_by_sdo(bus: tuple[SimDrive, canopen.RemoteNode, object]) -> None:
    drive, node, _ = bus
    assert sdo_state(node) is State.SWITCH_ON_DISABLED
    assert node.sdo[obj.DEVICE_TYPE].raw & 0xFFFF == 402
    with pytest.raises(SdoAbortedError) as refused:
        node.sdo[obj.MODES_OF_OPERATION].raw = 1  # profile position: not implemented
    assert refused.value.code == 0x06090030
    node.sdo[obj.MODES_OF_OPERATION].raw = obj.PROFILE_VELOCITY_MODE
    assert node.sdo[obj.MODES_OF_OPERATION_DISPLAY].raw == obj.PROFILE_VELOCITY_MODE
    expected = [State.READY_TO_SWITCH_ON, State.SWITCHED_ON, State.OPERATION_ENABLED]
    for word, state in zip((0x06, 0x07, 0x0F), expected, strict=True):
        node.sdo[obj.CONTROLWORD].raw = word
        assert sdo_state(node) is state
    node.sdo[obj.CONTROLWORD].raw = 0x02  # quick stop at standstill: option code 2 shows
    assert sdo_state(node) is State.QUICK_STOP_ACTIVE  # Quick stop active for a drive cycle,
    wait_for(  # then ends in Switch on disabled by itself (transition 12)
        lambda: sdo_state(node) is State.SWITCH_ON_DISABLED, 1.0, "transition 12"
    )
    assert drive.state is State.SWITCH_ON_DISABLED
    with pytest.raises(SdoAbortedError):
        node.sdo[obj.STATUSWORD].raw = 0  # read-only


@pytest.mark.timeout(10)
def test_velocity_ramp_and_position_integral(
    bus: tuple[SimDrive, canopen.RemoteNode, object],
) -> None:
    drive, node, _ = bus
    enable_velocity_mode(
        node, {obj.PROFILE_ACCELERATION: 1_000_000, obj.QUICK_STOP_DECELERATION: 2_000_000}
    )
    node.sdo[obj.TARGET_VELOCITY].raw = 10_000
    for _ in range(100):
        drive.advance(0.001)
    # 0.1 s at 10000 counts/s, minus the 0.01 s ramp at 1e6 counts/s^2: 1000 - 50 counts.
    assert drive.velocity_counts_s == 10_000
    assert drive.position_counts == pytest.approx(950.0, abs=1e-6)
    assert node.sdo[obj.POSITION_ACTUAL].raw == 950
    assert node.sdo[obj.VELOCITY_ACTUAL].raw == 10_000
    node.sdo[obj.CONTROLWORD].raw = 0x02
    assert drive.state is State.QUICK_STOP_ACTIVE  # while it ramps down
    for _ in range(20):
        drive.advance(0.001)
    # Quick stop ramp at 2e6 counts/s^2 from 10000 counts/s: v^2 / 2a = 25 counts.
    assert drive.velocity_counts_s == 0
    assert drive.position_counts == pytest.approx(975.0, abs=1e-6)
    assert drive.state is State.SWITCH_ON_DISABLED


@pytest.mark.timeout(10)
def test_quick_stop_option_6_holds_quick_stop_active(
    bus: tuple[SimDrive, canopen.RemoteNode, object],
) -> None:
    drive, node, _ = bus
    enable_velocity_mode(node, {obj.QUICK_STOP_OPTION_CODE: 6})
    node.sdo[obj.TARGET_VELOCITY].raw = 5_000
    drive.advance(0.1)
    node.sdo[obj.CONTROLWORD].raw = 0x02
    drive.advance(0.1)
    assert drive.velocity_counts_s == 0
    assert drive.state is State.QUICK_STOP_ACTIVE
    node.sdo[obj.CONTROLWORD].raw = 0x0F  # transition 16, allowed with option 6
    assert drive.state is State.OPERATION_ENABLED


@pytest.mark.timeout(10)
def test_heartbeat_starts_on_0x1017_and_stops_when_silent(
    bus: tuple[SimDrive, canopen.RemoteNode, object],
) -> None:
    drive, node, _ = bus
    node.sdo[obj.PRODUCER_HEARTBEAT_TIME].raw = 20
    assert node.nmt.wait_for_heartbeat(timeout=1.0) == "PRE-OPERATIONAL"
    drive.go_silent(heartbeat_only=True)
    with contextlib.suppress(NmtError):  # one may already be on its way
        node.nmt.wait_for_heartbeat(timeout=0.05)
    with pytest.raises(NmtError):
        node.nmt.wait_for_heartbeat(timeout=0.2)
    assert node.sdo[obj.STATUSWORD].raw  # still answers SDO


@pytest.mark.timeout(10)
def test_silent_drive_answers_nothing(bus: tuple[SimDrive, canopen.RemoteNode, object]) -> None:
    drive, node, _ = bus
    node.sdo.RESPONSE_TIMEOUT = 0.05
    drive.go_silent()
    with pytest.raises(SdoCommunicationError):
        _ = node.sdo[obj.STATUSWORD].raw


@pytest.mark.timeout(10)
def test_fault_injection_emcy_and_fault_reset(
    bus: tuple[SimDrive, canopen.RemoteNode, object],
) -> None:
    drive, node, _ = bus
    enable_velocity_mode(node)
    drive.inject_fault(0x7121)  # motor blocked
    emcy = node.emcy.wait(0x7121, timeout=1.0)
    assert emcy is not None and emcy.register == 0x01
    assert sdo_state(node) is State.FAULT
    assert node.sdo[obj.ERROR_CODE].raw == 0x7121
    node.sdo[obj.CONTROLWORD].raw = 0x0F
    assert sdo_state(node) is State.FAULT  # only a fault reset leaves Fault
    node.sdo[obj.CONTROLWORD].raw = 0x00
    node.sdo[obj.CONTROLWORD].raw = 0x80
    assert sdo_state(node) is State.SWITCH_ON_DISABLED
    assert node.sdo[obj.ERROR_CODE].raw == 0
    wait_for(lambda: not node.emcy.active, 1.0, "the EMCY error reset")


@pytest.mark.timeout(10)
def test_pdos_follow_the_mapping_the_master_writes(
    bus: tuple[SimDrive, canopen.RemoteNode, canopen.Network],
) -> None:
    drive, node, network = bus
    node.tpdo.read(from_od=True)
    node.rpdo.read(from_od=True)
    tpdo = node.tpdo[1]
    tpdo.clear()
    tpdo.add_variable(obj.VELOCITY_ACTUAL)  # swapped order: velocity first, then statusword
    tpdo.add_variable(obj.STATUSWORD)
    tpdo.trans_type = 2  # every second SYNC
    tpdo.enabled = True
    node.tpdo.save()
    node.rpdo.save()
    enable_velocity_mode(node)

    network.sync.transmit()
    assert tpdo.wait_for_reception(timeout=0.1) is None  # PDOs only in OPERATIONAL
    node.nmt.state = "OPERATIONAL"

    rpdo = node.rpdo[1]
    rpdo[obj.CONTROLWORD].raw = 0x0F
    rpdo[obj.TARGET_VELOCITY].raw = 5_000
    rpdo.transmit()
    # Synchronous RPDO: the SDO round trip proves it arrived, but it waits for SYNC.
    assert node.sdo[obj.TARGET_VELOCITY].raw == 0
    network.sync.transmit()
    wait_for(lambda: drive.target_velocity_counts_s == 5_000, 1.0, "the RPDO to apply")
    drive.advance(0.1)
    network.sync.transmit()  # second SYNC: the TPDO goes out
    assert tpdo.wait_for_reception(timeout=1.0) is not None
    assert tpdo[obj.VELOCITY_ACTUAL].raw == 5_000
    assert state_from_statusword(tpdo[obj.STATUSWORD].raw) is State.OPERATION_ENABLED
    assert drive.sync_count == 2


@pytest.mark.timeout(10)
def test_a_long_step_integrates_a_ramp_that_ends_within_it_exactly(
    bus: tuple[SimDrive, canopen.RemoteNode, object],
) -> None:
    """One step of 1 s (a process stopped and continued) over a 0.2 s quick stop ramp: the
    travel is that of the ramp, v^2 / (2 a), not half the step at the old speed."""
    drive, node, _ = bus
    enable_velocity_mode(node, {obj.QUICK_STOP_DECELERATION: 50_000})
    node.sdo[obj.TARGET_VELOCITY].raw = 10_000
    drive.advance(0.1)  # 0.01 s ramp up at 1e6 counts/s^2, then 0.09 s at speed
    start = drive.position_counts
    node.sdo[obj.CONTROLWORD].raw = 0x02
    drive.advance(1.0)
    assert drive.velocity_counts_s == 0
    assert drive.position_counts - start == pytest.approx(10_000**2 / (2 * 50_000), abs=1e-6)
