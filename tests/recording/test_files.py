"""Killed runs leave readable files; bad files get ``FILE: error:`` and exit 2; record-info."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from mcap.stream_reader import StreamReader

from tests.poll import wait_for
from tests.recorded import messages_on_disk
from tests.recording.conftest import GRAPH, Run
from umbra.runtime.cli.main import main
from umbra.runtime.recording.reader import RecordingScan, read_records
from umbra.runtime.recording.samples import iter_samples

REPO = Path(__file__).resolve().parents[2]


def _umbra(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "umbra.runtime.cli.main", *args],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=REPO,
    )


@pytest.mark.slow
def test_a_killed_run_leaves_a_file_that_reads_back(tmp_path: Path) -> None:
    out = tmp_path / "run"
    proc = subprocess.Popen(
        [
            *(
                sys.executable,
                "-m",
                "umbra.runtime.cli.main",
                "run",
                str(GRAPH),
                "--single-process",
            ),
            *("--clock", "real", "--duration", "60", "--record", "--out", str(out), "--quiet"),
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        cwd=REPO,
    )
    try:
        path = out / "recording.mcap"
        wait_for(  # chunks reach the disk at least once a second
            lambda: path.exists() and path.stat().st_size > 200_000, 40, "200 kB recorded", 0.1
        )
        wanted = {"/camera/image", "/world/camera_pose", "/kinematics/joint_rates"}
        wait_for(  # the file holds what is read back below before the run is killed
            lambda: (
                (topics := messages_on_disk(path))["/camera/image"] >= 20 and wanted <= set(topics)
            ),
            40,
            "20 images and every topic on disk",
            0.2,
        )
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.wait(timeout=10)
    assert proc.returncode == -signal.SIGKILL
    scan = RecordingScan(path)
    samples = list(iter_samples(path, scan=scan))
    assert not scan.finished  # no footer: the process never got to finish it
    topics = {s.topic for s in samples}
    assert {"/camera/image", "/world/camera_pose", "/kinematics/joint_rates"} <= topics
    images = [s.message for s in samples if s.topic == "/camera/image"]
    assert len(images) >= 20 and images[0].pixels.shape == (480, 640, 3)  # JPEG, decoded
    # mcap's own stream reader reads the same messages up to where the file stops
    with open(path, "rb") as f:
        count = 0
        with pytest.raises(Exception):  # noqa: B017 — it has no footer, mcap says so its way
            for record in StreamReader(f).records:
                count += type(record).__name__ == "Message"
    assert count == scan.messages
    info = _umbra("record-info", str(path))
    assert info.returncode == 0, info.stderr
    assert "NOT FINISHED" in info.stdout and "/camera/image" in info.stdout


def _cli(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    code = main(list(args))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


@pytest.mark.parametrize(
    ("damage", "expected"),
    [
        ("foreign", "not an MCAP file"),
        ("empty", "empty file (0 bytes)"),
        ("truncated", "truncated: the file ends inside a record"),
        ("corrupted", "corrupted:"),
        ("header_only", "holds no recording"),
    ],
)
def test_bad_files_are_refused_with_file_error_and_exit_2(
    pickup_run: Run, tmp_path: Path, capsys: pytest.CaptureFixture[str], damage: str, expected: str
) -> None:
    good = pickup_run.recording.read_bytes()
    bad = tmp_path / f"{damage}.mcap"
    if damage == "foreign":
        bad.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(500))
    elif damage == "empty":
        bad.write_bytes(b"")
    elif damage == "truncated":
        bad.write_bytes(good[: len(good) // 2])
    elif damage == "corrupted":
        data = bytearray(good)
        for i in range(len(data) // 3, len(data) // 3 + 64):  # inside a chunk
            data[i] ^= 0x5A
        bad.write_bytes(bytes(data))
    else:
        bad.write_bytes(good[:8] + good[8 : 8 + 1 + 8 + 4 + 5 + 4 + 5])  # magic + header
        scan_size = len(bad.read_bytes())
        assert scan_size < 64
    replay = ["replay", str(bad), str(GRAPH), "--out", str(tmp_path / "replay"), "--quiet"]
    for command in (["record-info", str(bad)], replay):
        code, out, err = _cli(capsys, *command)
        assert code == 2, (command, out, err)
        (line,) = [x for x in err.splitlines() if x.startswith(f"{bad}: error: ")]
        assert expected in line and "Traceback" not in err
    # a finished file is indexed from its summary: a damaged chunk is found when replay reaches
    # it (the samples before it were replayed); any other damage is refused before anything runs
    ran = (tmp_path / "replay" / "summary.json").exists()
    assert ran == (damage == "corrupted")
    if ran:
        summary = json.loads((tmp_path / "replay" / "summary.json").read_text())
        assert summary["exit_code"] == 2 and summary["reason"].startswith(f"{bad}: error: corr")
        camera = next(m for m in summary["modules"] if m["module"] == "camera")
        assert 0 < camera["sent"] < 45 + 45  # some images and truth contours, not all of them


def test_header_only_file_is_what_the_test_thinks(pickup_run: Run) -> None:
    """The header-only case above really is the magic and a header record (its length checked)."""
    good = pickup_run.recording.read_bytes()
    length = int.from_bytes(good[9:17], "little")
    assert good[8] == 0x01 and length < 64  # opcode Header, a short profile and library


def test_record_info_lists_channels_rates_gaps_drops_and_duration(
    pickup_run: Run, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, _err = _cli(capsys, "record-info", str(pickup_run.recording), "--json")
    assert code == 0
    info = json.loads(out)
    assert info["finished"] and info["dropped"] == 0
    assert info["duration_s"] == pytest.approx(1.49, abs=1e-9)  # 100 Hz ticks from 0 to 1.49 s
    channels = {c["topic"]: c for c in info["channels"]}
    image = channels["/camera/image"]
    assert image["count"] == 44 and image["rate_hz"] == pytest.approx(30.0, rel=1e-6)
    assert image["gaps"] == 0 and image["max_gap"] == pytest.approx(1 / 30, abs=1e-6)
    assert channels["/kinematics/joint_rates"]["rate_hz"] == pytest.approx(100.0, rel=0.01)
    assert channels["/snake/contour/annotations"]["role"] == "view"
    code, out, _err = _cli(capsys, "record-info", str(pickup_run.recording))
    assert code == 0 and "/camera/image" in out and "foxglove.RawImage" in out


def test_record_info_counts_a_gap(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from umbra.connectors.messages import Scalar
    from umbra.runtime.recording.writer import RecordingFile

    rec = RecordingFile(tmp_path / "gap.mcap", blocking=True)
    times = [i * 0.01 for i in range(50)] + [1.0 + i * 0.01 for i in range(50)]  # 0.5 s hole
    for i, t in enumerate(times):
        rec.offer("/x/value", Scalar(value=float(i), stamp=t, seq=i + 1), t)
    rec.close()
    code, out, _err = _cli(capsys, "record-info", str(tmp_path / "gap.mcap"), "--json")
    (ch,) = json.loads(out)["channels"]
    assert code == 0 and ch["gaps"] == 1 and ch["max_gap"] == pytest.approx(0.51)
    assert [s.message.value for s in iter_samples(tmp_path / "gap.mcap")] == list(range(100))
    assert sum(1 for _ in read_records(tmp_path / "gap.mcap")) == 100
