"""What the distribution installs cannot collide with another's names: one top-level package,
``umbra`` (``umbra.connectors``, ``umbra.modules``, ``umbra.runtime``), and the old top-level
names kept as deprecated aliases that never shadow a user's own package (``umbra/legacy_names.py``).

Each case runs in a fresh interpreter whose working folder is a tmp folder: the checkout's root
(where ``runtime/`` is a plain folder) must not be on ``sys.path``, as it is not for a user.

rename_imports: skip (this file writes the old names on purpose)
"""

from __future__ import annotations

import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
OLD_NAMES = ("connectors", "modules", "runtime")
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


def _python(code: str, cwd: Path, *args: str) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    return subprocess.run(
        [sys.executable, *args, "-c", code],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_a_users_own_runtime_modules_and_connectors_packages_win_over_the_old_names(
    tmp_path: Path,
) -> None:
    for name in OLD_NAMES:
        (tmp_path / name).mkdir()
        (tmp_path / name / "__init__.py").write_text(f"WHOSE = 'the user {name}'\n")
    code = (
        "import umbra, runtime, modules, connectors\n"
        "print(runtime.WHOSE, modules.WHOSE, connectors.WHOSE, sep=', ')\n"
        "import umbra.runtime.scheduler as s\n"
        "print(s.Scheduler.__module__)\n"
        "try:\n"
        "    import runtime.scheduler\n"
        "except ModuleNotFoundError as e:\n"
        "    print('no', e.name)\n"
    )
    done = _python(code, tmp_path, "-W", "error::DeprecationWarning")  # no alias was made
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == [
        "the user runtime, the user modules, the user connectors",
        "umbra.runtime.scheduler",
        "no runtime.scheduler",
    ]
    cli = subprocess.run(
        [sys.executable, "-m", "umbra.runtime.cli.main", "--help"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert cli.returncode == 0 and "usage: umbra" in cli.stdout, cli.stderr


def test_an_old_name_is_the_same_module_and_warns_where_it_is_imported(tmp_path: Path) -> None:
    code = (
        "import warnings\n"
        "warnings.simplefilter('always')\n"
        "with warnings.catch_warnings(record=True) as caught:\n"
        "    import umbra.runtime.scheduler\n"
        "    import umbra.connectors.messages\n"
        "    assert caught == [], caught\n"
        "    import runtime.scheduler\n"
        "    from connectors.messages import Scalar\n"
        "    import modules.arm.reg_vel\n"
        "assert runtime.scheduler is umbra.runtime.scheduler\n"
        "assert Scalar is umbra.connectors.messages.Scalar\n"
        "import sys\n"
        "assert sys.modules['modules.arm'] is sys.modules['umbra.modules.arm']\n"
        "for w in caught:\n"
        "    print(w.category.__name__, w.filename, w.lineno, str(w.message).split(':')[0])\n"
    )
    done = _python(code, tmp_path)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    said = {line.split(" ", 3)[3] for line in lines}
    assert {
        "`runtime` is a deprecated name of umbra-smart's `umbra.runtime`",
        "`runtime.scheduler` is a deprecated name of umbra-smart's `umbra.runtime.scheduler`",
        "`connectors` is a deprecated name of umbra-smart's `umbra.connectors`",
        "`connectors.messages` is a deprecated name of umbra-smart's `umbra.connectors.messages`",
        "`modules.arm.reg_vel` is a deprecated name of umbra-smart's `umbra.modules.arm.reg_vel`",
    } <= said, lines
    # every warning points at the user's import statement (lines 7 to 9 of the script)
    assert {tuple(line.split(" ")[:3]) for line in lines} <= {
        ("DeprecationWarning", "<string>", str(n)) for n in (7, 8, 9)
    }, lines


def test_a_name_missing_under_umbra_is_missing_under_the_old_name_too(tmp_path: Path) -> None:
    code = (
        "import importlib.util, umbra, runtime\n"
        "print(importlib.util.find_spec('runtime.no_such_module'))\n"
        "print(importlib.util.find_spec('runtime.scheduler').name)\n"
    )
    done = _python(code, tmp_path, "-W", "ignore::DeprecationWarning")
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == ["None", "runtime.scheduler"]


@pytest.mark.slow
@pytest.mark.untimed
def test_the_wheel_holds_one_top_level_package_and_the_pth_keeps_old_scripts_running(
    tmp_path: Path,
) -> None:
    """The wheel is built from a copy of the sources with this environment's setuptools (no
    network), unpacked as a site folder; an old script that never imports ``umbra`` runs."""
    source = tmp_path / "source"
    source.mkdir()
    for name in ("pyproject.toml", "setup.py", "README.md"):
        (source / name).write_bytes((REPO / name).read_bytes())
    for folder in ("umbra", *OLD_NAMES):
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
        tops = {name.split("/")[0] for name in archive.namelist()}
        archive.extractall(tmp_path / "site")
    assert tops == {
        "umbra",
        "umbra-smart-legacy-names.pth",
        wheel.name.split("-py")[0] + ".dist-info",
    }
    assert (tmp_path / "site" / "umbra" / "runtime" / "scheduler.py").is_file()
    assert (tmp_path / "site" / "umbra" / "modules" / "operator" / "static").is_dir()
    code = (
        "import site, sys, runpy, warnings\n"
        f"site.addsitedir({str(tmp_path / 'site')!r})\n"  # as site-packages: its .pth runs
        "assert 'umbra' in sys.modules\n"
        "warnings.simplefilter('ignore', DeprecationWarning)\n"
        "from connectors.messages import Scalar\n"
        "import runtime.scheduler\n"
        "print(Scalar.__module__, runtime.scheduler.__file__)\n"
        "sys.argv = ['umbra', '--help']\n"
        "runpy.run_module('runtime.cli.main', run_name='__main__')\n"
    )
    done = _python(code, tmp_path)
    site_dir = tmp_path / "site"
    assert done.stdout.splitlines()[0] == (
        f"umbra.connectors.messages {site_dir / 'umbra' / 'runtime' / 'scheduler.py'}"
    ), done.stderr
    assert "usage: umbra" in done.stdout and done.returncode == 0, done.stderr
