"""Every code block of README.md and the guide (docs/**/*.md) is run or checked (the convention
is in ``tests/docs/blocks.py``): Python blocks run (in order, one namespace per file), the whole
files a page shows are written out and their tests run, graphs pass ``umbra check`` (or fail it,
when shown for their errors), TOML and JSON parse, and every shell command parses with umbra's
own command line and names graphs that pass ``umbra check``. The commands themselves run, with
short durations, in ``test_docs_commands.py`` (slow)."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import pytest
import tomllib
import yaml

from tests.docs.blocks import (
    NEVER_RUN,
    ROOT,
    RUN_LANGUAGES,
    Block,
    all_blocks,
    commands,
    files,
    output_after,
    write_files,
)
from umbra.connectors.errors import UserError
from umbra.connectors.module import Module
from umbra.runtime.cli.main import build_parser
from umbra.runtime.graph.check import check_text
from umbra.runtime.registry import Registry

BLOCKS = all_blocks()
SHELL_BUILTINS = {".", "source", "cd", "export"}


def _ids(items: list[Block]) -> list[str]:
    return [b.where for b in items]


def test_the_docs_have_blocks_to_run() -> None:
    assert sum(b.runs for b in BLOCKS) >= 12
    assert {"python", "yaml", "bash", "toml"} <= {b.language for b in BLOCKS if b.runs}


@pytest.mark.parametrize("block", BLOCKS, ids=_ids(BLOCKS))
def test_every_block_names_its_language(block: Block) -> None:
    known = RUN_LANGUAGES | NEVER_RUN
    assert block.language in known, (
        f"{block.where}: a fenced block needs a language ({', '.join(sorted(known))}); "
        "`text` for output or layouts, `LANG norun` for a block shown but not run"
    )


PYTHON_FILES = sorted(
    {b.file for b in BLOCKS if b.language == "python" and b.runs and not b.file_name}
)


@pytest.mark.parametrize("path", PYTHON_FILES, ids=[p.name for p in PYTHON_FILES])
def test_python_blocks_run_in_order(path: Path) -> None:
    script = "\n".join(
        f"# ---- {b.where}\n{b.text}"
        for b in BLOCKS
        if b.file == path and b.language == "python"
        if b.runs and not b.file_name
    )
    done = subprocess.run(
        [sys.executable, "-c", script], cwd=ROOT, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, f"{path.name}: python blocks failed:\n{done.stderr[-3000:]}"


YAML_BLOCKS = [b for b in BLOCKS if b.language == "yaml" and b.runs]


@pytest.mark.parametrize("block", YAML_BLOCKS, ids=_ids(YAML_BLOCKS))
def test_yaml_blocks_are_graphs_that_check(block: Block, tmp_path: Path) -> None:
    """A whole graph is checked as it stands; a fragment of top-level graph keys (``record:``)
    is checked inside graphs/tool_pickup.yaml, which it configures."""
    document = yaml.safe_load(block.text)
    assert isinstance(document, dict), f"{block.where}: expected a YAML mapping"
    if block.fails:
        with pytest.raises(UserError):
            check_text(block.text, block.file_name or block.where, None)
        return
    if "graph" in document:
        check_text(block.text, block.where, _registry_with_page_modules(block.file, tmp_path))
        return
    base = yaml.safe_load((ROOT / "graphs" / "tool_pickup.yaml").read_text())
    unknown = set(document) - {"record", "links", "processes", "frames", "seed", "clock", "ros2"}
    assert not unknown, f"{block.where}: neither a graph nor graph settings: {sorted(unknown)}"
    base.update(document)
    check_text(yaml.safe_dump(base), f"{block.where} (in graphs/tool_pickup.yaml)", None)


def _registry_with_page_modules(page: Path, folder: Path) -> Registry:
    """The installed module types and those the page's own Python files define (a graph on the
    page uses the module the page writes)."""
    registry = Registry()
    for path in write_files(page, folder):
        if path.suffix != ".py" or path.name.startswith("test_"):
            continue
        spec = importlib.util.spec_from_file_location(f"doc_page_{path.stem}", path)
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        for value in vars(module).values():
            ours = isinstance(value, type) and value.__module__ == module.__name__
            if ours and issubclass(value, Module):
                registry.add(value)
    return registry


PAGES_WITH_FILES = sorted({b.file for b in BLOCKS if b.file_name})


@pytest.mark.parametrize("page", PAGES_WITH_FILES, ids=[p.name for p in PAGES_WITH_FILES])
def test_the_files_a_page_shows_are_whole_and_their_tests_pass(page: Path, tmp_path: Path) -> None:
    """Every Python file compiles as it stands, every ``test_*.py`` passes (run by pytest in the
    folder the files were written into, as a reader runs it)."""
    written = write_files(page, tmp_path)
    for path in written:
        if path.suffix == ".py":
            compile(path.read_text(), str(path), "exec")
    tests = [str(p.relative_to(tmp_path)) for p in written if p.name.startswith("test_")]
    if not tests:
        return
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *tests],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, f"{page.name}: its tests failed:\n{done.stdout[-3000:]}"


OUTPUT_BLOCKS = [b for b in BLOCKS if b.is_output]


@pytest.mark.parametrize("block", OUTPUT_BLOCKS, ids=_ids(OUTPUT_BLOCKS))
def test_an_output_block_follows_the_commands_it_shows(block: Block) -> None:
    before = [b for b in BLOCKS if b.file == block.file and b.line < block.line]
    assert before and before[-1].language == "bash" and output_after(before[-1]) == block, (
        f"{block.where}: a `text output` block must come right after the bash block it shows"
    )


TOML_BLOCKS = [b for b in BLOCKS if b.language == "toml" and b.runs]


@pytest.mark.parametrize("block", TOML_BLOCKS, ids=_ids(TOML_BLOCKS))
def test_toml_blocks_parse(block: Block) -> None:
    table = tomllib.loads(block.text)
    assert table, f"{block.where}: empty TOML"


JSON_BLOCKS = [b for b in BLOCKS if b.language == "json" and b.runs]


@pytest.mark.parametrize("block", JSON_BLOCKS, ids=_ids(JSON_BLOCKS))
def test_json_blocks_parse(block: Block) -> None:
    json.loads(block.text)


COMMANDS = [c for b in BLOCKS if b.language == "bash" and b.runs for c in commands(b)]


@pytest.mark.parametrize("command", COMMANDS, ids=[c.where for c in COMMANDS])
def test_shell_commands_parse_and_their_graphs_check(command) -> None:
    program, *args = command.argv
    if program in SHELL_BUILTINS or program == "pip":
        return  # set-up steps, run as written by .ci/run in a fresh environment
    if program in ("python", "python3"):
        assert args[:1] == ["-m"] and args[1] in (
            "venv",
            "pytest",
            "umbra.modules.calib.visca.sim_camera",
        ), f"{command.where}: unexpected python command {command.argv}"
        for target in args[2:]:
            if args[1] == "pytest" and not target.startswith("-") and "/" in target:
                name = target.split("::")[0]
                shown = name in files(command.block.file)
                assert shown or (ROOT / name).exists(), f"{command.where}: no {target}"
        return
    assert program == "umbra", f"{command.where}: {program!r} is not a command the docs test knows"
    try:
        build_parser().parse_args(args)
    except SystemExit as exc:
        pytest.fail(f"{command.where}: `{' '.join(command.argv)}` does not parse (exit {exc})")
    for word in args:
        if word.startswith("graphs/") and word.endswith(".yaml"):
            graph = ROOT / word
            assert graph.is_file(), f"{command.where}: no graph {word}"
            check_text(graph.read_text(), str(graph), None)
