"""A viewer that does not keep up: its backlog drops a channel's own old frames first, then the
oldest of the channel holding the most bytes, so every channel keeps its newest frame (a real
``_Viewer``; the socket is not needed to fill and drain its backlog)."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

from umbra.runtime.live.viewer_server import (
    MAX_VIEWER_BACKLOG,
    MAX_VIEWER_BACKLOG_BYTES,
    _Viewer,
)

IMAGE, CONTOUR, JOINTS = 1, 2, 3


def _viewer() -> _Viewer:
    conn: Any = SimpleNamespace(remote_address=("127.0.0.1", 5))
    return _Viewer(conn, 1)


def _held(viewer: _Viewer) -> list[int]:
    return [channel for channel, _f in viewer.data]


def test_images_give_way_and_every_channel_keeps_its_newest_frame() -> None:
    viewer = _viewer()
    image = bytes(MAX_VIEWER_BACKLOG_BYTES // 4)
    viewer.push_data(CONTOUR, b"contour-0")
    for k in range(50):  # a video and 100 Hz joints arrive; nothing is read
        viewer.push_data(IMAGE, image)
        viewer.push_data(JOINTS, f"joints-{k}".encode())
        viewer.push_data(JOINTS, f"joints-{k}b".encode())
    held = _held(viewer)
    assert CONTOUR in held  # the rare channel's frame is still there
    assert held.count(JOINTS) >= 1 and held.count(IMAGE) >= 1
    assert viewer.data_bytes <= MAX_VIEWER_BACKLOG_BYTES
    assert len(viewer.data) <= MAX_VIEWER_BACKLOG
    assert viewer.dropped > 0
    newest_joints = [f for c, f in viewer.data if c == JOINTS][-1]
    assert newest_joints == b"joints-49b"  # a stream replaces its own old frames


def test_many_small_channels_beside_a_busy_one_each_keep_a_frame() -> None:
    viewer = _viewer()
    for k in range(MAX_VIEWER_BACKLOG * 3):
        viewer.push_data(100, f"busy-{k}".encode())  # a busy channel fills the backlog
        if k % 20 == 0:
            viewer.push_data(200 + k // 20, b"rare")
    rare = {c for c in _held(viewer) if c >= 200}
    assert rare == {200 + k // 20 for k in range(0, MAX_VIEWER_BACKLOG * 3, 20)}
