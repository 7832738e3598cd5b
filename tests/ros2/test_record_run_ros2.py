"""``umbra run --record --record-format ros2``: the run's recording is one that rosbags (and so
``ros2 bag``) reads: ``ros2msg``/``cdr`` channels with the run's samples."""

from __future__ import annotations

import itertools
import json

import pytest
from rosbags.highlevel import AnyReader

from .run_graph import start_run, write_graph


@pytest.mark.slow  # a real run of 1.5 s in a child process
@pytest.mark.timeout(120)
@pytest.mark.parametrize("split", [False, True])
def test_rosbags_reads_a_recorded_run(tmp_path, split):
    graph = write_graph(tmp_path, split=split)
    graph.write_text(graph.read_text() + "record: {ports: {cam.image: jpeg}}\n")
    out = tmp_path / "out"
    proc = start_run(graph, out, "--record-format", "ros2", "--duration", "1.5")
    _, err = proc.communicate(timeout=90)
    assert proc.returncode == 0, err
    frames = json.loads((out / ("summary-vision.json" if split else "summary.json")).read_text())
    sent = next(m for m in frames["modules"] if m["module"] == "cam")["calls"]
    with AnyReader([out / "recording.mcap"]) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        assert types["/cam/image"] == "sensor_msgs/msg/CompressedImage"
        assert types["/cam/truth"] == "geometry_msgs/msg/PolygonStamped"
        images = [
            reader.deserialize(raw, conn.msgtype)
            for conn, _t, raw in reader.messages()
            if conn.topic == "/cam/image"
        ]
    assert len(images) == sent >= 10  # 10 Hz for 1.5 s, every frame
    assert images[0].format == "jpeg" and bytes(images[0].data[:2]) == b"\xff\xd8"
    stamps = [m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in images]
    assert all(b - a == pytest.approx(0.1, abs=0.05) for a, b in itertools.pairwise(stamps))
