"""WOLVERINE_JNTS's canopen backend: its YAML file, rate guard, and a run through the module."""

from __future__ import annotations

import time
import uuid
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from tests.poll import wait_for
from umbra.connectors.messages import JointRates
from umbra.modules.arm.cia402 import Cia402ConfigError
from umbra.modules.arm.cia402.backend import Cia402Backend, guard_rates
from umbra.modules.arm.cia402.config_yaml import load_canopen_settings
from umbra.modules.arm.dh import puma560
from umbra.modules.arm.joints_backend import BackendError
from umbra.modules.arm.wolverine_jnts import WolverineJnts
from umbra.runtime.harness import ModuleHarness

JOINTS_YAML = "".join(
    f"  - {{name: j{i}, node_id: {i}, counts_per_rad: 10000}}\n" for i in range(1, 7)
)


def write_config(tmp_path: Path, body: str, name: str = "canopen.yaml") -> Path:
    path = tmp_path / name
    path.write_text(body, encoding="utf-8")
    return path


def sim_config(tmp_path: Path, extra: str = "") -> Path:
    channel = f"umbra-cia402-{uuid.uuid4().hex}"
    return write_config(
        tmp_path,
        f"bus: {{interface: virtual, channel: {channel}}}\nsimulate: true\n{extra}"
        f"joints:\n{JOINTS_YAML}",
    )


def test_yaml_settings_load_with_defaults_and_turn_scale(tmp_path: Path) -> None:
    path = write_config(
        tmp_path,
        "bus: {interface: socketcan, channel: can1, bitrate: 1000000}\n"
        "sync_period: 0.004\n"
        "command_timeout: null\n"
        "joints:\n"
        "  - {name: a, node_id: 3, counts_per_turn: 131072, zero_counts: -5}\n",
    )
    settings = load_canopen_settings(path)
    arm = settings.arm
    assert (arm.bus.interface, arm.bus.channel, arm.bus.bitrate) == ("socketcan", "can1", 1000000)
    assert arm.sync_period_s == 0.004 and arm.command_timeout_s is None
    assert arm.heartbeat_timeout_s == 0.2 and arm.configure_pdos and not settings.simulate
    (joint,) = arm.joints
    assert joint.node_id == 3 and joint.zero_counts == -5
    assert joint.counts_per_rad == pytest.approx(131072 / (2 * np.pi))


@pytest.mark.parametrize(
    ("body", "line", "message"),
    [
        ("bus: {interface: virtual, channel: x}\njoints: []\n", 2, "joints: expected a non-empty"),
        ("bus: {interface: vrtual, channel: x}\njoints: [1]\n", 1, "unknown interface 'vrtual'"),
        (
            "bus: {interface: virtual, channel: x}\nsync: 1\njoints: [1]\n",
            2,
            "unknown key 'sync'",
        ),
        (
            "bus: {interface: virtual, channel: x}\njoints:\n  - {name: a, node_id: 1}\n",
            3,
            r"joints\[0\]: give exactly one of 'counts_per_rad' and 'counts_per_turn'",
        ),
        (
            "bus: {interface: virtual, channel: x}\njoints:\n"
            "  - {name: a, node_id: 1, counts_per_rad: 1}\n"
            "  - {name: b, node_id: 1, counts_per_rad: 1}\n",
            1,
            r"node ids used by more than one joint: \[1\]",
        ),
        (
            "bus: {interface: socketcan, channel: can0}\nsimulate: true\n"
            "joints:\n  - {name: a, node_id: 1, counts_per_rad: 1}\n",
            2,
            "simulated drives need bus interface 'virtual'",
        ),
        ("bus: [\n", 2, "invalid YAML"),
    ],
)
def test_yaml_errors_name_file_and_line(tmp_path: Path, body: str, line: int, message: str) -> None:
    path = write_config(tmp_path, body)
    with pytest.raises(Cia402ConfigError, match=message) as caught:
        load_canopen_settings(path)
    assert str(caught.value).startswith(f"{path}:{line}: error: ")


