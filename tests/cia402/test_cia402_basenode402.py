"""The simulated drive under an independent master: `canopen`'s own `BaseNode402`.

On a python-can virtual bus, `BaseNode402` (the canopen library's CiA 402 master, not ours)
walks the drive through every commanded transition of the power state machine, runs it in
profile velocity mode, and quick-stops it under each quick stop option code (0x605A) 0..8.
PDOs: RPDO1 controlword + target velocity (asynchronous: `BaseNode402` sends it itself);
TPDO1 statusword + position actual and TPDO2 velocity actual + mode display, on every SYNC
(10 ms).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator

import canopen
import pytest
from canopen.pdo import PdoMap
from canopen.profiles.p402 import BaseNode402

from tests.poll import wait_for
from umbra.modules.arm.cia402 import SimDrive
from umbra.modules.arm.cia402 import objects as obj

NODE = 7
SYNC_S = 0.01
SPEED = 20_000  # counts/s
PROFILE_DECEL = 100_000  # counts/s^2: 0.2 s and 2000 counts from SPEED
QUICK_STOP_DECEL = 200_000  # 0.1 s, 1000 counts
MAX_DECEL = 400_000  # 0.05 s, 500 counts
STOP_DECELERATION = {
    0: None,  # the drive function is disabled at once
    1: PROFILE_DECEL,
    2: QUICK_STOP_DECEL,
    3: MAX_DECEL,  # current limit: the simulation brakes at max deceleration
    4: MAX_DECEL,  # voltage limit: likewise
    5: PROFILE_DECEL,
    6: QUICK_STOP_DECEL,
    7: MAX_DECEL,
    8: MAX_DECEL,
}


class Master:
    """`BaseNode402` with a record of every TPDO1 (statusword, position actual)."""

    def __init__(self, node: BaseNode402, network: canopen.Network) -> None:
        self.node = node
        self.network = network
        self.tpdo1: list[tuple[int, int]] = []
        node.tpdo[1].add_callback(self._on_tpdo1)

    def _on_tpdo1(self, pdo_map: PdoMap) -> None:
        self.tpdo1.append((int(pdo_map[obj.STATUSWORD].raw), int(pdo_map[obj.POSITION_ACTUAL].raw)))

    def velocity(self) -> int:
        return int(self.node.tpdo_values[obj.VELOCITY_ACTUAL])

    def target(self, counts_s: int) -> None:
        self.node.rpdo_pointers[obj.TARGET_VELOCITY].raw = counts_s
        self.node.rpdo[1].transmit()


def state_of(statusword: int) -> str:
    for name, (mask, bits) in canopen.profiles.p402.State402.SW_MASK.items():
        if statusword & mask == bits:
            return name
    return "UNKNOWN"


@pytest.fixture
def master(
    channel: str, sim_drives: Callable[..., list[SimDrive]]
) -> Iterator[tuple[Master, SimDrive]]:
    (drive,) = sim_drives(NODE)
    network = canopen.Network()
    network.NOTIFIER_CYCLE = 0.05
    network.connect(interface="virtual", channel=channel)
    node = BaseNode402(NODE, str(obj.EDS_PATH))
    network.add_node(node)
    node.nmt.state = "PRE-OPERATIONAL"
    node.tpdo.read(from_od=True)
    node.rpdo.read(from_od=True)
    layout = (
        (node.rpdo[1], 0x200, 255, (obj.CONTROLWORD, obj.TARGET_VELOCITY)),
        (node.tpdo[1], 0x180, 1, (obj.STATUSWORD, obj.POSITION_ACTUAL)),
        (node.tpdo[2], 0x280, 1, (obj.VELOCITY_ACTUAL, obj.MODES_OF_OPERATION_DISPLAY)),
    )
    for pdo_map, base, trans_type, indexes in layout:
        pdo_map.clear()
        for index in indexes:
            pdo_map.add_variable(index)
        pdo_map.cob_id = base + NODE
        pdo_map.trans_type = trans_type
        pdo_map.enabled = True
    node.rpdo.save()
    node.tpdo.save()
    node.sdo[obj.PROFILE_DECELERATION].raw = PROFILE_DECEL
    node.sdo[obj.QUICK_STOP_DECELERATION].raw = QUICK_STOP_DECEL
    node.sdo[obj.MAX_DECELERATION].raw = MAX_DECEL
    node.setup_402_state_machine(read_pdos=True)  # its own PDO discovery, by SDO
    node.nmt.state = "OPERATIONAL"
    network.sync.start(SYNC_S)
    wait_for(lambda: len(node.tpdo_values) >= 4 and node.statusword != 0, 2.0, "TPDOs")
    yield Master(node, network), drive
    network.sync.stop()
    network.disconnect()


def enable_profile_velocity(m: Master) -> None:
    m.node.op_mode = "PROFILED VELOCITY"
    assert m.node.op_mode == "PROFILED VELOCITY"
    m.node.state = "OPERATION ENABLED"
    assert m.node.state == "OPERATION ENABLED"


@pytest.mark.timeout(30)
def test_every_commanded_transition(master: tuple[Master, SimDrive]) -> None:
    m, drive = master
    node = m.node
    assert node.state == "SWITCH ON DISABLED"  # after power-up (transitions 0, 1)
    walk = [
        ("READY TO SWITCH ON", 2),
        ("SWITCHED ON", 3),
        ("OPERATION ENABLED", 4),
        ("SWITCHED ON", 5),
        ("READY TO SWITCH ON", 6),
        ("SWITCH ON DISABLED", 7),
        ("OPERATION ENABLED", None),  # 2, 3, 4 again
        ("READY TO SWITCH ON", 8),
        ("OPERATION ENABLED", None),
        ("SWITCH ON DISABLED", 9),
        ("SWITCHED ON", None),
        ("SWITCH ON DISABLED", 10),
        ("OPERATION ENABLED", None),
        ("QUICK STOP ACTIVE", 11),  # option code 2: then transition 12 by itself
    ]
    for state, _transition in walk:
        node.state = state  # raises RuntimeError when not confirmed by a TPDO in time
        assert node.state == state
        assert drive.state.value == state.lower()
    wait_for(lambda: node.state == "SWITCH ON DISABLED", 1.0, "transition 12")
    drive.inject_fault(0x2310)
    wait_for(lambda: node.state == "FAULT", 1.0, "the fault in a TPDO")
    node.reset_from_fault()  # transition 15, then on to OPERATION ENABLED
    assert node.state == "OPERATION ENABLED"
    assert not node.is_faulted()


@pytest.mark.timeout(30)
def test_profile_velocity(master: tuple[Master, SimDrive]) -> None:
    m, drive = master
    enable_profile_velocity(m)
    m.target(SPEED)
    wait_for(lambda: m.velocity() == SPEED, 1.0, "velocity actual at the target")
    assert m.node.statusword & 0x0400  # target reached
    start = m.tpdo1[-1][1]
    wait_for(lambda: m.tpdo1[-1][1] - start >= SPEED * 0.1, 1.0, "0.1 s of travel")
    m.target(-SPEED // 2)
    wait_for(lambda: m.velocity() == -SPEED // 2, 1.0, "the reverse speed")
    m.target(0)
    wait_for(lambda: m.velocity() == 0, 1.0, "standstill")
    assert m.node.state == "OPERATION ENABLED"  # a zero target holds, it does not disable
    assert drive.target_velocity_counts_s == 0


@pytest.mark.timeout(60)
@pytest.mark.parametrize("option", sorted(STOP_DECELERATION))
def test_quick_stop_option_code(master: tuple[Master, SimDrive], option: int) -> None:
    m, drive = master
    m.node.sdo[obj.QUICK_STOP_OPTION_CODE].raw = option
    enable_profile_velocity(m)
    m.target(SPEED)
    wait_for(lambda: m.velocity() == SPEED, 1.0, "full speed")
    m.tpdo1.clear()
    wait_for(lambda: len(m.tpdo1) >= 2, 1.0, "TPDOs at speed")
    m.node.state = "QUICK STOP ACTIVE"  # BaseNode402 waits for it in a TPDO (0.4 s at most)
    stays = option >= 5
    final = "QUICK STOP ACTIVE" if stays else "SWITCH ON DISABLED"
    wait_for(
        lambda: drive.velocity_counts_s == 0 and drive.state.value == final.lower(), 2.0, "the stop"
    )
    n = len(m.tpdo1)
    wait_for(lambda: len(m.tpdo1) >= n + 3, 1.0, "TPDOs at standstill")
    states = [state_of(word) for word, _ in m.tpdo1]
    positions = [pos for _, pos in m.tpdo1]
    first_qs = states.index("QUICK STOP ACTIVE")
    assert set(states[:first_qs]) == {"OPERATION ENABLED"}
    end = positions[-1]
    # Quick stop active is in every statusword while the drive still moves.
    for state, position in zip(states[first_qs:], positions[first_qs:], strict=True):
        if position != end:
            assert state == "QUICK STOP ACTIVE", (states, positions)
    assert states[-1] == final
    # The braking distance from the last position at speed: v^2 / (2 a) for its deceleration.
    decel = STOP_DECELERATION[option]
    travelled = end - positions[first_qs - 1]
    expected = 0 if decel is None else SPEED**2 / (2 * decel)
    assert travelled == pytest.approx(expected, abs=SPEED * SYNC_S * 0.1 + 2)
    if stays:
        m.node.state = "OPERATION ENABLED"  # transition 16, allowed for 5..8
        m.target(SPEED // 4)
        wait_for(lambda: m.velocity() == SPEED // 4, 1.0, "moving again")
    else:
        with pytest.raises(ValueError, match="Illegal state transition"):
            m.node._change_state("OPERATION ENABLED")  # no transition 16 from disabled
        m.node.state = "OPERATION ENABLED"  # the long way, 2, 3, 4
        assert drive.state.value == "operation enabled"


@pytest.mark.timeout(10)
def test_reserved_option_codes_are_refused(master: tuple[Master, SimDrive]) -> None:
    m, _ = master
    for index, value in (
        (obj.QUICK_STOP_OPTION_CODE, 9),
        (obj.QUICK_STOP_OPTION_CODE, -1),
        (obj.ABORT_CONNECTION_OPTION_CODE, 4),
    ):
        with pytest.raises(canopen.sdo.SdoAbortedError) as refused:
            m.node.sdo[index].raw = value
        assert refused.value.code == 0x06090030  # value range exceeded
