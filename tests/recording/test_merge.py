"""A split run's parts merged into one file; files cut anywhere read back or say why not."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from umbra.connectors.errors import UserError
from umbra.connectors.messages import Image, Scalar, Status, Twist
from umbra.runtime.recording.merge import merge_parts
from umbra.runtime.recording.reader import RecordingScan
from umbra.runtime.recording.samples import iter_samples
from umbra.runtime.recording.writer import RecordingFile


def _part(
    path: Path,
    process: str,
    topic: str,
    times: list[float],
    finish: bool = True,
    compress: bool = True,
) -> None:
    rec = RecordingFile(path, blocking=True, chunk_size=2048, flush_period=0.0, compress=compress)
    rec.add_metadata("umbra.run", {"graph": "g", "process": process, "t0_ns": "1000000000"})
    rec.add_attachment("graph.yaml", "application/yaml", b"graph: g\n")
    rec.write_static_frames([("base", "table", np.eye(4))], times[0])
    for i, t in enumerate(times):
        if topic.endswith("twist"):
            sample = Twist(vector=np.full(6, float(i)), frame="tool", stamp=t, seq=i + 1)
        else:
            sample = Scalar(value=float(i), stamp=t, seq=i + 1)
        rec.offer(topic, sample, t)
    rec.close()
    if not finish:  # a killed process: its data section, without DataEnd, summary and footer
        data = path.read_bytes()
        summary_start = int.from_bytes(data[-8 - 20 : -8 - 12], "little")
        data_end = summary_start - 13  # DataEnd: opcode, length, CRC
        assert data[data_end] == 0x0F
        path.write_bytes(data[:data_end])


def test_a_channel_that_carried_nothing_is_still_in_the_merged_file(tmp_path: Path) -> None:
    """An output nobody sent on (a solver's status that never changed) keeps its channel, with
    its schema, as a single-process recording keeps it."""
    a, b = tmp_path / "rec-umbra.mcap", tmp_path / "rec-smart.mcap"
    _part(a, "umbra", "/servo/twist", [1.0, 1.1])
    rec = RecordingFile(b, blocking=True, chunk_size=2048, flush_period=0.0)
    rec.declare("/kinematics/status", Status, {"umbra.port": "kinematics.status"})
    rec.declare("/joints/value", Scalar, {"umbra.port": "joints.value"})
    rec.offer("/joints/value", Scalar(value=1.0, stamp=1.05, seq=1), 1.05)
    rec.close()
    merge_parts([a, b], tmp_path / "rec.mcap")
    with open(tmp_path / "rec.mcap", "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    channels = {c.topic: c for c in summary.channels.values()}
    assert {"/servo/twist", "/joints/value", "/kinematics/status"} <= set(channels)
    status = channels["/kinematics/status"]
    assert summary.statistics.channel_message_counts.get(status.id, 0) == 0
    assert summary.schemas[status.schema_id].name == "umbra.Status"


def test_parts_merge_in_time_order_with_static_frames_and_attachments_once(
    tmp_path: Path,
) -> None:
    a, b = tmp_path / "rec-umbra.mcap", tmp_path / "rec-smart.mcap"
    _part(a, "umbra", "/servo/twist", [1.0 + i / 30 for i in range(30)])
    _part(b, "smart", "/joints/value", [1.0 + i / 100 for i in range(100)])
    out = tmp_path / "rec.mcap"
    counts = merge_parts([a, b], out)
    assert counts == {"messages": 131, "parts": 2}  # 130 samples and one /tf_static
    with open(out, "rb") as f:
        reader = make_reader(f)
        times = [m.log_time for _s, _c, m in reader.iter_messages(log_time_order=False)]
        summary = reader.get_summary()
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
        attachments = [x.name for x in reader.iter_attachments()]
    assert times == sorted(times)
    topics = sorted(c.topic for c in summary.channels.values())
    assert topics == ["/joints/value", "/servo/twist", "/tf_static"]
    assert attachments == ["graph.yaml"]
    assert meta["umbra.recording"]["written"] == "130" and meta["umbra.recording"]["dropped"] == "0"
    samples = list(iter_samples(out))
    twists = [s.message for s in samples if s.topic == "/servo/twist"]
    assert [t.vector[0] for t in twists] == list(range(30)) and twists[0].frame == "tool"
    assert {c.compression for c in summary.chunk_indexes} == {"lz4"}


def test_parts_written_uncompressed_merge_uncompressed(tmp_path: Path) -> None:
    a, b = tmp_path / "rec-umbra.mcap", tmp_path / "rec-smart.mcap"
    _part(a, "umbra", "/servo/twist", [1.0 + i / 30 for i in range(30)], compress=False)
    _part(b, "smart", "/joints/value", [1.0 + i / 100 for i in range(100)])
    merge_parts([a, b], tmp_path / "rec.mcap")
    with open(tmp_path / "rec.mcap", "rb") as f:
        summary = make_reader(f).get_summary()
    assert {c.compression for c in summary.chunk_indexes} == {""}
    assert summary.statistics.message_count == 131


def test_a_killed_process_part_merges_up_to_its_last_chunk(tmp_path: Path) -> None:
    a, b = tmp_path / "rec-umbra.mcap", tmp_path / "rec-smart.mcap"
    _part(a, "umbra", "/servo/twist", [1.0 + i / 30 for i in range(30)])
    _part(b, "smart", "/joints/value", [1.0 + i / 100 for i in range(100)], finish=False)
    scan = RecordingScan(b)
    assert len(list(iter_samples(b, scan=scan))) == 100 and not scan.finished
    merge_parts([a, b], tmp_path / "rec.mcap")
    with open(tmp_path / "rec.mcap", "rb") as f:
        meta = {m.name: m.metadata for m in make_reader(f).iter_metadata()}
    assert meta["umbra.recording"]["unfinished_parts"] == "rec-smart.mcap"
    assert "dropped" not in meta["umbra.recording"]  # unknown for the killed process


def test_a_file_cut_anywhere_reads_to_its_last_record_or_says_why(tmp_path: Path) -> None:
    whole = tmp_path / "whole.mcap"
    rec = RecordingFile(whole, blocking=True, chunk_size=4096)
    rng = np.random.default_rng(3)
    for i in range(60):
        pixels = rng.integers(0, 256, (16, 24, 3), dtype=np.uint8)
        rec.offer("/cam/image", Image(pixels=pixels, stamp=i / 30, seq=i + 1), i / 30)
        rec.offer("/x/value", Scalar(value=float(i), stamp=i / 30, seq=i + 1), i / 30)
    rec.close()
    data = whole.read_bytes()
    total = len(list(iter_samples(whole)))
    assert total == 120
    before_error = []
    for cut in np.linspace(9, len(data) - 1, 40).astype(int):
        part = tmp_path / "cut.mcap"
        part.write_bytes(data[:cut])
        got = 0
        with pytest.raises(UserError) as err:  # never a traceback, never a silent short read
            for _sample in iter_samples(part):
                got += 1
        assert str(err.value).startswith(f"{part}: error: ")
        assert "truncated" in str(err.value) or "holds no recording" in str(err.value)
        before_error.append(got)
    # the complete chunks before the cut were read: more of the file, more samples
    assert before_error == sorted(before_error) and before_error[-1] >= 100


def test_samples_of_unknown_channels_are_skipped_not_guessed(tmp_path: Path) -> None:
    from mcap.writer import Writer

    path = tmp_path / "foreign.mcap"
    with open(path, "wb") as f:
        w = Writer(f)
        w.start()
        sid = w.register_schema("x", "jsonschema", b'{"type": "object"}')
        cid = w.register_channel("/other", "json", sid)
        w.add_message(cid, 1, b"{}", 1)
        w.finish()
    assert list(iter_samples(path)) == []
    with pytest.raises(UserError, match="holds no umbra samples to replay"):
        from umbra.runtime.recording.replay import RecordingIndex

        RecordingIndex.read(path)
