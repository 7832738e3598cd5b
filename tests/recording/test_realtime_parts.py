"""A real-time process writes its part of a recording uncompressed: LZ4 compresses a chunk
holding the GIL (another thread waited up to 2.7 ms per MiB), and the servo loop would wait for
it. Other processes compress (real runs, the mcap library's reader on the file)."""

from __future__ import annotations

from pathlib import Path

import pytest
from mcap.reader import make_reader

from umbra.runtime.graph.check import check_text
from umbra.runtime.scheduler import Scheduler, SchedulerOptions

GRAPH = """
graph: parts
clock: sim
duration: 0.5
record: true
processes:
  umbra: {{{umbra}}}
modules:
  count: {{type: Counter, process: umbra, rate: 100}}
  show: {{type: Printer, process: umbra}}
connections:
  - count.count -> show.value
"""


@pytest.mark.parametrize(
    ("umbra", "compression"), [("", "lz4"), ("realtime_priority: 20", "")], ids=["plain", "rt"]
)
def test_a_real_time_process_writes_its_chunks_uncompressed(
    umbra: str, compression: str, tmp_path: Path
) -> None:
    plan = check_text(GRAPH.format(umbra=umbra), "parts.yaml")
    Scheduler(plan, SchedulerOptions(clock="sim", duration=0.5, output_dir=tmp_path)).run()
    with open(tmp_path / "recording.mcap", "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and summary.chunk_indexes
    assert {c.compression for c in summary.chunk_indexes} == {compression}
    assert summary.statistics.channel_message_counts  # the samples are there either way
