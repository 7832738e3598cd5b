"""Two runs of one graph on one host, each served with ``--foxglove``: every tool attaches to its
own run. The runs count from different first values (``counter.start``: 0 and 1 000 000), so a
sample tells which run it came from. One run's processes are slow to build (a module that takes
``SLOW_S`` s to construct, in each process), so its run files appear ``SLOW_S`` s after its live
server listens, while the other run's are there; it is started first or second.

Checked: each live server serves its own run's data and nothing else (read by a Foxglove viewer
connected as soon as the server listens, through the window where the other run alone has run
files); ``umbra echo``/``topics`` with ``--run ID`` attach to that run and say so; without it they
take the newest and say which and how to choose; an unknown ID is refused in one line naming the
runs (exit 2); an observer whose run is killed says so and exits, while the other run goes on."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.links.conftest import Running, start_umbra
from tests.live.fox_collect import FoxCollector
from tests.live.slow_build import plugin_env

# two split runs with their live servers and observers: tens of seconds; real-time runs
pytestmark = [pytest.mark.slow, pytest.mark.timeout(300)]

GRAPH = """
graph: two_runs
clock: real
processes: {umbra: {}, smart: {}}
modules:
  counter: {type: Counter, process: umbra, rate: 50, params: {start: 0}}
  double: {type: Gain, process: smart, params: {gain: 2.0}}
  build_umbra: {type: SlowBuild, process: umbra}
  build_smart: {type: SlowBuild, process: smart}
connections:
  - counter.count -> double.input
  - counter.count -> build_umbra.input
  - double.output -> build_smart.input
