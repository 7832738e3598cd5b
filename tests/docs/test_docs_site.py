"""The guide holds together without building it (``.ci/run`` builds it, strictly): the README is
a landing page whose first block is the project's two set-up commands, every ``--help`` names a
guide page that exists, the graph reference names every key a graph file takes, and the pages
generated from the code cover every module type, command and benchmark result."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path
from types import ModuleType

import yaml

from tests.docs.blocks import ROOT, blocks
from umbra.runtime.cli.main import GUIDE, build_parser
from umbra.runtime.graph.parse import TOP_KEYS
from umbra.runtime.graph.parse_extends import COMPOSE_KEYS
from umbra.runtime.graph.parse_links import LINK_KEYS
from umbra.runtime.graph.parse_modules import MODULE_KEYS
from umbra.runtime.graph.parse_processes import PROCESS_KEYS
from umbra.runtime.graph.parse_ros2 import PORT_KEYS, SECTION_KEYS
from umbra.runtime.recording.settings import RECORD_KEYS
from umbra.runtime.registry import Registry

DOCS = ROOT / "docs"
SET_UP = [
    "python3 -m venv .venv && . .venv/bin/activate && pip install -e . && "
    "umbra run graphs/tool_pickup.yaml",
    "python3 -m venv .venv && . .venv/bin/activate && pip install -e '.[test]' && "
    "python -m pytest -n 2",
]


def _hook(name: str) -> ModuleType:
    path = DOCS / "hooks" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(f"docs_hook_{name}", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _generated() -> set[str]:
    """The pages the build generates, as paths under docs/."""
    return {_hook(name).PAGE for name in _hook("generated").GENERATORS}


def _nav_pages() -> set[str]:
    def walk(items: list) -> set[str]:
        found = set()
        for item in items:
            for value in item.values() if isinstance(item, dict) else [item]:
                found |= walk(value) if isinstance(value, list) else {value}
        return found

    config = yaml.load((ROOT / "mkdocs.yml").read_text(), Loader=yaml.BaseLoader)
    return walk(config["nav"])


def test_the_readme_is_a_landing_page_that_starts_with_the_set_up_commands() -> None:
    readme = ROOT / "README.md"
    assert len(readme.read_text().splitlines()) <= 150
    first = blocks(readme)[0]
    assert first.language == "bash" and first.text.splitlines() == SET_UP


def test_every_help_names_a_guide_page_that_exists() -> None:
    pages = {str(p.relative_to(ROOT)) for p in DOCS.rglob("*.md")}
    pages |= {f"docs/{page}" for page in _generated()}
    parser = build_parser()
    assert f"guide: {GUIDE}" in parser.format_help()
    assert GUIDE in pages
    (sub,) = [a for a in parser._actions if hasattr(a, "choices") and isinstance(a.choices, dict)]
    for name, command in sub.choices.items():
        text = command.format_help()
        guide = text.rsplit("guide: ", 1)[-1].split()[0] if "guide: " in text else None
        assert guide in pages, f"`umbra {name} --help` names no guide page that exists: {guide}"


def test_every_page_is_in_the_navigation_and_every_entry_is_a_page() -> None:
    pages = {str(p.relative_to(DOCS)) for p in DOCS.rglob("*.md")} | _generated()
    assert _nav_pages() == pages


def test_the_graph_reference_names_every_key() -> None:
    text = (DOCS / "guide" / "graphs.md").read_text() + (DOCS / "ros2.md").read_text()
    keys = {*TOP_KEYS, *COMPOSE_KEYS, "values", *PROCESS_KEYS, *MODULE_KEYS, *LINK_KEYS}
    keys |= {*RECORD_KEYS, *SECTION_KEYS, *PORT_KEYS}
    missing = sorted(k for k in keys if f"`{k}`" not in text and f"{k}:" not in text)
    assert not missing, f"docs/guide/graphs.md (or docs/ros2.md) does not explain {missing}"


def test_the_module_reference_describes_every_type() -> None:
    page = _hook("gen_modules").render()
    names = Registry().names()
    assert len(names) >= 30
    for name in names:
        assert f"\n## {name} " in page and f"\n{name}  (" in page, name


def test_the_command_reference_holds_every_help() -> None:
    page = _hook("gen_cli").render()
    parser = build_parser()
    (sub,) = [a for a in parser._actions if hasattr(a, "choices") and isinstance(a.choices, dict)]
    for name in sub.choices:
        assert f"\n## umbra {name}\n" in page and f"usage: umbra {name}" in page, name


def test_the_benchmark_page_has_one_table_per_result_with_its_goals() -> None:
    gen = _hook("gen_benchmarks")
    page = gen.render()
    results = gen.result_files()
    assert results and all(not p.name.endswith(".quick.json") for p in results)
    for path in results:
        assert f"\n## {path.stem}\n" in page, path.name
        assert f"`benchmarks/results/{path.name}`" in page
    servo = json.loads((ROOT / "benchmarks" / "results" / "servo_tick.json").read_text())
    verdict = "**met**" if servo["meets_goal"] else "**missed**"
    assert f"| goal: meets_goal | {verdict} |" in page


def test_the_fence_hook_keeps_the_language_and_names_the_file() -> None:
    fences = _hook("fences")
    shown = "```python file=affine-demo/affine.py\nx = 1\n```\n```bash norun\nls\n```\n"
    site = fences.on_page_markdown(shown)
    assert site.splitlines()[0] == '```python title="affine-demo/affine.py"'
    assert "```bash\nls" in site
    assert Path(fences.__file__).parent == DOCS / "hooks"
