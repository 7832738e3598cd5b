"""Image sizes read from the header the decoder will actually use (connectors/image_header.py).

The reference is the decoder itself: OpenCV's libjpeg and libpng decode each small image built or
mutated here, and the size the header reader gave must be the size they decoded (or the reader
refused it). The decoy file is the attack that once passed the 8192-pixel check: its real frame
header hides behind a fill byte, and a naive walk of the segments jumps over it to a small decoy
frame header inside a comment; libjpeg decodes the real one.
"""

from __future__ import annotations

import struct
import zlib
from datetime import timedelta
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from umbra.connectors.image_header import check_image_size, image_size
from umbra.connectors.messages import Image
from umbra.runtime.recording.encoders import compressed_image, decode_primary

#: Where a naive walk of segments lands after taking ``FF FF E1 00`` as a marker and its length.
NAIVE_LANDING = 2 + 2 + 0xE100


def _jpeg(width: int, height: int) -> bytes:
    rng = np.random.default_rng(width * 1000 + height)
    pixels = rng.integers(0, 255, (height, width, 3), dtype=np.uint8)
    ok, buf = cv2.imencode(".jpg", pixels, [cv2.IMWRITE_JPEG_QUALITY, 80])
    assert ok
    return buf.tobytes()


def _segments(jpeg: bytes) -> tuple[list[bytes], bytes]:
    """The marker segments of an encoder's JPEG (no fill bytes) up to SOS, and SOS onwards."""
    out, i = [], 2
    while jpeg[i + 1] != 0xDA:
        length = int.from_bytes(jpeg[i + 2 : i + 4], "big")
        out.append(jpeg[i : i + 2 + length])
        i += 2 + length
    return out, jpeg[i:]


def _with_sof(segments: list[bytes], width: int, height: int) -> list[bytes]:
    """``segments`` with the frame header declaring ``width`` x ``height``."""
    out = []
    for seg in segments:
        if seg[1] == 0xC0:
            seg = seg[:5] + struct.pack(">HH", height, width) + seg[9:]
        out.append(seg)
    return out


def decoy_jpeg(real: tuple[int, int], decoy: tuple[int, int] = (100, 100)) -> bytes:
    """A 120 x 90 JPEG whose frame header declares ``real`` behind a fill byte, with a decoy frame
    header declaring ``decoy`` where a naive walk of the segments lands (inside a comment)."""
    segments, scan = _segments(_jpeg(120, 90))
    head = b"\xff\xd8" + b"\xff" + b"\xff\xe1\x00\x08" + b"decoy!"
    head += b"".join(_with_sof(segments, *real))
    fake_sof = b"\xff\xc0\x00\x11\x08" + struct.pack(">HH", decoy[1], decoy[0]) + bytes(10)
    body_start = len(head) + 4
    pad = NAIVE_LANDING - body_start
    assert pad > 0
    comment = bytes(pad) + fake_sof + bytes(16)
    head += b"\xff\xfe" + struct.pack(">H", len(comment) + 2) + comment
    return head + scan


def _naive_size(data: bytes) -> tuple[int, int]:
    """The walk that once guarded replay: marker and length at fixed places, no fill bytes."""
    i = 2
    while True:
        marker, length = data[i + 1], int.from_bytes(data[i + 2 : i + 4], "big")
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
            return int.from_bytes(data[i + 7 : i + 9], "big"), int.from_bytes(
                data[i + 5 : i + 7], "big"
            )
        i += 2 + length


def _decoded_size(data: bytes) -> tuple[int, int] | None:
    pixels = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    return None if pixels is None else (pixels.shape[1], pixels.shape[0])


def test_the_decoy_fools_a_naive_walk_but_not_the_header_reader() -> None:
    """Real frame 160 x 120 (cheap to decode): libjpeg decodes 160 x 120, the naive walk said
    100 x 100, the header reader says 160 x 120."""
    data = decoy_jpeg(real=(160, 120))
    assert _naive_size(data) == (100, 100)
    assert _decoded_size(data) == (160, 120)
    assert image_size(data) == (160, 120)


def test_a_decoy_hiding_18000_squared_is_refused_before_decoding() -> None:
    data = decoy_jpeg(real=(18000, 18000))
    assert _naive_size(data) == (100, 100)  # what let 6.7 GB frames through
    assert len(data) < 70_000
    with pytest.raises(ValueError, match=r"image declares 18000 x 18000 pixels \(at most 8192"):
        check_image_size(data)
    from umbra.runtime.recording.encoders import CompressedImage

    msg = CompressedImage(data=data, format="jpeg", frame_id="camera").SerializeToString()
    with pytest.raises(ValueError, match="18000 x 18000"):
        decode_primary(Image, "foxglove.CompressedImage", msg, 1)


