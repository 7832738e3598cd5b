"""The launcher watching its processes: a death, a failure, an interrupt; servo side first."""

from __future__ import annotations

import json
import os
import re
import signal
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from tests.links.conftest import Running
from umbra.modules.generic.recording import read_recording

# whole runs of umbra in subprocesses, seconds each: in CI with -m slow (a short default run)
pytestmark = pytest.mark.slow

SERVO_GRAPH = """
graph: guarded
clock: real
processes: {umbra: {}, smart: {}, view: {}}
modules:
  counter: {type: Counter, process: umbra, rate: 100, params: {start: 1}}
  guard: {type: ProbeGuard, process: smart, params: {tell_after: 20}}
  record: {type: Recorder, process: smart, params: {channels: [twist], path: twist.mcap}}
  watch: {type: LinkWatch, process: smart, rate: 100}
  boom: {type: Boom, process: view, params: {at: %(boom_at)s}}
connections:
  - counter.count -> guard.value
  - guard.twist -> record.twist
  - counter.count -> watch.input
  - counter.count -> boom.value
"""


def _graph(tmp_path: Path, boom_at: float = 1e9) -> str:
    path = tmp_path / "guarded.yaml"
    path.write_text(SERVO_GRAPH % {"boom_at": boom_at})
    return str(path)


def _pid(run: Running, process: str) -> int:
    line = run.wait_for(f"started process `{process}`")
    match = re.search(r"pid (\d+)", line)
    assert match, line
    return int(match.group(1))


def _twists(out: Path) -> np.ndarray:
    return np.array([s.vector for _c, s in read_recording(out / "twist.mcap")])


def _ended_order(run: Running) -> list[str]:
    return re.findall(r"umbra run: process `(\w+)` ended", "\n".join(run.stderr))


def _summaries(out: Path) -> dict[str, dict]:
    return {
        p: json.loads((out / f"summary-{p}.json").read_text()) for p in ("umbra", "smart", "view")
    }


def test_killed_process_fails_the_run_and_the_servo_side_zeroes(
    umbra: Callable[..., Running], tmp_path: Path
) -> None:
    run = umbra("run", _graph(tmp_path), "--out", "out", "--duration", "60")
    pid = _pid(run, "umbra")
    run.wait_for("link up")
    run.wait_for("guard: 20 twists sent")  # some commands through first
    os.kill(pid, signal.SIGKILL)
    run.wait_for("process `umbra` ended")
    left = [name for name in os.listdir("/dev/shm") if f"-{pid}-" in name]
    assert left == []  # its /dev/shm files were removed at once, not at the next start
    assert run.finish() == 1, run.text
    assert "failed: process `umbra` died: killed by SIGKILL" in run.text
    out = tmp_path / "out"
    summaries = _summaries(out)
    assert summaries["umbra"]["reason"] == "died: killed by SIGKILL"  # written by the launcher
    assert "process `umbra` died" in summaries["smart"]["reason"]
    assert _ended_order(run)[0] == "umbra"
    assert _ended_order(run).index("smart") < _ended_order(run).index("view")  # servo side first
    twists = _twists(out)
    assert len(twists) > 10
    assert np.all(twists[:-1, 0] > 0)
    np.testing.assert_array_equal(twists[-1], np.zeros(6))  # the guard's last word is zero
    whole = json.loads((out / "summary.json").read_text())
    assert whole["exit_code"] == 1 and "killed by SIGKILL" in whole["reason"]


def test_failing_module_fails_the_run_naming_process_and_cause(
    umbra: Callable[..., Running], tmp_path: Path
) -> None:
    run = umbra("run", _graph(tmp_path, boom_at=60), "--out", "out", "--duration", "60")
    assert run.finish() == 1, run.text
    assert re.search(r"failed: process `view` failed \(exit 1\): .*boom.*boom at 60", run.text)
    assert _ended_order(run) == ["view", "smart", "umbra"]  # servo side before the rest
    np.testing.assert_array_equal(_twists(tmp_path / "out")[-1], np.zeros(6))


def test_interrupt_stops_every_process_cleanly(
    umbra: Callable[..., Running], tmp_path: Path
) -> None:
    run = umbra("run", _graph(tmp_path), "--out", "out", "--duration", "60")
    run.wait_for("link up")
    run.popen.send_signal(signal.SIGINT)
    assert run.finish() == 130, run.text
    assert "interrupted by SIGINT" in run.text
    summaries = _summaries(tmp_path / "out")
    for name, summary in summaries.items():
        assert "interrupted by SIGINT" in summary["reason"], name
    assert _ended_order(run)[0] == "smart"
    np.testing.assert_array_equal(_twists(tmp_path / "out")[-1], np.zeros(6))
