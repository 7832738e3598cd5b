"""A graph run with ``--foxglove`` in a child process, and the independent npm client."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.poll import wait_for

NODE_DIR = Path(__file__).resolve().parent / "node"
REPO = Path(__file__).resolve().parents[2]
_URL = re.compile(r"foxglove: open (ws://\S+)")
_RUN_ID = re.compile(r"umbra run: run ID (\S+)")

needs_node = pytest.mark.skipif(
    shutil.which("node") is None or shutil.which("npm") is None,
    reason="needs node and npm (the independent @foxglove/ws-protocol client)",
)


def install_client(folder: Path) -> Path:
    """``tests/live/node`` installed by npm into ``folder`` (no global install); its client."""
    folder.mkdir(parents=True, exist_ok=True)
    for name in ("package.json", "client.js", "tune.js"):
        shutil.copy(NODE_DIR / name, folder / name)
    done = subprocess.run(
        ["npm", "install", "--no-audit", "--no-fund", "--loglevel=error"],
        cwd=folder,
        capture_output=True,
        text=True,
        timeout=300,
    )
    if done.returncode != 0:
        pytest.skip(f"npm install of the ws-protocol client failed: {done.stderr[-400:]}")
    return folder / "client.js"


def run_client(client: Path, url: str, seconds: float, subprotocol: str = "") -> dict:
    """The npm client's report after ``seconds`` subscribed to every channel of ``url``."""
    args = ["node", str(client), url, str(seconds), *([subprotocol] if subprotocol else [])]
    done = subprocess.run(args, capture_output=True, text=True, timeout=seconds + 60)
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


def run_tune(tune_js: Path, url: str, seconds: float, topics: str, changes: list[dict]) -> dict:
    """``tune.js``'s report: parameters, answers to ``changes``, status messages, samples."""
    args = ["node", str(tune_js), url, str(seconds), topics, json.dumps(changes)]
    done = subprocess.run(args, capture_output=True, text=True, timeout=seconds + 60)
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


def wait_joined(run: LiveRun, timeout: float = 60.0) -> None:
    """Until the live server of a split run receives the other processes' samples (it then
    joins them as the tuner and says so)."""
    wait_for(
        lambda: "foxglove: parameter changes reach processes" in run.text(),
        timeout,
        lambda: f"the live server to join the processes:\n{run.text()[-3000:]}",
        0.2,
    )


class LiveRun:
    """``umbra run GRAPH --foxglove --foxglove-port 0 ...`` in a child process."""

    def __init__(self, graph: str, out: Path, *extra: str) -> None:
        self.log_path = out.parent / f"{out.name}.log"
        self._log = open(self.log_path, "w")  # noqa: SIM115 — closed by stop()
        cmd = [sys.executable, "-m", "umbra.runtime.cli.main", "run", graph, "--foxglove"]
        cmd += ["--foxglove-port", "0", "--out", str(out), "--quiet", *extra]
        self.proc = subprocess.Popen(
            cmd, cwd=REPO, stdout=self._log, stderr=subprocess.STDOUT, env=dict(os.environ)
        )
        self.url = self._wait_url()

    def _wait_url(self, timeout: float = 60.0) -> str:
        def url() -> str:
            found = _URL.search(self.text())
            assert found or self.proc.poll() is None, f"ended, no address:\n{self.text()[-3000:]}"
            return found.group(1) if found else ""

        return wait_for(url, timeout, lambda: f"a foxglove address:\n{self.text()[-3000:]}", 0.1)

    def text(self) -> str:
        return self.log_path.read_text(errors="replace")

    @property
    def run_id(self) -> str:
        """The run ID the launcher said on start."""
        found = _RUN_ID.search(self.text())
        assert found, f"no run ID said:\n{self.text()[-3000:]}"
        return found.group(1)

    def wait(self, timeout: float = 120.0) -> int:
        try:
            return self.proc.wait(timeout)
        finally:
            self._log.close()

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self._log.close()
