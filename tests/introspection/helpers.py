"""Waiting for a run's processes to be observable, and running observer commands."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

from tests.links.conftest import REPO, Running, run_umbra
from tests.poll import wait_for
from umbra.runtime.links.observe import Run, local_runs

COUNTER = str(REPO / "graphs" / "counter_split.yaml")


def user_folder(env: dict[str, str]) -> Path:
    """The private folder of the user the test's processes run as (run files, secrets)."""
    return Path(env["XDG_RUNTIME_DIR"]) / "umbra"


def running(
    run: Running | list[Running], env: dict[str, str], processes: int = 2, timeout: float = 90
) -> Run:
    """The run once its ``processes`` run files are written and every process runs (``run``:
    the launcher, or each process started by hand)."""
    commands = run if isinstance(run, list) else [run]

    def up() -> Run | None:
        runs = [r for r in local_runs(user_folder(env)) if len(r.processes) == processes]
        lines = [line for c in commands for line in c.stderr]
        if runs and sum("links ready, running" in line for line in lines) >= processes:
            return runs[0]
        for c in commands:
            assert c.popen.poll() is None, "\n".join(c.stderr[-30:])
        return None

    return wait_for(
        up, timeout, lambda: "the run to come up:\n" + "\n".join(commands[0].stderr[-30:]), 0.1
    )


def umbra_cli(
    env: dict[str, str], *args: str, timeout: float = 60, cwd: Path | None = None
) -> subprocess.CompletedProcess:
    """``umbra ARGS...`` run to its end (in ``cwd``, this folder by default)."""
    return run_umbra(env, cwd or Path.cwd(), *args, timeout=timeout)


def json_lines(text: str) -> list[dict]:
    return [json.loads(line) for line in text.splitlines() if line.startswith("{")]
