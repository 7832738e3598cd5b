"""Another vendor's EDS (tests/cia402/vendor_drive.eds: a CiA 402 servo drive's EDS that lacks
the abort connection option code 0x6007, the max deceleration 0x60C6 and the RPDO event timer
0x1400 sub 5): the master takes it; `simulate: true` refuses it when the settings are read,
naming the missing objects and the file, before any simulated drive or thread exists; `umbra
check` and `umbra run` exit 2 on it without a traceback."""

from __future__ import annotations

import subprocess
import sys
import threading
import uuid
from pathlib import Path

import pytest

from umbra.modules.arm.cia402 import Cia402ConfigError, SimDrive
from umbra.modules.arm.cia402 import objects as obj
from umbra.modules.arm.cia402.config_yaml import load_canopen_settings

VENDOR_EDS = Path(__file__).with_name("vendor_drive.eds")
MISSING = (
    "0x6007 sub 0 Abort connection option code (simulated drive)",
    "0x60C6 sub 0 Max deceleration (simulated drive)",
    "0x1400 sub 5 RPDO1 event timer (simulated drive)",
)
JOINTS = "".join(f"  - {{name: j{i}, node_id: {i}, counts_per_rad: 10000}}\n" for i in range(1, 7))


def write_settings(tmp_path: Path, simulate: bool, eds: Path | None = VENDOR_EDS) -> Path:
    """A CANopen settings file for the Puma 560's six joints (``eds`` None: the built-in)."""
    path = tmp_path / "canopen.yaml"
    path.write_text(
        f"bus: {{interface: virtual, channel: umbra-vendor-{uuid.uuid4().hex}}}\n"
        f"simulate: {'true' if simulate else 'false'}\n"
        f"eds: {'' if eds is None else eds}\n"
        f"joints:\n{JOINTS}",
        encoding="utf-8",
    )
    return path


def test_the_master_takes_the_vendor_eds(tmp_path: Path) -> None:
    settings = load_canopen_settings(write_settings(tmp_path, simulate=False))
    assert settings.arm.eds == VENDOR_EDS and not settings.simulate


def test_simulate_refuses_the_vendor_eds_at_its_line_naming_each_missing_object(
    tmp_path: Path,
) -> None:
    path = write_settings(tmp_path, simulate=True)
    with pytest.raises(Cia402ConfigError) as caught:
        load_canopen_settings(path)
    message = str(caught.value)
    assert message.startswith(f"{path}:3: error: eds: EDS file {VENDOR_EDS} lacks 3 object(s)")
    for text in MISSING:
        assert text in message
    assert "leave eds empty for the built-in one" in message


def test_a_simulated_drive_refuses_it_before_any_thread_starts() -> None:
    threads = threading.active_count()
    with pytest.raises(Cia402ConfigError, match=r"0x6007 sub 0 Abort connection option code"):
        SimDrive(1, eds=VENDOR_EDS)
    assert threading.active_count() == threads


GRAPH = """graph: vendor_arm
frames:
  tool->camera: {{xyz: [0.0, 0.06, 0.04], rpy_deg: [0, 0, 90]}}
modules:
  vision: {{type: TwistSource, rate: 100, params: {{twist: [0.02, 0, 0, 0, 0, 0.1]}}}}
  reg: {{type: REG_VEL, rate: 100, params: {{timeout: 0.1}}}}
  rot: {{type: ROTATE_KIN}}
  kin: {{type: WOLVERINE_KIN}}
  jnts: {{type: WOLVERINE_JNTS, rate: 100, params: {{backend: canopen, canopen_config: {config}}}}}
connections:
  - vision.twist -> reg.command
  - reg.twist -> rot.camera_twist
  - rot.tool_twist -> kin.tool_twist
  - kin.joint_rates -> jnts.rates
  - jnts.joint_state ~> kin.joint_state
"""


def umbra(cwd: Path, *args: str) -> tuple[int, str]:
    """Run ``umbra ARGS`` to its end: exit status and everything it printed."""
    result = subprocess.run(
        [sys.executable, "-m", "umbra.runtime.cli.main", *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=120,
        stdin=subprocess.DEVNULL,
    )
    return result.returncode, result.stdout + result.stderr


def test_the_graph_checks_with_the_built_in_eds(tmp_path: Path) -> None:
    """The control: the same graph with the simulated drives on the built-in EDS passes."""
    graph = tmp_path / "vendor_arm.yaml"
    graph.write_text(GRAPH.format(config=write_settings(tmp_path, simulate=True, eds=None)))
    status, output = umbra(tmp_path, "check", str(graph))
    assert status == 0, output


@pytest.mark.parametrize("command", ["check", "run"])
def test_umbra_refuses_a_simulation_on_the_vendor_eds_with_exit_2(
    tmp_path: Path, command: str
) -> None:
    graph = tmp_path / "vendor_arm.yaml"
    graph.write_text(GRAPH.format(config=write_settings(tmp_path, simulate=True)))
    run = ["--duration", "2", "--out", str(tmp_path)] if command == "run" else []
    status, output = umbra(tmp_path, command, str(graph), *run)
    assert status == 2, output
    assert "Traceback" not in output and "Exception in thread" not in output
    assert f"EDS file {VENDOR_EDS} lacks 3 object(s)" in output
    for text in MISSING:
        assert text in output
    assert len(output.strip().splitlines()) == 1, output  # that one error, nothing else


def test_a_foreign_object_at_0x2000_is_left_to_its_eds(tmp_path: Path) -> None:
    """The simulated drive serves its loss count at 0x2000 only where the EDS declares it as an
    unsigned number; an EDS with a string there reads back that string."""
    text = obj.EDS_PATH.read_text()
    ours = (
        "[2000]\nParameterName=Communication loss count\nObjectType=0x7\nDataType=0x0006\n"
        "AccessType=ro\nDefaultValue=0\nPDOMapping=1\n"
    )
    assert ours in text
    theirs = (
        "[2000]\nParameterName=Drive label\nObjectType=0x7\nDataType=0x0009\n"
        "AccessType=rw\nDefaultValue=axis\nPDOMapping=0\n"
    )
    eds = tmp_path / "string_2000.eds"
    eds.write_text(text.replace(ours, theirs))
    assert SimDrive(1, eds=eds).node.sdo[obj.COMMUNICATION_LOSS_COUNT].raw == "axis"
    assert SimDrive(1).node.sdo[obj.COMMUNICATION_LOSS_COUNT].raw == 0
