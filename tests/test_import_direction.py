"""Imports run the declared way (``tests/import_rules.py``, explained in ``docs/code-map.md``):
modules -> connectors <- runtime, domains by their declared arrows, no cycles between files.
The checker itself is tested on small trees written in tmp_path, and on a copy of the project
with one bad import added."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

from tests.import_rules import (
    DOMAIN_ARROWS,
    EXCEPTIONS,
    LAYERS,
    Rules,
    cycles,
    new_cycles,
    old_name_imports,
    violations,
)

REPO = Path(__file__).resolve().parents[1]
MAP = REPO / "docs" / "code-map.md"


def test_every_import_runs_the_declared_way() -> None:
    assert violations(REPO) == []


def test_no_new_import_cycle_between_files() -> None:
    assert new_cycles(REPO) == []


def test_no_file_imports_a_layer_by_its_old_top_level_name() -> None:
    folders = ("connectors", "modules", "runtime", "umbra", "tests", "benchmarks")
    assert old_name_imports(REPO, folders) == []


def test_the_checker_names_an_import_by_an_old_top_level_name(tmp_path: Path) -> None:
    old = "runtime.scheduler"
    root = _tree(tmp_path, {"runtime/scheduler.py": "", "modules/arm/reg.py": f"import {old}\n"})
    assert violations(root, RULES) == [f"modules/arm/reg.py:1: imports {old}: import umbra.{old}"]


def test_the_declared_domain_arrows_have_no_cycle_and_name_real_domains() -> None:
    assert cycles(DOMAIN_ARROWS) == []
    on_disk = {p.parent.name for p in (REPO / "modules").glob("*/__init__.py")}
    assert set(DOMAIN_ARROWS) == on_disk
    for file in EXCEPTIONS:
        assert (REPO / file).is_file(), f"exception for a file that is gone: {file}"


def test_the_code_map_shows_the_declared_arrows() -> None:
    """The map's table (``| `modules/<domain>/` | ... | <arrows> |``) says what the rules say."""
    rows = re.findall(r"^\| `modules/(\w+)/` \|[^|\n]*\| ([^|\n]*) \|$", MAP.read_text(), re.M)
    documented = {name: set(re.findall(r"`(\w+)`", arrows)) for name, arrows in rows}
    assert documented == DOMAIN_ARROWS


def _tree(root: Path, files: dict[str, str]) -> Path:
    for rel, text in files.items():
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    for top in ("connectors", "modules", "runtime"):
        (root / top).mkdir(exist_ok=True)
        for folder in [root / top, *(p for p in (root / top).rglob("*") if p.is_dir())]:
            (folder / "__init__.py").touch()
    return root


RULES = Rules(
    layers=LAYERS,
    domains={"geometry": set(), "arm": {"geometry"}, "sketch": {"arm"}},
    exceptions={},
    known_cycles=[],
)


@pytest.mark.parametrize(
    ("rel", "text", "message"),
    [
        ("connectors/ports.py", "import umbra.runtime.scheduler\n", "`connectors` may import only"),
        (
            "runtime/scheduler.py",
            "def f():\n    from umbra.modules.arm.reg import RegVel\n",
            "`runtime` may import only connectors, runtime",
        ),
        (
            "modules/arm/reg.py",
            "from umbra.runtime import scheduler\n",
            "`modules` may import only",
        ),
        (
            "modules/geometry/frames.py",
            "import typing\nif typing.TYPE_CHECKING:\n    from umbra.modules.arm.reg import X\n",
            "domain `geometry` may import no other domain",
        ),
        ("modules/arm/reg.py", "from ..sketch import plan\n", "domain `arm` may import geometry"),
        (  # a domain's message types are no exception: shared ones live in connectors
            "modules/arm/reg.py",
            "from umbra.modules.sketch.messages import ToolPath\n",
            "domain `arm` may import geometry",
        ),
    ],
)
def test_the_checker_names_an_import_against_the_direction(
    tmp_path: Path, rel: str, text: str, message: str
) -> None:
    base = {
        "connectors/ports.py": "import numpy\nfrom umbra.connectors import messages\n",
        "connectors/messages.py": "",
        "runtime/scheduler.py": "from umbra.connectors.ports import Input\n",
        "modules/geometry/frames.py": "import numpy as np\n",
        "modules/arm/reg.py": (
            "import umbra.connectors.ports\n"  # the base layer
            "import umbra.modules.geometry.frames\n"  # a declared arrow: arm -> geometry
        ),
        "modules/sketch/plan.py": "from umbra.modules.arm.reg import X\n",
        "modules/sketch/messages.py": "from umbra.connectors.messages import Message\n",
    }
    root = _tree(tmp_path, base)
    assert violations(root, RULES) == []  # the tree as written follows the rules
    path = root / rel
    path.write_text(path.read_text() + text)
    lines = len(path.read_text().splitlines())
    (found,) = violations(root, RULES)
    assert found.startswith(f"{rel}:{lines}: imports ") and message in found, found


def test_the_checker_finds_a_cycle_through_a_lazy_import(tmp_path: Path) -> None:
    root = _tree(
        tmp_path,
        {
            "runtime/scheduler.py": "from umbra.runtime.recording import tap\n",
            "runtime/recording/tap.py": "def f():\n    import umbra.runtime.scheduler\n",
        },
    )
    assert new_cycles(root, RULES) == [{"umbra.runtime.scheduler", "umbra.runtime.recording.tap"}]


def test_a_bad_import_in_a_copy_of_the_project_fails_the_check(tmp_path: Path) -> None:
    copy = tmp_path / "repo"
    for top in ("connectors", "modules", "runtime"):
        shutil.copytree(REPO / top, copy / top, ignore=shutil.ignore_patterns("__pycache__"))
    assert violations(copy) == [] and new_cycles(copy) == []
    transforms = copy / "modules" / "geometry" / "transforms.py"
    text = transforms.read_text()
    transforms.write_text(
        text + "\n\ndef _bad():\n    from umbra.runtime.scheduler import Scheduler\n"
    )
    line = len(transforms.read_text().splitlines())
    assert violations(copy) == [
        f"modules/geometry/transforms.py:{line}: imports umbra.runtime.scheduler: "
        "`modules` may import only connectors, modules"
    ]
    tap = copy / "runtime" / "recording" / "tap.py"
    tap.write_text(tap.read_text() + "\n\ndef _back():\n    import umbra.runtime.scheduler\n")
    assert any(
        {"umbra.runtime.scheduler", "umbra.runtime.recording.tap"} <= c for c in new_cycles(copy)
    )
