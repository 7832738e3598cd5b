"""The video file written on a thread of its own: what waits, what is dropped, what reads back."""

from __future__ import annotations

import threading
from pathlib import Path

import cv2
import numpy as np
import pytest

from umbra.modules.vision.video import VideoFileError, VideoWriter
from umbra.modules.vision.video_thread import ThreadedVideoWriter


def _frame(i: int) -> np.ndarray:
    frame = np.zeros((120, 160, 3), np.uint8)
    frame[:, :, 1] = 20 * i  # each frame its own shade of green
    return frame


def _read_back(path: Path) -> list[np.ndarray]:
    capture = cv2.VideoCapture(str(path))
    frames = []
    while True:
        ok, frame = capture.read()
        if not ok:
            return frames
        frames.append(frame)


def _held_encoder(monkeypatch: pytest.MonkeyPatch) -> tuple[threading.Event, threading.Event]:
    """The encoder's first write waits for ``release``; ``busy`` is set once it is waiting."""
    busy, release = threading.Event(), threading.Event()
    original = VideoWriter.write

    def slow_write(self: VideoWriter, frame: np.ndarray) -> None:
        busy.set()
        release.wait(5.0)
        original(self, frame)

    monkeypatch.setattr(VideoWriter, "write", slow_write)
    return busy, release


def test_on_the_real_clock_a_frame_the_encoder_cannot_take_is_dropped_and_counted(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    busy, release = _held_encoder(monkeypatch)
    video = ThreadedVideoWriter(tmp_path / "v.avi", 10.0, (160, 120), wait=False, depth=1)
    assert video.write(_frame(1))  # taken by the encoder, which is held
    assert busy.wait(5.0)
    assert video.write(_frame(2))  # waits in the queue
    assert not video.write(_frame(3))  # no room: dropped, the caller not held
    release.set()
    video.close()
    assert (video.frames, video.dropped, video.error) == (2, 1, "")
    shades = [int(f[60, 80, 1]) for f in _read_back(tmp_path / "v.avi")]
    assert len(shades) == 2 and abs(shades[0] - 20) < 8 and abs(shades[1] - 40) < 8


def test_on_the_sim_clock_every_frame_reaches_the_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    busy, release = _held_encoder(monkeypatch)
    video = ThreadedVideoWriter(tmp_path / "v.avi", 10.0, (160, 120), wait=True, depth=1)
    video.write(_frame(1))
    assert busy.wait(5.0)
    video.write(_frame(2))
    threading.Timer(0.2, release.set).start()
    assert video.write(_frame(3))  # waits for room instead of dropping
    for i in range(4, 10):
        video.write(_frame(i))
    video.close()
    assert (video.frames, video.dropped) == (9, 0)
    assert len(_read_back(tmp_path / "v.avi")) == 9


def test_a_frame_of_another_size_is_refused_where_it_is_offered(tmp_path: Path) -> None:
    video = ThreadedVideoWriter(tmp_path / "v.avi", 10.0, (160, 120), wait=True)
    video.write(_frame(1))
    with pytest.raises(VideoFileError, match="160x120x3"):
        video.write(np.zeros((240, 320, 3), np.uint8))
    video.close()
    video.close()  # idempotent
    assert video.frames == 1 and not video.write(_frame(2)) and video.dropped == 1


def test_a_file_that_cannot_be_written_is_refused_at_once(tmp_path: Path) -> None:
    with pytest.raises(VideoFileError, match="must end in"):
        ThreadedVideoWriter(tmp_path / "v.gif", 10.0, (160, 120), wait=True)


def test_a_failing_encoder_counts_what_it_lost_and_never_holds_the_caller(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A full disk: the frames queued behind the failure are counted, later ones refused, and
    closing returns; an encoder thread that died outright holds nobody either."""
    busy, release = _held_encoder(monkeypatch)
    calls = []
    held = VideoWriter.write

    def failing(self: VideoWriter, frame: np.ndarray) -> None:
        calls.append(1)
        if len(calls) >= 2:
            raise OSError("No space left on device")
        held(self, frame)

    monkeypatch.setattr(VideoWriter, "write", failing)
    video = ThreadedVideoWriter(tmp_path / "v.avi", 10.0, (160, 120), wait=True, depth=2)
    video.write(_frame(1))
    assert busy.wait(5.0)
    video.write(_frame(2))  # the disk is full when it comes: lost
    video.write(_frame(3))  # queued behind the failure: lost
    release.set()
    for _ in range(50):
        if video.error:
            break
        threading.Event().wait(0.05)
    assert "No space left on device" in video.error
    assert not video.write(_frame(4))  # refused at once, the sim clock not held
    video.close()
    assert video.frames == 1 and video.dropped == 3  # frames 2, 3 and 4

    class Stop(BaseException):
        pass

    def dies(self: VideoWriter, frame: np.ndarray) -> None:
        raise Stop

    monkeypatch.setattr(VideoWriter, "write", dies)
    monkeypatch.setattr(threading, "excepthook", lambda args: None)  # the thread's end is expected
    dead = ThreadedVideoWriter(tmp_path / "w.avi", 10.0, (160, 120), wait=True, depth=1)
    for i in range(5):  # the first kills the encoder; none of them may wait forever
        dead.write(_frame(i))
    dead.close()
    assert "video encoder stopped" in dead.error and dead.frames == 0


def test_the_encoder_gives_way_under_starvation(tmp_path: Path, monkeypatch) -> None:
    """The encoder's thread runs under SCHED_BATCH at a positive nice: a starved CPU takes its
    frames (counted as dropped), not the vision loop's time."""
    import os

    seen: list[tuple[int, int]] = []
    original = VideoWriter.write

    def noting_write(self: VideoWriter, frame: np.ndarray) -> None:
        tid = threading.get_native_id()
        seen.append((os.sched_getscheduler(tid), os.getpriority(os.PRIO_PROCESS, tid)))
        original(self, frame)

    monkeypatch.setattr(VideoWriter, "write", noting_write)
    writer = ThreadedVideoWriter(tmp_path / "v.avi", 10.0, (160, 120), wait=True)
    writer.write(_frame(1))
    writer.close()
    assert seen == [(os.SCHED_BATCH, 10)]