"""
#: The counter's first value in the run started second (the first run's starts at 0 and stays
#: far below it).
HIGH = 1_000_000
#: Seconds the slow run's processes take to build (before they write their run files).
SLOW_S = 6.0
COUNT, DOUBLE = "/counter/count", "/double/output"
_URL = re.compile(r"foxglove: open (ws://\S+)")
_PID = re.compile(r"started process `umbra`.*, pid (\d+)")


@pytest.fixture
def env(tmp_path: Path) -> dict[str, str]:
    return plugin_env(tmp_path / "plugin", tmp_path / "xdg")


@pytest.fixture
def launched() -> Iterator[list[Running]]:
    """The commands a test starts: stopped as Ctrl-C stops them, killed if they do not."""
    started: list[Running] = []
    yield started
    for run in started:
        if run.popen.poll() is None:
            run.popen.send_signal(signal.SIGINT)
    for run in started:
        try:
            run.popen.wait(timeout=30)
        except subprocess.TimeoutExpired:
            run.popen.kill()
            run.popen.wait()


def _run(env: dict[str, str], cwd: Path, start: int, slow: bool) -> Running:
    build = SLOW_S if slow else 0.0
    return start_umbra(
        env, cwd, "run", str(cwd / "two_runs.yaml"), "--foxglove", "--foxglove-port", "0",
        "--duration", "120", "--quiet", "--out", str(cwd / f"run-{start}"),
        "--set", f"counter.start={start}",
        "--set", f"build_umbra.build_s={build}", "--set", f"build_smart.build_s={build}",
    )  # fmt: skip


def _umbra(env: dict[str, str], cwd: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "umbra.runtime.cli.main", *args],
        cwd=cwd, env=env, capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL,
    )  # fmt: skip


def _echo_value(env: dict[str, str], cwd: Path, *run: str) -> tuple[float, str]:
    """``umbra echo counter/count --once --json [--run ID]``: the value and what it said."""
    done = _umbra(env, cwd, "echo", "counter/count", "--once", "--json", *run)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.splitlines()[-1])["value"], done.stderr


@pytest.mark.parametrize("slow", ["first", "second"])
def test_each_tool_serves_and_observes_its_own_run(
    slow: str, env: dict[str, str], tmp_path: Path, launched: list[Running]
) -> None:
    (tmp_path / "two_runs.yaml").write_text(GRAPH)
    first = _run(env, tmp_path, 0, slow == "first")
    launched.append(first)
    first_fox = FoxCollector(_URL.search(first.wait_for("foxglove: open", 60))[1], (COUNT, DOUBLE))
    if slow == "second":  # the first run is up and served before the second starts
        first.wait_for("foxglove: parameter changes reach processes", 60)
    second = _run(env, tmp_path, HIGH, slow == "second")
    launched.append(second)
    second_fox = FoxCollector(
        _URL.search(second.wait_for("foxglove: open", 60))[1], (COUNT, DOUBLE)
    )
    try:
        for fox in (first_fox, second_fox):
            fox.wait_count(COUNT, 50, timeout=90)
            fox.wait_count(DOUBLE, 50, timeout=30)
        slow_fox = first_fox if slow == "first" else second_fox
        # the window was there: the slow run's server listened SLOW_S s before its processes
        # wrote their run files, the other run's were there, and it waited for its own
        assert slow_fox.first_arrival() - slow_fox.connected_at > SLOW_S / 2
        first_counts, second_counts = first_fox.values(COUNT), second_fox.values(COUNT)
        assert max(first_counts) < HIGH <= min(second_counts), (
            first_counts[:3],
            second_counts[:3],
        )
        assert max(first_fox.values(DOUBLE)) < HIGH and min(second_fox.values(DOUBLE)) >= 2 * HIGH
    finally:
        first_fox.close()
        second_fox.close()
    first_id = first.wait_for("umbra run: run ID").split()[-1]
    second_id = second.wait_for("umbra run: run ID").split()[-1]
    assert first_id != second_id
    assert f"foxglove: observing run {first_id} " in first.text
    assert f"foxglove: observing run {second_id} " in second.text

    # observers: --run picks either; the default is the newest (the run started second)
    value, said = _echo_value(env, tmp_path, "--run", first_id)
    assert value < HIGH and f"attached to run {first_id} (graph two_runs" in said
    value, said = _echo_value(env, tmp_path, "--run", second_id)
    assert value >= HIGH and f"attached to run {second_id} (" in said
    value, said = _echo_value(env, tmp_path)
    assert value >= HIGH and f"attached to run {second_id} (" in said
    assert len(said.strip().splitlines()) == 1 and "choose one with --run ID" in said
    assert first_id in said  # the other run, named

    topics = _umbra(env, tmp_path, "topics", "--json", "--window", "1")
    assert topics.returncode == 0, topics.stderr
    assert f"* {second_id} (" in topics.stderr and f"  {first_id} (" in topics.stderr
    topics = _umbra(env, tmp_path, "topics", "--json", "--window", "1", "--run", first_id)
    assert topics.returncode == 0 and f"attached to run {first_id} (" in topics.stderr
    assert f"* {first_id} (" in topics.stderr and f"  {second_id} (" in topics.stderr
    rows = [json.loads(line) for line in topics.stdout.splitlines()]
    assert {r["key"] for r in rows} == {
        f"umbra/two_runs/{key}" for key in ("counter/count", "double/output")
    }
    assert all(r["samples"] > 10 for r in rows), rows

    wrong = _umbra(env, tmp_path, "echo", "counter/count", "--run", "nope")
    assert wrong.returncode == 2 and "Traceback" not in wrong.stderr
    (line,) = wrong.stderr.strip().splitlines()
    assert line.startswith("umbra echo: error: --run: expected a run on this host")
    assert "no run `nope`" in line and first_id in line and second_id in line

    # an observer of the first run: when that run is killed, it says so and exits, and never
    # takes the second run's samples meanwhile
    echo = start_umbra(env, tmp_path, "echo", "counter/count", "--json", "--run", first_id)
    launched.append(echo)
    echo.wait_for('"value"', 30)
    os.kill(int(_PID.search(first.wait_for("started process `umbra`"))[1]), signal.SIGKILL)
    assert echo.finish(timeout=30) == 1
    assert f"umbra echo: run {first_id} ended (none of its processes is running)" in echo.text
    echoed = [json.loads(line)["value"] for line in echo.stdout if line.startswith("{")]
    assert echoed and max(echoed) < HIGH
    value, _ = _echo_value(env, tmp_path)  # the second run goes on, alone now
    assert value >= HIGH
