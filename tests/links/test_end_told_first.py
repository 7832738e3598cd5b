"""The launcher tells the other processes that the run ends before anything slow.

On a loaded machine the launcher is starved: reading every process's memory map under ``/proc``
(to remove a dead process's shared memory) took it 2 s at load 20, reading a 400 KB summary for
its reason 1.7 s more, and the other processes (and the pages they serve) learnt of the run's end
only after both. A process that ends now has the others told first; the sweep and the "ended"
line come after, and the reason is read alone from the summary."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from umbra.runtime import launcher
from umbra.runtime.child_summaries import Child, reason_of
from umbra.runtime.cli.main import main
from umbra.runtime.links.config import Endpoints
from umbra.runtime.links.control_line import ControlCommand

pytestmark = pytest.mark.slow

GRAPH = """
graph: told_first
clock: real
processes: {source: {}, sink: {}, third: {}}
modules:
  counter: {type: Counter, process: source, rate: 50, params: {stop_after: 20}}
  echo: {type: Gain, process: sink, params: {gain: 2.0}}
  last: {type: Gain, process: third, params: {gain: 1.0}}
connections:
  - counter.count -> echo.input
  - echo.output -> last.input
"""


def test_the_others_are_told_before_the_launcher_sweeps_or_says(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    events: list[tuple[str, ...]] = []
    tell, sweep, say = (
        launcher.Supervisor._tell,
        launcher.remove_orphans,
        launcher.Supervisor.say,
    )

    def told(self: launcher.Supervisor, child: Child, command: ControlCommand, *a: object) -> None:
        if child.running and child.told_at is None:
            events.append(("told", child.name, command.value))
        tell(self, child, command, *a)  # type: ignore[arg-type]

    def swept(paths: set[str]) -> int:
        events.append(("swept",))
        return sweep(paths)

    def said(self: launcher.Supervisor, text: str) -> None:
        events.append(("said", text))
        say(self, text)

    monkeypatch.setattr(launcher.Supervisor, "_tell", told)
    monkeypatch.setattr(launcher, "remove_orphans", swept)
    monkeypatch.setattr(launcher.Supervisor, "say", said)
    graph = tmp_path / "told_first.yaml"
    graph.write_text(GRAPH)
    out = tmp_path / "out"
    assert main(["run", str(graph), "--out", str(out), "--duration", "60"]) == 0
    first_end = next(i for i, e in enumerate(events) if e[0] == "swept" or "` ended (" in e[-1])
    told_before = {e[1]: e[2] for e in events[:first_end] if e[0] == "told"}
    assert told_before == {"sink": "finish", "third": "finish"}, events
    whole = json.loads((out / "summary.json").read_text())
    assert whole["reason"] == "process `source` finished: `counter` sent 20 values", whole
    sink = json.loads((out / "summary-sink.json").read_text())
    assert sink["reason"].endswith("`counter` sent 20 values"), sink["reason"]


def test_the_reason_is_read_alone_and_a_broken_summary_falls_back_to_the_last_line(
    tmp_path: Path,
) -> None:
    child = Child("p", Endpoints(), None, False)  # type: ignore[arg-type]
    assert reason_of(tmp_path, child) == "no reason given"  # no summary, no line
    child.tail.append("the last line on stderr")
    assert reason_of(tmp_path, child) == "the last line on stderr"
    (tmp_path / "summary-p.json").write_text('{"process": "p", "reason": ')  # cut short
    assert reason_of(tmp_path, child) == "the last line on stderr"
    (tmp_path / "summary-p.json").write_text('{"reason": 3}')  # not words
    assert reason_of(tmp_path, child) == "the last line on stderr"
    # Python's json writes a measurement that is not a number as NaN, which strict JSON is not
    (tmp_path / "summary-p.json").write_text(
        json.dumps({"process": "p", "reason": "no grasp", "grasp_distance_mm": float("nan")})
    )
    assert reason_of(tmp_path, child) == "no grasp"
    (tmp_path / "summary-p.json").write_text("[1, 2]")  # JSON, not a summary
    assert reason_of(tmp_path, child) == "the last line on stderr"
    records = {"record": [[float(i)] * 6 for i in range(20000)]}
    (tmp_path / "summary-p.json").write_text(
        json.dumps({"process": "p", "reason": "judged", "modules": [records]})
    )
    assert reason_of(tmp_path, child) == "judged"
