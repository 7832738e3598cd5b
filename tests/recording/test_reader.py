"""Reading through the summary: a finished file is indexed without reading its chunks, and only the
chunks holding the wanted channels are read, each checked against its CRC."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.recording.conftest import Run
from umbra.connectors.errors import UserError
from umbra.connectors.messages import Scalar
from umbra.runtime.recording.reader import indexed_scan, read_messages, read_records
from umbra.runtime.recording.replay import RecordingIndex
from umbra.runtime.recording.writer import RecordingFile


def test_a_finished_recording_is_indexed_from_its_summary(pickup_run: Run) -> None:
    scan = indexed_scan(pickup_run.recording)
    assert scan is not None and scan.finished and scan.statistics is not None
    counts: dict[int, int] = {}
    times = []
    for channel, _schema, msg in read_records(pickup_run.recording):
        counts[channel.id] = counts.get(channel.id, 0) + 1
        times.append(msg.log_time)
    assert dict(scan.statistics.channel_message_counts) == counts  # the file read through agrees
    assert (scan.statistics.message_start_time, scan.statistics.message_end_time) == (
        min(times),
        max(times),
    )
    assert scan.messages == len(times) and scan.metadata["umbra.run"]["graph"] == "pickup_small"
    assert "graph.yaml" in scan.attachments and len(scan.chunk_indexes) > 10
    index = RecordingIndex.read(pickup_run.recording)
    assert index.topics["/camera/image"]["count"] == 44
    assert index.end_ns - index.t0_ns == 1_490_000_000  # sim times, on a wall-clock line


def _two_phase(path: Path) -> None:
    """/a/x for 1 s, then /b/y for 1 s, in small chunks: no chunk holds both."""
    rec = RecordingFile(path, blocking=True, chunk_size=2000)
    for i in range(100):
        rec.offer("/a/x", Scalar(value=float(i), stamp=i / 100, seq=i + 1), i / 100)
    for i in range(100):
        rec.offer("/b/y", Scalar(value=-float(i), stamp=1 + i / 100, seq=i + 1), 1 + i / 100)
    rec.close()


def test_only_the_chunks_holding_the_wanted_channels_are_read(tmp_path: Path) -> None:
    path = tmp_path / "two.mcap"
    _two_phase(path)
    scan = indexed_scan(path)
    assert scan is not None
    b_id = next(c.id for c in scan.channels.values() if c.topic == "/b/y")
    b_only = [c for c in scan.chunk_indexes if set(c.message_index_offsets) == {b_id}]
    assert len(b_only) >= 3
    damaged = bytearray(path.read_bytes())
    middle = b_only[1].chunk_start_offset + b_only[1].chunk_length // 2
    damaged[middle] ^= 0xFF  # one bit pattern inside a chunk of /b/y only
    path.write_bytes(bytes(damaged))
    scan = indexed_scan(path)
    assert scan is not None  # the summary is intact: the damage is found when the chunk is read
    values = [m.data for _c, _s, m in read_messages(path, ["/a/x"], scan)]
    assert len(values) == 100
    assert {k: json.loads(values[7])[k] for k in ("stamp", "seq", "value")} == {
        "stamp": 0.07,
        "seq": 8,
        "value": 7.0,
    }
    # /a/x never touches the damaged chunk
    with pytest.raises(UserError) as err:
        sum(1 for _ in read_messages(path, ["/b/y"], scan))
    where = f"the chunk at byte {b_only[1].chunk_start_offset} of {len(damaged)}"
    assert str(err.value).startswith(f"{path}: error: corrupted: ") and where in str(err.value)
    with pytest.raises(UserError, match="corrupted"):  # read through, the file is refused too
        sum(1 for _ in read_records(path))


def test_a_damaged_summary_is_not_trusted(tmp_path: Path) -> None:
    path = tmp_path / "two.mcap"
    _two_phase(path)
    scan = indexed_scan(path)
    assert scan is not None
    data = bytearray(path.read_bytes())
    name = data.rindex(b"umbra.Scalar")  # the schema's name, repeated in the summary section
    data[name + 6] = ord("X")
    path.write_bytes(bytes(data))
    assert indexed_scan(path) is None  # the summary fails its CRC: the file is read through
    index = RecordingIndex.read(path)
    assert index.topics["/a/x"]["count"] == 100 and index.end_ns == 1_990_000_000
