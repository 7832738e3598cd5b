"""What the distribution installs cannot collide with another's names: one top-level package,
``umbra`` (``umbra.connectors``, ``umbra.modules``, ``umbra.runtime``), and nothing else (no
``.pth`` that runs code in every interpreter of the environment).

Each case runs in a fresh interpreter whose working folder is a tmp folder: the checkout's root
(where ``runtime/`` is a plain folder) must not be on ``sys.path``, as it is not for a user.
"""

from __future__ import annotations

import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
FOLDERS = ("connectors", "modules", "runtime")
#: a wheel of the sources alone, with this environment's setuptools and no network
PIP_WHEEL = (
    sys.executable,
    "-m",
    "pip",
    "wheel",
    "-q",
    "--no-deps",
    "--no-build-isolation",
    "--no-index",
)


def _python(code: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    return subprocess.run(
        [sys.executable, "-c", code], cwd=cwd, env=env, capture_output=True, text=True, timeout=120
    )


def test_the_folder_names_are_not_installed_and_a_users_own_packages_of_those_names_win(
    tmp_path: Path,
) -> None:
    bare = _python(
        "import importlib.util as u\nprint([u.find_spec(n) for n in ('runtime', 'modules', "
        "'connectors')])\n",
        tmp_path,
    )
    assert bare.returncode == 0 and bare.stdout.strip() == "[None, None, None]", bare
    for name in FOLDERS:
        (tmp_path / name).mkdir()
        (tmp_path / name / "__init__.py").write_text(f"WHOSE = 'the user {name}'\n")
    code = (
        "import umbra.runtime.scheduler as s, runtime, modules, connectors\n"
        "print(runtime.WHOSE, modules.WHOSE, connectors.WHOSE, sep=', ')\n"
        "print(s.Scheduler.__module__)\n"
    )
    done = _python(code, tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == [
        "the user runtime, the user modules, the user connectors",
        "umbra.runtime.scheduler",
    ]
    cli = subprocess.run(
        [sys.executable, "-m", "umbra.runtime.cli.main", "--help"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert cli.returncode == 0 and "usage: umbra" in cli.stdout, cli.stderr


@pytest.mark.slow
@pytest.mark.untimed
def test_the_wheel_holds_one_top_level_package_and_nothing_that_runs_at_start_up(
    tmp_path: Path,
) -> None:
    """The wheel is built from a copy of the sources with this environment's setuptools (no
    network), unpacked as a site folder; the CLI runs from it."""
    source = tmp_path / "source"
    source.mkdir()
    for name in ("pyproject.toml", "setup.py", "README.md"):
        (source / name).write_bytes((REPO / name).read_bytes())
    for folder in ("umbra", *FOLDERS):
        subprocess.run(
            ["cp", "-r", str(REPO / folder), str(source / folder)], check=True, timeout=60
        )
    wheels = tmp_path / "wheels"
    built = subprocess.run(
        [*PIP_WHEEL, "-w", str(wheels), str(source)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert built.returncode == 0, built.stderr[-3000:]
    (wheel,) = wheels.glob("umbra_smart-*.whl")
    with zipfile.ZipFile(wheel) as archive:
        names = archive.namelist()
        archive.extractall(tmp_path / "site")
    tops = {name.split("/")[0] for name in names}
    assert tops == {"umbra", wheel.name.split("-py")[0] + ".dist-info"}
    assert not [name for name in names if name.endswith(".pth")]
    site_dir = tmp_path / "site"
    assert (site_dir / "umbra" / "runtime" / "scheduler.py").is_file()
    assert (site_dir / "umbra" / "modules" / "operator" / "static").is_dir()
    code = (
        "import site, sys, runpy\n"
        f"site.addsitedir({str(site_dir)!r})\n"
        "assert 'umbra' not in sys.modules\n"  # nothing of ours ran at start-up
        "import umbra.runtime.scheduler as s\n"
        "print(s.__file__)\n"
        "sys.argv = ['umbra', '--help']\n"
        "runpy.run_module('umbra.runtime.cli.main', run_name='__main__')\n"
    )
    done = _python(code, tmp_path)
    assert done.stdout.splitlines()[0] == str(site_dir / "umbra" / "runtime" / "scheduler.py"), (
        done.stderr
    )
    assert "usage: umbra" in done.stdout and done.returncode == 0, done.stderr