def test_a_real_recorded_jpeg_and_png_still_decode() -> None:
    pixels = np.random.default_rng(3).integers(0, 255, (48, 64, 3), dtype=np.uint8)
    for fmt in ("jpeg", "png"):
        comp = compressed_image(Image(pixels=pixels, frame="cam", stamp=0.5, seq=1), fmt, 90)
        image = decode_primary(Image, "foxglove.CompressedImage", comp.SerializeToString(), 1)
        assert image.pixels.shape == (48, 64, 3)


def _png(width: int, height: int, before_ihdr: bytes = b"") -> bytes:
    def chunk(kind: bytes, data: bytes) -> bytes:
        return (
            struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
        )

    raw = b"".join(b"\x00" + bytes(width) for _ in range(height))
    return (
        b"\x89PNG\r\n\x1a\n"
        + before_ihdr
        + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0))
        + chunk(b"IDAT", zlib.compress(raw))
        + chunk(b"IEND", b"")
    )


def test_png_sizes_agree_with_the_decoder_and_ihdr_comes_first() -> None:
    assert image_size(_png(33, 21)) == (33, 21) == _decoded_size(_png(33, 21))
    text = (
        struct.pack(">I", 4) + b"tEXt" + b"a\x00bc" + struct.pack(">I", zlib.crc32(b"tEXta\x00bc"))
    )
    hidden = _png(33, 21, before_ihdr=text)
    assert _decoded_size(hidden) is None  # libpng refuses it too
    with pytest.raises(ValueError, match="first chunk is not a 13-byte IHDR"):
        image_size(hidden)


@st.composite
def mutated_jpegs(draw: st.DrawFn) -> bytes:
    """A small real JPEG with fill bytes, junk, comments, stray markers and decoy frame headers
    put between its segments, and maybe a second or a missing frame header."""
    w, h = draw(st.integers(8, 64)), draw(st.integers(8, 64))
    segments, scan = _segments(_jpeg(w, h))
    extras = st.sampled_from(
        [
            b"\xff",
            b"\xff\xff\xff",
            b"\x00\x12junk",
            b"\xff\x00",
            b"\xff\xd0",
            b"\xff\x01",
            b"\xff\xfe\x00\x0dFF\xc0\x00\x11\x08\x40\x00\x40\x00",
            b"\xff\xc8\x00\x04ab",
            b"\xff\xd9",
            b"\xff\xd8",
            b"\xff\xc2\x00\x0b\x08\x10\x00\x10\x00\x01\x01\x11\x00",
        ]
    )
    parts = [b"\xff\xd8"]
    keep = draw(st.lists(st.booleans(), min_size=len(segments), max_size=len(segments)))
    for seg, kept in zip(segments, keep, strict=True):
        parts.append(b"".join(draw(st.lists(extras, max_size=2))))
        if kept or seg[1] != 0xC0:
            parts.append(seg)
    parts.append(b"".join(draw(st.lists(extras, max_size=2))))
    return b"".join(parts) + scan


@settings(max_examples=150, deadline=timedelta(seconds=5), derandomize=True)
@given(mutated_jpegs())
def test_a_size_read_from_a_mutated_jpeg_is_the_size_libjpeg_decodes(data: bytes) -> None:
    """Whatever the header reader says, libjpeg says the same or decodes nothing: never a larger
    image than was checked."""
    try:
        size = image_size(data)
    except ValueError:
        return  # refused: nothing is decoded
    decoded = _decoded_size(data)
    assert decoded is None or decoded == size, (size, decoded)


def test_an_image_file_is_sized_as_its_decoder_reads_it(tmp_path: Path) -> None:
    """``read_image`` (photo backgrounds, snake test images): the decoy hiding 18000 x 18000 is
    refused before decoding; the same decoy hiding 160 x 120 decodes to 160 x 120."""
    from umbra.connectors.errors import UserError
    from umbra.modules.vision.image_file import read_image

    bomb = tmp_path / "bomb.jpg"
    bomb.write_bytes(decoy_jpeg(real=(18000, 18000)))
    with pytest.raises(UserError, match=r"bomb\.jpg: error: image is (too large|18000x18000)"):
        read_image(bomb)
    small = tmp_path / "small.jpg"
    small.write_bytes(decoy_jpeg(real=(160, 120)))
    assert read_image(small).shape == (120, 160, 3)
