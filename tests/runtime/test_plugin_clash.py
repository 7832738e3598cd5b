"""A plug-in distribution, really installed by pip, that registers a type under a built-in's name
(the README's own example: ``Gain``) makes discovery fail, naming both distributions; renamed, it
is found beside the built-in."""

from __future__ import annotations

import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

PLUGIN = '''from umbra.connectors import Module, Output
from umbra.connectors.messages import Scalar


class ThirdPartyGain(Module):
    """A third-party gain, from the gain-plugin distribution."""

    TYPE = "{name}"
    output = Output(Scalar, doc="nothing yet")
'''


def _wheel(folder: Path, type_name: str) -> Path:
    """A pure-Python wheel of distribution ``gain-plugin`` registering ``type_name``."""
    info = "gain_plugin-1.0.dist-info"
    files = {
        "gain_plugin/__init__.py": PLUGIN.format(name=type_name),
        f"{info}/METADATA": "Metadata-Version: 2.1\nName: gain-plugin\nVersion: 1.0\n",
        f"{info}/WHEEL": "Wheel-Version: 1.0\nGenerator: umbra-test\nRoot-Is-Purelib: true\n"
        "Tag: py3-none-any\n",
        f"{info}/entry_points.txt": f"[umbra.modules]\n{type_name} = gain_plugin:ThirdPartyGain\n",
    }
    path = folder / "gain_plugin-1.0-py3-none-any.whl"
    with zipfile.ZipFile(path, "w") as wheel:
        for name, text in files.items():
            wheel.writestr(name, text)
        wheel.writestr(f"{info}/RECORD", "".join(f"{n},,\n" for n in [*files, f"{info}/RECORD"]))
    return path


def _pip_install(wheel: Path, target: Path) -> None:
    pip = [sys.executable, "-m", "pip", "install", "--no-deps", "--no-index", "--quiet"]
    subprocess.run(
        [*pip, "--target", str(target), str(wheel)],
        check=True,
        timeout=120,
    )


def _umbra(site: Path, *args: str) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(site), os.getcwd()]))
    return subprocess.run(
        [sys.executable, "-m", "umbra.runtime.cli.main", *args],
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
    )


@pytest.mark.parametrize("command", [["describe", "Gain"], ["modules"]])
def test_a_plugin_type_named_like_a_built_in_is_an_error_naming_both(
    tmp_path: Path, command: list[str]
) -> None:
    site = tmp_path / "site"
    _pip_install(_wheel(tmp_path, "Gain"), site)
    assert (site / "gain_plugin-1.0.dist-info" / "entry_points.txt").is_file()
    done = _umbra(site, *command)
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert "module type `Gain` is registered by" in done.stderr
    assert "gain-plugin 1.0 (gain_plugin:ThirdPartyGain)" in done.stderr
    assert "umbra-smart" in done.stderr and "(umbra.modules.generic.gain:Gain)" in done.stderr
    assert '[project.entry-points."umbra.modules"]' in done.stderr and "MyGain" in done.stderr


def test_a_renamed_plugin_type_is_found_beside_the_built_in(tmp_path: Path) -> None:
    site = tmp_path / "site"
    _pip_install(_wheel(tmp_path, "MyGain"), site)
    mine = _umbra(site, "describe", "MyGain")
    assert mine.returncode == 0, mine.stderr
    assert "A third-party gain, from the gain-plugin distribution." in mine.stdout
    ours = _umbra(site, "describe", "Gain")
    assert ours.returncode == 0 and "umbra.modules.generic.gain.Gain" in ours.stdout
