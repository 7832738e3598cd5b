"""Decompression bombs and lying headers in recordings: refused before they are inflated.

The files are written here, byte by byte (tests/hostile/bombs.py): a 98 kB zstd chunk that inflates
to 3.2 GB and a 13 MB LZ4 one that inflates to 3.4 GB, each either declaring its real size in the
chunk header or a small one (the lie is found when inflation passes the declared size), with and
without a summary (``record-info`` reads a file through, ``replay`` reads the chunks its index
points at). The real ``umbra`` CLI runs in a child process whose peak memory is read from the
kernel (``wait4``) and compared with the same command on a valid recording of the same shape.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import lz4.frame
import pytest
import zstandard

from tests.hostile.bombs import (
    CAMERA,
    CAMERA_TRUTH,
    LZ4_BLOCK,
    MAGIC,
    ZSTD_BLOCK,
    chunk_payload,
    crc,
    lz4_zero_frame,
    mcap_bytes,
    zstd_rle_frame,
)
from umbra.connectors.errors import UserError
from umbra.connectors.limits import MAX_RECORDING_RECORD_BYTES
from umbra.runtime.recording.chunks import inflate
from umbra.runtime.recording.reader import indexed_scan, read_messages, read_records

# whole runs of umbra in subprocesses, seconds each: in CI with -m slow (a short default run)
pytestmark = [pytest.mark.slow, pytest.mark.untimed]

REPO = Path(__file__).resolve().parents[2]
GRAPH = REPO / "tests" / "recording" / "pickup_small.yaml"
#: A 98 kB zstd frame of RLE blocks: 3.2 GB of zeros.
ZSTD_TOTAL = 98_000 // 4 * ZSTD_BLOCK
#: A 13 MB LZ4 frame: 800 blocks of 4 MiB zeros (3.4 GB).
LZ4_BLOCKS = 800
#: Peak memory a refused bomb may add to the same command on a valid recording [bytes].
MEMORY_ALLOWANCE = 64 * 1024 * 1024


def test_the_hand_made_frames_are_what_the_real_decompressors_read() -> None:
    """Small versions of the bombs through zstandard and lz4 themselves: the builders are right."""
    small = zstd_rle_frame(3 * ZSTD_BLOCK + 17)
    assert zstandard.ZstdDecompressor().decompressobj().decompress(small) == bytes(
        3 * ZSTD_BLOCK + 17
    )
    assert lz4.frame.decompress(lz4_zero_frame(3)) == bytes(3 * LZ4_BLOCK)
    assert len(zstd_rle_frame(ZSTD_TOTAL)) < 100_000 and ZSTD_TOTAL > 3e9
    assert len(lz4_zero_frame(LZ4_BLOCKS)) < 14_000_000


@pytest.mark.parametrize("compression", ["", "zstd", "lz4"])
@pytest.mark.parametrize("indexed", [False, True])
def test_valid_chunks_of_every_compression_read_back(
    compression: str, indexed: bool, tmp_path: Path
) -> None:
    payload = chunk_payload(10)
    data = {"": payload, "zstd": zstandard.compress(payload), "lz4": lz4.frame.compress(payload)}
    path = tmp_path / "ok.mcap"
    path.write_bytes(
        mcap_bytes(compression, data[compression], len(payload), indexed, crc(payload))
    )
    assert [m.sequence for _c, _s, m in read_records(path)] == list(range(1, 11))
    scan = indexed_scan(path)
    assert (scan is not None) == indexed
    assert [m.log_time for _c, _s, m in read_messages(path, None, scan)][-1] == 9_000_000


def _bombs() -> dict[str, tuple[str, bytes, int]]:
    """name -> (compression, data, declared uncompressed size)."""
    z, lz = zstd_rle_frame(ZSTD_TOTAL), lz4_zero_frame(LZ4_BLOCKS)
    return {
        "zstd-honest": ("zstd", z, ZSTD_TOTAL),
        "zstd-lying": ("zstd", z, 5000),
        "lz4-honest": ("lz4", lz, LZ4_BLOCKS * LZ4_BLOCK),
        "lz4-lying": ("lz4", lz, 5000),
        "stored-lying": ("", bytes(20_000), 5000),
    }


@pytest.mark.parametrize("name", list(_bombs()))
def test_inflation_stops_at_the_declared_size(name: str) -> None:
    from mcap.records import Chunk

    compression, data, declared = _bombs()[name]
    chunk = Chunk(compression, data, 0, 0, 0, declared)
    with pytest.raises(ValueError) as err:
        inflate(chunk)
    text = str(err.value)
    if declared > MAX_RECORDING_RECORD_BYTES:
        assert f"declares {declared} bytes uncompressed, more than the" in text
    else:
        assert "declares 5000 bytes uncompressed but holds more" in text


def _run_measured(argv: list[str], cwd: Path) -> tuple[int, str, int]:
    """(exit status, stderr, peak resident memory in bytes) of ``umbra ARGV`` in a child, read
    from the kernel's accounting of that child alone (``wait4``)."""
    err_path = cwd / "stderr.txt"
    with open(err_path, "wb") as err:
        pid = os.posix_spawn(
            sys.executable,
            [sys.executable, "-m", "umbra.runtime.cli.main", *argv],
            {**os.environ, "PYTHONPATH": str(REPO)},
            file_actions=[
                (os.POSIX_SPAWN_OPEN, 0, "/dev/null", os.O_RDONLY, 0),
                (os.POSIX_SPAWN_OPEN, 1, "/dev/null", os.O_WRONLY, 0),
                (os.POSIX_SPAWN_DUP2, err.fileno(), 2),
            ],
        )
        _pid, status, usage = os.wait4(pid, 0)
    return (
        os.waitstatus_to_exitcode(status),
        err_path.read_text(errors="replace"),
        (usage.ru_maxrss * 1024),
    )


