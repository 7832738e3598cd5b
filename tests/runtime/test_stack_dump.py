"""SIGUSR1 to a running ``umbra`` prints every thread's Python stack to stderr, and the run goes
on: what a process that does not stop is waiting for can be seen from outside."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from tests.poll import wait_for


@pytest.mark.skipif(not hasattr(signal, "SIGUSR1"), reason="needs POSIX signals")
def test_sigusr1_prints_every_threads_stack_and_the_run_goes_on(tmp_path: Path) -> None:
    graph = tmp_path / "g.yaml"
    graph.write_text(
        "graph: g\nclock: real\nmodules:\n  c: {type: Counter, rate: 50}\n"
        "  rec: {type: Recorder, params: {channels: [x]}}\n"
        "connections: [c.count -> rec.x]\n"
    )
    out = tmp_path / "out"
    proc = subprocess.Popen(
        [sys.executable, "-m", "umbra.runtime.cli.main", "run", str(graph), "--out", str(out)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    lines: list[str] = []
    assert proc.stderr is not None
    reader = threading.Thread(target=lambda: lines.extend(proc.stderr), daemon=True)
    reader.start()
    try:
        wait_for((out / "recording.mcap").exists, 30, "the recording file", 0.05)
        proc.send_signal(signal.SIGUSR1)
        wait_for(
            lambda: sum("most recent call first" in line for line in lines) >= 2,
            30,
            lambda: "two threads' stacks on stderr, found:\n" + "".join(lines),
        )
        assert proc.poll() is None, "".join(lines)  # the run went on
        dump = "".join(lines)
        assert "Current thread" in dump and 'File "' in dump, dump
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=30)
    reader.join(timeout=5)
    assert proc.returncode == 130, "".join(lines)
    assert json.loads((out / "summary.json").read_text())["exit_code"] == 130
