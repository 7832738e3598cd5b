"""The shell blocks of README.md and the guide (docs/**/*.md), run as a user runs them, block by
block in a fresh folder (``graphs/`` linked in, the page's own files written out), so that one
command's output feeds the next (a recording, then its replay). Runs are cut short: ``umbra run``
and ``umbra replay`` get ``--duration 3`` unless the line gives one. A command ending in ``&``
runs in the background while the block's later commands run; those are tried again (for 60 s at
most) while they fail for want of it (exit 2: no graph running yet). Set-up lines (venv, ``.``)
and the test suite itself are not run here (``.ci/run`` runs them in a fresh environment); ``pip
install -e ./DIR`` of a folder the page writes installs it into the test's folder. A command
must not crash (a traceback) and must end with the status its ``# exits N`` comment says, else
succeed (a short run may also end 1: a pick-up not judged in 3 s); a ``text output`` block after
the bash block is what its last command prints."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.docs.blocks import ROOT, Block, Command, all_blocks, commands, files, output_after
from tests.docs.blocks import write_files as write_page_files

pytestmark = pytest.mark.slow

SHELL_BLOCKS = [b for b in all_blocks() if b.language == "bash" and b.runs and commands(b)]
SKIPPED = {".", "source", "pip", "cd", "export"}
SHORT = ["--duration", "3"]
#: how long a command beside a background run is tried again while that run starts [s]
STARTING_S = 60.0


def _argv(command: Command, site: Path) -> list[str] | None:
    """What the test runs for a command of the docs; None for a set-up line it leaves out."""
    program, *args = command.argv
    shown = files(command.block.file)
    if program == "pip" and args[:2] == ["install", "-e"] and args[2].strip("./") in _dirs(shown):
        pip = [sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-index"]
        return [*pip, "--no-build-isolation", "--target", str(site), args[2]]
    if program.startswith("python") and args[:2] == ["-m", "pytest"]:
        targets = [a for a in args[2:] if not a.startswith("-")]
        if targets and all(t.split("::")[0] in shown for t in targets):
            return [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", *args[2:]]
        return None  # the project's own suite: .ci/run runs it
    if program in SKIPPED or (program.startswith("python") and args[:2] != ["-m", "umbra"]):
        return None
    assert program == "umbra", f"unexpected program {program!r}"
    if args and args[0] in ("run", "replay") and "--duration" not in args:
        args = [*args, *SHORT]
    return [sys.executable, "-m", "umbra.runtime.cli.main", *args]


def _dirs(shown: dict[str, Block]) -> set[str]:
    return {name.split("/")[0] for name in shown if "/" in name}


def _ends_as_said(command: Command, code: int) -> bool:
    if command.expect is not None:
        return code == command.expect
    is_run = command.argv[0] == "umbra" and command.argv[1] in ("run", "replay")
    return code in ((0, 1) if is_run else (0,))


@pytest.mark.timeout(900)
@pytest.mark.parametrize("block", SHELL_BLOCKS, ids=[b.where for b in SHELL_BLOCKS])
def test_shell_block_runs(block: Block, tmp_path: Path) -> None:
    (tmp_path / "graphs").symlink_to(ROOT / "graphs")
    (tmp_path / "modules").symlink_to(ROOT / "modules")  # data files the docs name
    write_page_files(block.file, tmp_path)
    site = tmp_path / "site-packages"
    path = [str(site), str(ROOT), os.environ.get("PYTHONPATH", "")]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(path))
    background: list[subprocess.Popen[str]] = []
    done = None
    try:
        for command in commands(block):
            argv = _argv(command, site)
            if argv is None:
                continue
            if command.background:
                background.append(
                    subprocess.Popen(
                        argv,
                        cwd=tmp_path,
                        env=env,
                        stdout=subprocess.DEVNULL,
                        stderr=subprocess.DEVNULL,
                        text=True,
                    )
                )
                continue
            deadline = time.monotonic() + STARTING_S
            while True:
                done = subprocess.run(
                    argv, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600
                )
                starting = any(p.poll() is None for p in background) and done.returncode == 2
                if not starting or _ends_as_said(command, 2) or time.monotonic() > deadline:
                    break
            said = f"{command.where}: `{' '.join(command.argv)}` exited {done.returncode}:\n"
            said += done.stderr[-2000:]
            assert "Traceback" not in done.stderr, said
            assert _ends_as_said(command, done.returncode), said
    finally:
        for proc in background:
            proc.terminate()
            proc.wait(timeout=30)
    shown = output_after(block)
    if shown is not None:
        assert done is not None, f"{block.where}: no command printed the output shown after it"
        printed = {line.rstrip() for line in (done.stdout + done.stderr).splitlines()}
        missing = [line for line in shown.text.splitlines() if line.rstrip() not in printed]
        assert not missing, f"{shown.where}: not printed: {missing}\nprinted:\n{done.stdout}"
