"""Shared fixtures: a private python-can virtual bus per test, simulated drives on it."""

from __future__ import annotations

import uuid
from collections.abc import Callable, Iterator

import pytest

from umbra.modules.arm.cia402 import BusSpec, Cia402Arm, Cia402ArmConfig, JointDrive, SimDrive

COUNTS_PER_RAD = 10_000.0


@pytest.fixture
def channel() -> str:
    """A virtual CAN channel no other test shares."""
    return f"umbra-cia402-{uuid.uuid4().hex}"


@pytest.fixture
def sim_drives(channel: str) -> Iterator[Callable[..., list[SimDrive]]]:
    """Factory: simulated drives with the given node ids, on the test's channel."""
    created: list[SimDrive] = []

    def make(*node_ids: int) -> list[SimDrive]:
        drives = [SimDrive(node_id).connect(channel=channel) for node_id in node_ids]
        created.extend(drives)
        return drives

    yield make
    for drive in created:
        drive.close()


@pytest.fixture
def make_arm(channel: str) -> Iterator[Callable[..., Cia402Arm]]:
    """Factory: a master on the test's channel for the given node ids (stopped at teardown)."""
    arms: list[Cia402Arm] = []

    def make(node_ids: tuple[int, ...], **settings: object) -> Cia402Arm:
        joints = tuple(JointDrive(f"j{n}", n, COUNTS_PER_RAD) for n in node_ids)
        config = Cia402ArmConfig(bus=BusSpec("virtual", channel), joints=joints, **settings)
        arm = Cia402Arm(config)
        arms.append(arm)
        return arm

    yield make
    for arm in arms:
        arm.stop()