def test_guard_rates_clips_and_stops_at_limits() -> None:
    rates = guard_rates(
        rates=[3.0, -3.0, 0.5, -0.5, 0.2],
        q=[0.0, 0.0, 1.0, 1.0, np.nan],
        q_min=[-1.0, -1.0, -1.0, 1.0, -1.0],
        q_max=[1.0, 1.0, 1.0, 2.0, 1.0],
        qd_max=[2.0, 1.0, 1.0, 1.0, 1.0],
    )
    # j3 sits on its upper limit: outward zeroed; j4 on its lower limit: outward zeroed.
    assert rates.tolist() == [2.0, -1.0, 0.0, 0.0, 0.2]
    inward = guard_rates([-0.5, 0.5], [1.0, 1.0], [-1.0, 1.0], [1.0, 2.0], [1.0, 1.0])
    assert inward.tolist() == [-0.5, 0.5]


def test_backend_needs_a_config_that_matches_the_arm(tmp_path: Path) -> None:
    table = puma560()
    context = SimpleNamespace(clock="real")
    with pytest.raises(BackendError, match="needs canopen_config"):
        Cia402Backend.from_module(table, SimpleNamespace(canopen_config=""), context)
    path = write_config(
        tmp_path,
        "bus: {interface: virtual, channel: x}\njoints:\n"
        "  - {name: j1, node_id: 1, counts_per_rad: 1}\n"
        "  - {name: wrist, node_id: 2, counts_per_rad: 1}\n",
    )
    params = SimpleNamespace(canopen_config=str(path), initial_q_deg=None)
    with pytest.raises(BackendError, match=r"missing \['j2', 'j3', 'j4', 'j5', 'j6'\]; unknown"):
        Cia402Backend.from_module(table, params, context)


@pytest.mark.timeout(15)
def test_wolverine_jnts_runs_simulated_drives_over_canopen(tmp_path: Path) -> None:
    table = puma560()
    config = sim_config(tmp_path)
    initial_deg = [10.0, -20.0, 30.0, 0.0, 15.0, -5.0]
    params = {"backend": "canopen", "canopen_config": str(config), "initial_q_deg": initial_deg}
    rates = np.array([0.2, -0.1, 0.0, 0.3, 0.0, -0.2])
    with ModuleHarness(WolverineJnts, params) as h:  # starts the module: drives come up
        first = h.step(0.01)["joint_state"][0]
        assert first.names == table.names
        np.testing.assert_allclose(first.position, np.radians(initial_deg), atol=1e-4)
        start = time.monotonic()
        while time.monotonic() - start < 0.3:
            h.push("rates", JointRates(names=table.names, rates=rates))
            h.step(0.01)
            time.sleep(0.01)
        moved = h.output("joint_state").position - first.position
        assert np.all(np.sign(np.round(moved, 3)) == np.sign(rates))
        assert h.output("status").stage == "running"
        backend = h.module.backend
        assert isinstance(backend, Cia402Backend)
        # A fault on one drive: the module reports the drive and refuses to move.
        backend.sim_drives[4].inject_fault(0x2310)
        wait_for(lambda: not backend.read(h.now).ok, 2.0, "the trip")
        h.push("rates", JointRates(names=table.names, rates=rates))
        h.step(0.01)
        status = h.output("status")
        assert status.stage == "zero" and "joint 'j5' (node 5)" in status.message
        assert "0x2310" in status.message
    assert not backend.sim_drives  # stop closed the simulated drives
    assert backend.counters() == {"drive_master_losses": 0}  # the master never went silent


def test_shipped_puma560_settings_fit_the_builtin_arm() -> None:
    path = Path(__file__).parents[2] / "modules/arm/cia402/puma560_sim.yaml"
    settings = load_canopen_settings(path)
    assert settings.simulate and settings.arm.bus.interface == "virtual"
    assert tuple(j.name for j in settings.arm.joints) == puma560().names
    assert [j.node_id for j in settings.arm.joints] == [1, 2, 3, 4, 5, 6]
