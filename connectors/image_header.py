"""The size of a PNG or JPEG image as its decoder will see it, read from its header undecoded.

A size check is only as good as its agreement with the decoder: a JPEG whose real frame header
(SOF) hides behind fill bytes (``FF FF C0``), garbage between segments or a decoy SOF inside a
comment must not pass as small while libjpeg decodes 18000 x 18000 pixels. So the markers are
walked exactly as libjpeg's ``read_markers`` walks them (``jdmarker.c``): bytes up to the next
``0xFF`` are skipped, any run of ``0xFF`` fill bytes is skipped, ``FF 00`` is no marker, the first
SOFn of any kind gives the size, a second SOFn, an SOS before any SOF, a second SOI, an EOI and a
marker libjpeg does not know are all refused (libjpeg refuses them too). A PNG's first chunk must
be its IHDR, as libpng requires. Anything else is refused: no other format reaches the decoder.
"""

from __future__ import annotations

from umbra.connectors.limits import MAX_IMAGE_PIXELS, MAX_IMAGE_SIDE_PX

_PNG = b"\x89PNG\r\n\x1a\n"
#: Start-of-frame markers of every coding process (baseline ... lossless, arithmetic).
_SOF = frozenset({0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF})
#: Markers with a length-prefixed segment libjpeg reads or skips (DHT, DAC, DQT, DNL, DRI, APPn,
#: COM).
_SEGMENTS = frozenset({0xC4, 0xCC, 0xDB, 0xDC, 0xDD, *range(0xE0, 0xF0), 0xFE})
#: Markers without a segment (RSTn, TEM).
_BARE = frozenset({*range(0xD0, 0xD8), 0x01})
_SOI, _EOI, _SOS = 0xD8, 0xD9, 0xDA


def image_size(data: bytes) -> tuple[int, int]:
    """``(width, height)`` [px] a PNG or JPEG declares to its decoder; ValueError when the bytes
    are neither, or a header the decoder would refuse or read otherwise."""
    if data[:8] == _PNG:
        if len(data) < 24 or data[8:16] != b"\x00\x00\x00\x0dIHDR":
            raise ValueError("PNG whose first chunk is not a 13-byte IHDR")
        return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")
    if data[:2] == b"\xff\xd8":
        return _jpeg_size(data)
    raise ValueError("neither a PNG nor a JPEG image")


def _jpeg_size(data: bytes) -> tuple[int, int]:
    """The frame size of a JPEG, markers walked as libjpeg walks them."""
    size: tuple[int, int] | None = None
    i = 2
    n = len(data)
    while True:
        marker, i = _next_marker(data, i)
        if marker is None:
            raise ValueError("JPEG ends before its first scan")
        if marker in _SOF:
            if size is not None:
                raise ValueError(f"JPEG with a second frame header (marker 0x{marker:02X})")
            if i + 7 > n:
                raise ValueError("JPEG ends inside its frame header")
            height = int.from_bytes(data[i + 3 : i + 5], "big")
            width = int.from_bytes(data[i + 5 : i + 7], "big")
            size = (width, height)
            i += int.from_bytes(data[i : i + 2], "big")
        elif marker == _SOS:
            if size is None:
                raise ValueError("JPEG scan before any frame header")
            return size
        elif marker in _SEGMENTS:
            if i + 2 > n:
                raise ValueError(f"JPEG ends inside a marker segment (0x{marker:02X})")
            i += max(2, int.from_bytes(data[i : i + 2], "big"))
        elif marker in _BARE:
            continue
        elif marker == _SOI:
            raise ValueError("JPEG with a second start-of-image marker")
        elif marker == _EOI:
            raise ValueError("JPEG ends (EOI) before its first scan")
        else:
            raise ValueError(f"JPEG with an unknown marker 0x{marker:02X} at byte {i - 2}")


def _next_marker(data: bytes, i: int) -> tuple[int | None, int]:
    """(marker, index past it) from ``i`` on, as libjpeg's ``next_marker``: skip to an 0xFF,
    skip fill bytes, and treat ``FF 00`` as data; (None, end) at the end of the bytes."""
    n = len(data)
    while True:
        i = data.find(b"\xff", i)
        if i < 0:
            return None, n
        while i < n and data[i] == 0xFF:
            i += 1
        if i >= n:
            return None, n
        if data[i] != 0:
            return data[i], i + 1
        i += 1


def check_image_size(data: bytes, max_pixels: int = MAX_IMAGE_PIXELS) -> tuple[int, int]:
    """``(width, height)`` of a PNG/JPEG; ValueError when a side is 0 or above
    :data:`~umbra.connectors.limits.MAX_IMAGE_SIDE_PX`, or the pixels are more than
    ``max_pixels``."""
    w, h = image_size(data)
    if w == 0 or h == 0 or w > MAX_IMAGE_SIDE_PX or h > MAX_IMAGE_SIDE_PX or w * h > max_pixels:
        raise ValueError(
            f"image declares {w} x {h} pixels (at most {MAX_IMAGE_SIDE_PX} a side and "
            f"{max_pixels} in all)"
        )
    return w, h
