"""The shell blocks of README.md and docs/*.md, run as a user runs them, block by block in a
fresh folder (``graphs/`` linked in), so that one command's output feeds the next (a recording,
then its replay). Runs are cut short: ``umbra run`` and ``umbra replay`` get ``--duration 3``
unless the line gives one. Set-up lines (venv, pip, ``.``) and the test suite itself are not run
here (``.ci/run`` runs them in a fresh environment). A command must not fail on its input (exit
2) or crash (a traceback); a short run may end 1 (a pick-up not judged in 3 s), any other
command must succeed."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.docs.blocks import ROOT, Block, all_blocks, commands

pytestmark = pytest.mark.slow

SHELL_BLOCKS = [b for b in all_blocks() if b.language == "bash" and b.runs and commands(b)]
SKIPPED = {".", "source", "pip", "cd", "export"}
SHORT = ["--duration", "3"]


def _argv(argv: list[str]) -> list[str] | None:
    program, *args = argv
    if program in SKIPPED or (program.startswith("python") and args[:2] != ["-m", "umbra"]):
        return None
    assert program == "umbra", f"unexpected program {program!r}"
    if args and args[0] in ("run", "replay") and "--duration" not in args:
        args = [*args, *SHORT]
    return [sys.executable, "-m", "umbra.runtime.cli.main", *args]


@pytest.mark.timeout(900)
@pytest.mark.parametrize("block", SHELL_BLOCKS, ids=[b.where for b in SHELL_BLOCKS])
def test_shell_block_runs(block: Block, tmp_path: Path) -> None:
    (tmp_path / "graphs").symlink_to(ROOT / "graphs")
    env = dict(
        os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])
    )
    for command in commands(block):
        argv = _argv(command.argv)
        if argv is None:
            continue
        done = subprocess.run(
            argv, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600
        )
        said = f"{command.where}: `{' '.join(command.argv)}` exited {done.returncode}:\n"
        said += done.stderr[-2000:]
        assert "Traceback" not in done.stderr, said
        is_run = command.argv[1] in ("run", "replay")
        assert done.returncode in ((0, 1) if is_run else (0,)), said
