"""The recorder's queue: bounded, drops and counts on the real clock, waits on the sim clock."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from mcap.reader import make_reader

from umbra.connectors.messages import Image
from umbra.runtime.recording.samples import iter_samples
from umbra.runtime.recording.writer import RecordingFile

FRAME = np.zeros((120, 160, 3), np.uint8)  # 58 kB


def _burst(path: Path, blocking: bool, n: int = 100) -> tuple[RecordingFile, list[bool]]:
    rec = RecordingFile(path, blocking=blocking, max_items=1000, max_bytes=2 * FRAME.nbytes)
    taken = [
        rec.offer("/cam/image", Image(pixels=FRAME, stamp=i / 30, seq=i + 1), i / 30)
        for i in range(n)
    ]
    rec.close()
    return rec, taken


def test_a_full_queue_drops_and_counts_on_the_real_clock(tmp_path: Path) -> None:
    rec, taken = _burst(tmp_path / "real.mcap", blocking=False)
    dropped = taken.count(False)
    assert dropped > 0 and rec.dropped == dropped and rec.written == taken.count(True)
    with open(tmp_path / "real.mcap", "rb") as f:
        reader = make_reader(f)
        stats = next(m for m in reader.iter_metadata() if m.name == "umbra.recording").metadata
        count = reader.get_summary().statistics.message_count
    assert stats["dropped"] == str(dropped) and stats["dropped:/cam/image"] == str(dropped)
    assert count == rec.written  # what was not dropped is all in the file
    seqs = [s.message.seq for s in iter_samples(tmp_path / "real.mcap")]
    assert seqs == sorted(seqs) and len(seqs) == rec.written


def test_the_sim_clock_waits_for_room_and_keeps_every_sample(tmp_path: Path) -> None:
    rec, taken = _burst(tmp_path / "sim.mcap", blocking=True)
    assert all(taken) and rec.dropped == 0 and rec.written == 100
    assert [s.message.seq for s in iter_samples(tmp_path / "sim.mcap")] == list(range(1, 101))


def test_a_frame_given_a_second_parent_is_said_once(tmp_path: Path, caplog) -> None:
    """A viewer keeps one parent per frame: the recorder says which frame got two, and where."""
    import logging

    from umbra.connectors.messages import Pose, Poses

    rec = RecordingFile(tmp_path / "tree.mcap", blocking=True)
    rec.write_static_frames([("base", "table", np.eye(4)), ("link2", "link3", np.eye(4))], 0.0)
    links = Poses(matrices=np.stack([np.eye(4)] * 2), children=("link2", "link3"), frame="base")
    with caplog.at_level(logging.WARNING, logger="umbra.record"):
        for i in range(3):
            rec.offer("/kin/links", links, 0.01 * i)  # a chain: link3 in link2, as static: fine
            rec.offer("/world/table", Pose(matrix=np.eye(4), parent="room", child="table"), 0.01)
        rec.offer("/kin/other", Poses(matrices=np.eye(4)[None], children=("link2",), frame="x"), 1)
        rec.close()
    said = [r.getMessage() for r in caplog.records if "two parents" in r.getMessage()]
    assert len(said) == 2, said
    assert "frame `table` has two parents, `base` (/tf_static) and `room` (/world/table)" in said[0]
    assert "frame `link2` has two parents, `base` (/kin/links) and `x` (/kin/other)" in said[1]