def _camera_frames(frames: int) -> bytes:
    """Chunk records: ``frames`` real 640 x 480 JPEG camera images on channel 1, 33 ms apart."""
    import cv2
    import numpy as np
    from mcap.data_stream import RecordBuilder
    from mcap.records import Message

    from umbra.runtime.recording.encoders import CompressedImage

    pixels = np.random.default_rng(2).integers(0, 255, (480, 640, 3), dtype=np.uint8)
    jpeg = cv2.imencode(".jpg", pixels)[1].tobytes()
    data = CompressedImage(data=jpeg, format="jpeg", frame_id="camera").SerializeToString()
    b = RecordBuilder()
    for i in range(frames):
        t = i * 33_000_000
        Message(channel_id=1, sequence=i + 1, log_time=t, publish_time=t, data=data).write(b)
    return b.end()


@pytest.fixture(scope="module")
def baseline_rss(tmp_path_factory: pytest.TempPathFactory) -> dict[str, int]:
    """Peak memory [bytes] of each command on a valid recording of the same shape (the camera's
    channels, one LZ4 chunk of three real JPEG frames)."""
    folder = tmp_path_factory.mktemp("baseline")
    payload = _camera_frames(3)
    path = folder / "ok.mcap"
    path.write_bytes(
        mcap_bytes(
            "lz4",
            lz4.frame.compress(payload),
            len(payload),
            True,
            crc(payload),
            channels=[CAMERA, CAMERA_TRUTH],
        )
    )
    status, err, info_peak = _run_measured(["record-info", str(path)], folder)
    assert status == 0, err
    argv = ["replay", str(path), str(GRAPH), "--out", str(folder / "out"), "--quiet"]
    _status, _err, replay_peak = _run_measured(argv, folder)  # it runs: its exit is not the point
    return {"record-info": info_peak, "replay": replay_peak}


@pytest.mark.timeout(300)
@pytest.mark.parametrize("name", [n for n in _bombs() if n != "stored-lying"])
@pytest.mark.parametrize("indexed", [False, True])
def test_record_info_and_replay_refuse_a_bomb_with_small_memory(
    name: str, indexed: bool, tmp_path: Path, baseline_rss: dict[str, int]
) -> None:
    compression, data, declared = _bombs()[name]
    path = tmp_path / "bomb.mcap"
    path.write_bytes(
        mcap_bytes(compression, data, declared, indexed, channels=[CAMERA, CAMERA_TRUTH])
    )
    commands = {
        "record-info": ["record-info", str(path)],
        "replay": ["replay", str(path), str(GRAPH), "--out", str(tmp_path / "out"), "--quiet"],
    }
    for command, argv in commands.items():
        status, err, peak = _run_measured(argv, tmp_path)
        assert status == 2, (command, err)
        assert "Traceback" not in err, err
        assert f"{path}: error: corrupted: " in err and "declares" in err, (command, err)
        base = baseline_rss[command]
        assert peak < base + MEMORY_ALLOWANCE, (command, peak / 1e6, base / 1e6)


