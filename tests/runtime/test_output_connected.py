"""An output knows whether the graph wires it to an input: a recording (or a live viewer) adds
sinks to every output, but is nobody a module may count on to act (the console offers *Stop
run* only when a judge of the run listens)."""

from __future__ import annotations

from pathlib import Path

from umbra.runtime.graph.check import check_text
from umbra.runtime.scheduler import Scheduler, SchedulerOptions

GRAPH = """
graph: connected
clock: sim
duration: 0.2
record: true
modules:
  wired: {type: Counter, rate: 20}
  alone: {type: Counter, rate: 20}
  show: {type: Printer}
connections:
  - wired.count -> show.value
"""


def test_a_recorded_output_that_nothing_reads_is_not_connected(tmp_path: Path) -> None:
    plan = check_text(GRAPH, "connected.yaml")
    scheduler = Scheduler(plan, SchedulerOptions(clock="sim", duration=0.2, output_dir=tmp_path))
    wired = scheduler.modules["wired"].outputs["count"]
    alone = scheduler.modules["alone"].outputs["count"]
    assert alone.sinks, "the recording listens to every output"
    assert wired.connected and not alone.connected
    scheduler.run()
    assert (tmp_path / "recording.mcap").stat().st_size > 0
