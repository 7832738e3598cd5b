"""Settings are checked before the bus is touched; bad ones say what was expected."""

from __future__ import annotations

import uuid

import pytest

from umbra.connectors.errors import UserError
from umbra.modules.arm.cia402 import (
    BusSpec,
    BusSpecError,
    Cia402Arm,
    Cia402ArmConfig,
    Cia402ConfigError,
    DriveStartError,
    JointDrive,
)


def test_unknown_interface_lists_the_valid_ones() -> None:
    with pytest.raises(BusSpecError, match=r"unknown interface 'canbus'.*socketcan.*virtual"):
        BusSpec("canbus", "can0")


def test_bitrate_must_be_a_canopen_rate() -> None:
    with pytest.raises(
        BusSpecError, match=r"bit rate must be one of the CANopen rates .*125000.* got 123456"
    ):
        BusSpec("socketcan", "can0", 123456)


def test_channel_must_be_named() -> None:
    with pytest.raises(BusSpecError, match="channel must be a non-empty name"):
        BusSpec("socketcan", " ")


def test_bus_errors_are_user_errors() -> None:
    assert issubclass(BusSpecError, UserError)
    assert issubclass(Cia402ConfigError, UserError)


def test_bus_that_cannot_be_opened_names_the_bus() -> None:
    # No socketcan device of this name exists (or no socketcan at all): either way the
    # error names the bus spec and the cause, and nothing is left running.
    config = Cia402ArmConfig(
        bus=BusSpec("socketcan", "umbra-no-such-can9"), joints=(JointDrive("j1", 1, 1000.0),)
    )
    arm = Cia402Arm(config)
    with pytest.raises(BusSpecError, match=r"cannot open CAN bus .*'umbra-no-such-can9'"):
        arm.start()
    assert arm.status().state.value == "idle"


@pytest.mark.timeout(10)
def test_missing_drive_names_joint_and_node() -> None:
    config = Cia402ArmConfig(
        bus=BusSpec("virtual", f"umbra-cia402-{uuid.uuid4().hex}"),
        joints=(JointDrive("elbow", 42, 1000.0),),
        sdo_timeout_s=0.05,
    )
    arm = Cia402Arm(config)
    with pytest.raises(DriveStartError, match=r"joint 'elbow' \(node 42\): no SDO answer"):
        arm.start()
    arm.stop()


def test_duplicate_node_ids_are_refused() -> None:
    joints = (JointDrive("a", 3, 1.0), JointDrive("b", 3, 1.0))
    with pytest.raises(Cia402ConfigError, match=r"node ids used by more than one joint: \[3\]"):
        Cia402ArmConfig(bus=BusSpec("virtual", "x"), joints=joints)


@pytest.mark.parametrize(
    ("joint", "message"),
    [
        (lambda: JointDrive("a", 0, 1.0), "node id must be 1..127, got 0"),
        (lambda: JointDrive("a", 128, 1.0), "node id must be 1..127, got 128"),
        (lambda: JointDrive("a", 1, 0.0), "counts_per_rad must be finite and non-zero"),
        (lambda: JointDrive("a", 1, float("nan")), "counts_per_rad must be finite and non-zero"),
    ],
)
def test_bad_joint_drive(joint: object, message: str) -> None:
    with pytest.raises(Cia402ConfigError, match=message):
        joint()  # type: ignore[operator]


def test_heartbeat_timeout_must_exceed_period() -> None:
    with pytest.raises(Cia402ConfigError, match=r"heartbeat_timeout_s \(0.05\) must exceed"):
        Cia402ArmConfig(
            bus=BusSpec("virtual", "x"),
            joints=(JointDrive("a", 1, 1.0),),
            heartbeat_period_s=0.05,
            heartbeat_timeout_s=0.05,
        )


def test_missing_eds_file_is_named(tmp_path: object) -> None:
    with pytest.raises(Cia402ConfigError, match=r"nope\.eds: error: object dictionary"):
        Cia402ArmConfig(
            bus=BusSpec("virtual", "x"), joints=(JointDrive("a", 1, 1.0),), eds="nope.eds"
        )
