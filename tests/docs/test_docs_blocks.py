"""Every code block of README.md and docs/*.md is run or checked (the convention is in
``tests/docs/blocks.py``): Python blocks run (in order, one namespace per file), graphs pass
``umbra check``, TOML and JSON parse, and every shell command parses with umbra's own command
line and names graphs that pass ``umbra check``. The commands themselves run, with short
durations, in ``test_docs_commands.py`` (slow)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
import tomllib
import yaml

from tests.docs.blocks import NEVER_RUN, ROOT, RUN_LANGUAGES, Block, all_blocks, commands
from umbra.runtime.cli.main import build_parser
from umbra.runtime.graph.check import check_text

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


PYTHON_FILES = sorted({b.file for b in BLOCKS if b.language == "python" and b.runs})


@pytest.mark.parametrize("path", PYTHON_FILES, ids=[p.name for p in PYTHON_FILES])
def test_python_blocks_run_in_order(path: Path) -> None:
    script = "\n".join(
        f"# ---- {b.where}\n{b.text}"
        for b in BLOCKS
        if b.file == path and b.language == "python"
        if b.runs
    )
    done = subprocess.run(
        [sys.executable, "-c", script], cwd=ROOT, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, f"{path.name}: python blocks failed:\n{done.stderr[-3000:]}"


YAML_BLOCKS = [b for b in BLOCKS if b.language == "yaml" and b.runs]


@pytest.mark.parametrize("block", YAML_BLOCKS, ids=_ids(YAML_BLOCKS))
def test_yaml_blocks_are_graphs_that_check(block: Block) -> None:
    """A whole graph is checked as it stands; a fragment of top-level graph keys (``record:``)
    is checked inside graphs/tool_pickup.yaml, which it configures."""
    document = yaml.safe_load(block.text)
    assert isinstance(document, dict), f"{block.where}: expected a YAML mapping"
    if "graph" in document:
        check_text(block.text, block.where, None)
        return
    base = yaml.safe_load((ROOT / "graphs" / "tool_pickup.yaml").read_text())
    unknown = set(document) - {"record", "links", "processes", "frames", "seed", "clock", "ros2"}
    assert not unknown, f"{block.where}: neither a graph nor graph settings: {sorted(unknown)}"
    base.update(document)
    check_text(yaml.safe_dump(base), f"{block.where} (in graphs/tool_pickup.yaml)", None)


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
                assert (ROOT / target.split("::")[0]).exists(), f"{command.where}: no {target}"
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
