"""DigiCam opens what OpenCV opens: image sequences and still images written by the test, device
indices written as YAML integers, device paths, stream URLs; every failure names its cause and
exits 2; no source makes a run outlast ``--duration`` (sim clock included)."""

from __future__ import annotations

import contextlib
import json
import select
import socket
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from tests.poll import wait_for
from umbra.connectors import UserError
from umbra.modules.vision.capture_source import CaptureSource, probe_stream
from umbra.modules.vision.digicam import DigiCam
from umbra.runtime.harness import ModuleHarness


def level(sample) -> int:
    return round(float(np.median(sample.pixels[:, :, 1])) / 20.0)


def write_sequence(folder: Path, first: int, count: int) -> str:
    folder.mkdir(exist_ok=True)
    for k in range(first, first + count):
        frame = np.zeros((48, 64, 3), dtype=np.uint8)
        frame[:, :, 1] = 20 * k
        assert cv2.imwrite(str(folder / f"img_{k:04d}.png"), frame)
    return str(folder / "img_%04d.png")


def images(h: ModuleHarness, steps: int, dt: float = 0.1) -> list:
    sent = []
    for _ in range(steps):
        sent.extend(h.step(dt).get("image", []))
    return sent


def free_loopback_port() -> int:
    """A loopback TCP port nobody listens on (bound, then closed)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def run_graph(tmp_path: Path, source: str, *extra: str, timeout: float = 90):
    graph = tmp_path / "cam.yaml"
    graph.write_text(
        "graph: cam\nclock: sim\nmodules:\n"
        f"  cam: {{type: DigiCam, rate: 10, params: {{source: {source}, open_timeout: 1}}}}\n"
    )
    started = time.monotonic()
    out = str(tmp_path / "o")
    done = subprocess.run(
        [sys.executable, "-m", "umbra.runtime.cli.main", "run", str(graph), "--out", out, *extra],
        capture_output=True,
        text=True,
        timeout=timeout,
    )
    return done, time.monotonic() - started


@pytest.mark.parametrize("first", [0, 1, 4])
def test_an_image_sequence_plays_in_order_and_loops(tmp_path: Path, first: int) -> None:
    pattern = write_sequence(tmp_path / "imgs", first, 3)
    assert CaptureSource.parse(pattern).kind == "sequence"
    with ModuleHarness(DigiCam, {"source": pattern}) as h:
        sent = images(h, 7)
    assert [level(s) for s in sent] == [first, first + 1, first + 2] * 2 + [first]
    assert sent[0].pixels.shape == (48, 64, 3)


def test_a_sequence_without_its_first_image_is_not_found(tmp_path: Path) -> None:
    pattern = write_sequence(tmp_path / "imgs", 7, 2)  # OpenCV starts at 0..4 only
    with pytest.raises(UserError, match=r"image sequence .* not found \(no .*img_0000\.png"):
        ModuleHarness(DigiCam, {"source": pattern})


def test_a_still_image_is_sent_at_every_step(tmp_path: Path) -> None:
    path = tmp_path / "still.png"
    frame = np.zeros((30, 40, 3), dtype=np.uint8)
    frame[:, :, 1] = 100
    assert cv2.imwrite(str(path), frame)
    with ModuleHarness(DigiCam, {"source": str(path), "stale_after": 0.5}) as h:
        sent = images(h, 20)
    assert len(sent) == 20 and all(level(s) == 5 and not s.stale for s in sent)
    assert [s.stamp for s in sent] == pytest.approx([0.1 * (k + 1) for k in range(20)])


def test_an_image_that_does_not_decode_says_so(tmp_path: Path) -> None:
    path = tmp_path / "broken.png"
    path.write_bytes(b"\x89PNG but not really")
    with pytest.raises(UserError, match="cannot decode"):
        ModuleHarness(DigiCam, {"source": str(path)}).start()


def test_a_device_path_that_does_not_exist_is_not_found() -> None:
    with pytest.raises(UserError, match=r"camera device /dev/video97 not found"):
        ModuleHarness(DigiCam, {"source": "/dev/video97"}).start()


def test_a_refused_stream_names_the_refusal() -> None:
    port = free_loopback_port()
    url = f"http://127.0.0.1:{port}/video.mjpg"
    assert "connection refused by 127.0.0.1" in probe_stream(url, 1.0)
    with pytest.raises(UserError, match=f"stream {url}: connection refused") as caught:
        ModuleHarness(DigiCam, {"source": url, "open_timeout": 1.0}).start()
    assert "cannot decode" not in str(caught.value)


def test_a_stream_whose_host_never_answers_times_out() -> None:
    """A loopback listener whose accept queue is full drops new connection requests: the probe
    waits ``open_timeout`` and says it timed out."""
    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen(0)
        port = server.getsockname()[1]
        queued = [socket.socket() for _ in range(4)]
        for client in queued:
            client.setblocking(False)
            with contextlib.suppress(BlockingIOError):
                client.connect(("127.0.0.1", port))

        def queue_full() -> bool:  # a queued handshake completed: the one place is taken
            _, done, _ = select.select([], queued, [], 0)
            return any(c.getsockopt(socket.SOL_SOCKET, socket.SO_ERROR) == 0 for c in done)

        wait_for(queue_full, 10.0, "a queued connection (the accept queue full)")
        url = f"rtsp://127.0.0.1:{port}/cam"
        started = time.monotonic()
        with pytest.raises(
            UserError, match=f"stream {url}: connection to .* timed out after 0.5 s"
        ):
            ModuleHarness(DigiCam, {"source": url, "open_timeout": 0.5}).start()
        assert 0.45 < time.monotonic() - started < 5.0
        for client in queued:
            client.close()


def test_a_stream_that_accepts_but_sends_no_video_cannot_be_decoded() -> None:
    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen()
        port = server.getsockname()[1]
        url = f"tcp://127.0.0.1:{port}"
        assert probe_stream(url, 1.0) == ""
        with pytest.raises(UserError, match=r"cannot decode|delivered no frame"):
            ModuleHarness(DigiCam, {"source": url, "open_timeout": 1.0}).start()


def test_a_device_index_written_as_a_yaml_integer_is_a_device(tmp_path: Path) -> None:
    done, _ = run_graph(tmp_path, "7")
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert "valid string" not in done.stderr
    assert "cannot open camera device 7" in done.stderr  # no camera 7 here: refused at start
    checked = subprocess.run(
        [sys.executable, "-m", "umbra.runtime.cli.main", "check", str(tmp_path / "cam.yaml")],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert checked.returncode == 0, checked.stderr


def test_a_refused_stream_in_a_run_exits_2(tmp_path: Path) -> None:
    port = free_loopback_port()
    done, _ = run_graph(tmp_path, f"'http://127.0.0.1:{port}/cam'")
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert "connection refused" in done.stderr


@pytest.mark.parametrize("kind", ["still", "one-image sequence"])
def test_a_sim_clock_run_on_a_single_image_ends_at_its_duration(tmp_path: Path, kind: str) -> None:
    frame = np.full((24, 32, 3), 90, dtype=np.uint8)
    if kind == "still":
        source = tmp_path / "still.jpg"
        assert cv2.imwrite(str(source), frame)
    else:
        assert cv2.imwrite(str(tmp_path / "one_0000.png"), frame)
        source = tmp_path / "one_%04d.png"
    done, seconds = run_graph(tmp_path, f"'{source}'", "--duration", "3")
    assert done.returncode == 0, done.stderr
    summaries = list((tmp_path / "o").glob("summary*.json"))
    cam = next(m for m in json.loads(summaries[0].read_text())["modules"] if m["module"] == "cam")
    assert cam["calls"] >= 30  # 10 Hz for 3 s of sim time
    assert seconds < 60
