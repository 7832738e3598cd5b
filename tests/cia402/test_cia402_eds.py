"""The drive's EDS file passes an independent validator: `eds-validate` from eds-utils (PyPI,
OreSat's CANopen EDS tools), run as its users run it, and `canopen`'s own parser."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import canopen
import pytest

from umbra.modules.arm.cia402 import objects as obj

# CiA 306 [FileInfo] keys eds-utils insists on (it reports each one that is missing).
FILE_INFO_KEYS = (
    "FileName",
    "FileVersion",
    "FileRevision",
    "EDSVersion",
    "Description",
    "CreationTime",
    "CreationDate",
    "CreatedBy",
    "ModificationTime",
    "ModificationDate",
    "ModifiedBy",
)


def eds_validate(path: Path) -> subprocess.CompletedProcess[str]:
    tool = Path(sys.executable).with_name("eds-validate")
    command = [str(tool)] if tool.exists() else [shutil.which("eds-validate") or "eds-validate"]
    return subprocess.run([*command, str(path)], capture_output=True, text=True, timeout=60)


def test_eds_utils_validates_the_drive_eds() -> None:
    result = eds_validate(obj.EDS_PATH)
    assert result.returncode == 0, result.stderr + result.stdout
    assert result.stderr == ""


@pytest.mark.parametrize("key", ["ModifiedBy", "CreationDate", "ModificationTime"])
def test_eds_utils_refuses_it_without_a_file_info_key(key: str, tmp_path: Path) -> None:
    text = obj.EDS_PATH.read_text()
    broken = tmp_path / "broken.eds"
    broken.write_text("\n".join(line for line in text.split("\n") if not line.startswith(key)))
    result = eds_validate(broken)
    assert result.returncode == 1
    assert key in result.stderr


def test_file_info_and_objects_as_canopen_reads_them() -> None:
    text = obj.EDS_PATH.read_text()
    info = text.split("[FileInfo]\n", 1)[1].split("\n\n", 1)[0]
    keys = {line.split("=", 1)[0] for line in info.splitlines()}
    assert set(FILE_INFO_KEYS) <= keys
    od = canopen.import_od(str(obj.EDS_PATH), 1)
    for index in (
        obj.CONSUMER_HEARTBEAT_TIME,
        obj.ABORT_CONNECTION_OPTION_CODE,
        obj.QUICK_STOP_OPTION_CODE,
        obj.MAX_DECELERATION,
        obj.COMMUNICATION_LOSS_COUNT,
    ):
        assert index in od, f"0x{index:04X} missing"
    assert od[obj.CONSUMER_HEARTBEAT_TIME][0].default == 2  # two consumer entries
    assert od[obj.QUICK_STOP_OPTION_CODE].default == 2
