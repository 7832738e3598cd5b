"""The heap frozen before a real-time loop: what starting made is out of every later collection."""

from __future__ import annotations

import gc
from pathlib import Path

from umbra.runtime.gc_pause import HeapFreeze
from umbra.runtime.graph.check import check_text
from umbra.runtime.scheduler import Scheduler, SchedulerOptions


def test_freezing_moves_what_exists_out_of_the_collector_and_release_gives_it_back() -> None:
    assert gc.get_freeze_count() == 0
    made_before = [[i] for i in range(1000)]  # tracked containers that live for the whole run
    heap = HeapFreeze(enabled=True)
    heap.acquire()
    try:
        assert heap.frozen == gc.get_freeze_count() >= len(made_before)
        cycle: list = []
        cycle.append(cycle)  # garbage made in the loop is still collected
        del cycle
        assert gc.collect() >= 1
    finally:
        heap.release()
    assert gc.get_freeze_count() == 0
    summary = heap.summary()
    assert summary["frozen_objects"] == heap.frozen and summary["collect_ms"] > 0


def test_disabled_it_leaves_the_collector_alone() -> None:
    heap = HeapFreeze(enabled=False)
    heap.acquire()
    assert gc.get_freeze_count() == 0 and heap.frozen == 0
    heap.release()


def test_a_real_clock_run_freezes_its_heap_and_says_so(tmp_path: Path) -> None:
    graph = "graph: g\nclock: real\nmodules:\n  c: {type: Counter, rate: 100}\n"
    plan = check_text(graph, str(tmp_path / "g.yaml"))
    result = Scheduler(
        plan, SchedulerOptions(clock="real", duration=0.05, output_dir=tmp_path)
    ).run()
    assert result.exit_code == 0
    assert result.extra["gc"]["frozen_objects"] > 1000  # the interpreter, numpy, the runtime
    assert gc.get_freeze_count() == 0  # given back when the run ended
    sim = Scheduler(plan, SchedulerOptions(clock="sim", duration=0.05, output_dir=tmp_path)).run()
    assert "gc" not in sim.extra  # nothing is real time on the sim clock