@pytest.mark.parametrize("claims", [2**40, 2**64 - 1, MAX_RECORDING_RECORD_BYTES + 1])
def test_a_record_longer_than_the_limit_is_a_file_error(claims: int, tmp_path: Path) -> None:
    """The record after the header claims ``claims`` bytes: a FILE error, never the library's
    exception (which once escaped as an AttributeError traceback)."""
    good = mcap_bytes("", chunk_payload(1), len(chunk_payload(1)))
    head_end = len(MAGIC) + 9 + int.from_bytes(good[len(MAGIC) + 1 : len(MAGIC) + 9], "little")
    bad = good[:head_end] + bytes([0x03]) + claims.to_bytes(8, "little") + bytes(64)
    path = tmp_path / "long.mcap"
    path.write_bytes(bad)
    with pytest.raises(UserError) as err:
        list(read_records(path))
    assert str(err.value) == (
        f"{path}: error: corrupted: the record at byte {head_end} of {len(bad)} claims {claims} "
        f"bytes, more than the {MAX_RECORDING_RECORD_BYTES} a recording's record may hold "
        "(after 0 messages)"
    )
    status, stderr, _peak = _run_measured(["record-info", str(path)], tmp_path)
    assert status == 2 and "Traceback" not in stderr and stderr.startswith(f"{path}: error: ")


def test_a_record_running_past_the_end_is_truncated(tmp_path: Path) -> None:
    good = mcap_bytes("", chunk_payload(1), len(chunk_payload(1)))
    head_end = len(MAGIC) + 9 + int.from_bytes(good[len(MAGIC) + 1 : len(MAGIC) + 9], "little")
    bad = good[:head_end] + bytes([0x03]) + (10_000).to_bytes(8, "little") + bytes(64)
    path = tmp_path / "cut.mcap"
    path.write_bytes(bad)
    with pytest.raises(UserError, match=r"error: truncated: the file ends inside a record"):
        list(read_records(path))


def test_a_chunk_of_zeros_is_refused_at_its_first_record(tmp_path: Path) -> None:
    """A chunk whose header is honest but whose bytes are no records (zeros: opcode 0, length 0,
    which a reader skipping unknown records would walk 9 bytes at a time) is refused at once."""
    path = tmp_path / "zeros.mcap"
    path.write_bytes(mcap_bytes("zstd", zstd_rle_frame(1 << 20), 1 << 20))
    with pytest.raises(UserError) as err:
        list(read_records(path))
    assert "a record with opcode 0x00 at byte 0 of a chunk, which holds only schemas" in str(
        err.value
    )


def test_private_records_in_a_chunk_are_skipped(tmp_path: Path) -> None:
    payload = chunk_payload(2)
    private = bytes([0x80]) + (5).to_bytes(8, "little") + b"hello"
    data = private + payload
    path = tmp_path / "private.mcap"
    path.write_bytes(mcap_bytes("", data, len(data), crc=crc(data)))
    assert [m.sequence for _c, _s, m in read_records(path)] == [1, 2]


def test_replay_refuses_a_decoy_jpeg_before_decoding_it(
    tmp_path: Path, baseline_rss: dict[str, int]
) -> None:
    """A recorded camera frame whose real JPEG frame header (18000 x 18000, 6.7 GB decoded)
    hides behind a fill byte: ``umbra replay`` says so and exits 2, at a valid file's memory."""
    from mcap.data_stream import RecordBuilder
    from mcap.records import Message

    from tests.hostile.test_image_headers import decoy_jpeg
    from umbra.runtime.recording.encoders import CompressedImage

    frame = CompressedImage(data=decoy_jpeg(real=(18000, 18000)), format="jpeg", frame_id="camera")
    b = RecordBuilder()
    for i in range(3):
        Message(
            channel_id=1,
            sequence=i + 1,
            log_time=i * 33_000_000,
            publish_time=i * 33_000_000,
            data=frame.SerializeToString(),
        ).write(b)
    payload = b.end()
    path = tmp_path / "decoy.mcap"
    path.write_bytes(
        mcap_bytes("", payload, len(payload), True, crc(payload), channels=[CAMERA, CAMERA_TRUTH])
    )
    argv = ["replay", str(path), str(GRAPH), "--out", str(tmp_path / "out"), "--quiet"]
    status, err, peak = _run_measured(argv, tmp_path)
    assert status == 2 and "Traceback" not in err, err
    assert f"{path}: error: message 1 on `/camera/image`" in err
    assert "image declares 18000 x 18000 pixels (at most 8192 a side" in err
    assert peak < baseline_rss["replay"] + MEMORY_ALLOWANCE, (peak / 1e6, baseline_rss)
