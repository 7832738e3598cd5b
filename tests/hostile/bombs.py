"""Hostile files built byte by byte: decompression bombs in MCAP chunks and images whose real frame
header hides behind a decoy.

The compressed frames are written by hand (a zstd frame of RLE blocks, an LZ4 frame repeating one
block of zeros) so that a gigabyte-sized bomb costs a few kilobytes and milliseconds to make; their
small versions are checked against the real decompressors by the tests.
"""

from __future__ import annotations

import struct
import zlib

import lz4.block
import lz4.frame
from mcap.data_stream import RecordBuilder
from mcap.records import (
    Channel,
    Chunk,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    Message,
    Schema,
    Statistics,
)

MAGIC = b"\x89MCAP0\r\n"
#: The most a zstd block may produce (128 KiB).
ZSTD_BLOCK = 128 * 1024
#: An LZ4 frame block of at most 4 MiB.
LZ4_BLOCK = 4 * 1024 * 1024


def zstd_rle_frame(total: int) -> bytes:
    """A zstd frame (no content size in its header) inflating to ``total`` zero bytes: RLE blocks
    of 128 KiB, 4 bytes each (a 98 kB frame inflates to 3.2 GB)."""
    out = bytearray(struct.pack("<I", 0xFD2FB528))
    out += bytes([0x00, 0x50])  # descriptor: no content size, not single segment; window 1 MiB
    left = total
    while left > 0:
        size = min(left, ZSTD_BLOCK)
        left -= size
        header = (1 if left == 0 else 0) | (1 << 1) | (size << 3)  # last flag, type RLE, size
        out += header.to_bytes(3, "little") + b"\x00"
    return bytes(out)


def lz4_zero_frame(blocks: int) -> bytes:
    """An LZ4 frame of ``blocks`` independent 4 MiB blocks of zeros (about 16 kB each)."""
    zeros = bytes(LZ4_BLOCK)
    one = lz4.frame.compress(
        zeros,
        block_size=lz4.frame.BLOCKSIZE_MAX4MB,
        block_linked=False,
        content_checksum=False,
        store_size=False,
    )
    block = lz4.block.compress(zeros, store_size=False)
    body = struct.pack("<I", len(block)) + block
    start = one.index(body)
    return one[:start] + body * blocks + struct.pack("<I", 0)


#: The channel of a camera's images as ``umbra run --record`` declares it.
CAMERA = {
    "topic": "/camera/image",
    "schema": "foxglove.CompressedImage",
    "encoding": "protobuf",
    "metadata": {
        "umbra.type": "Image",
        "umbra.role": "primary",
        "umbra.port": "camera.image",
        "umbra.frame": "camera",
    },
}
#: The simulated camera's ground-truth contour, recorded beside its images.
CAMERA_TRUTH = {
    "topic": "/camera/truth",
    "schema": "umbra.Contour",
    "encoding": "json",
    "metadata": {"umbra.type": "Contour", "umbra.role": "primary", "umbra.port": "camera.truth"},
}
#: A channel of umbra Scalars.
SCALAR = {
    "topic": "/src/value",
    "schema": "umbra.Scalar",
    "encoding": "json",
    "metadata": {"umbra.type": "Scalar", "umbra.role": "primary", "umbra.port": "src.value"},
}


def mcap_bytes(
    compression: str,
    data: bytes,
    declared: int,
    indexed: bool = False,
    crc: int = 0,
    channels: list[dict] | None = None,
) -> bytes:
    """An MCAP file with its channels (default :data:`SCALAR`; a camera's: :data:`CAMERA` and
    :data:`CAMERA_TRUTH`) and one chunk holding ``data`` compressed by ``compression`` and
    declaring ``declared`` bytes uncompressed; ``indexed``: with a summary (statistics and a chunk
    index), as a finished recording has."""
    b = RecordBuilder()
    Header(profile="", library="hostile").write(b)
    declared_records = []
    for i, of in enumerate(channels or [SCALAR], start=1):
        declared_records.append(Schema(id=i, name=of["schema"], encoding="jsonschema", data=b"{}"))
        declared_records.append(
            Channel(
                id=i,
                topic=of["topic"],
                message_encoding=of["encoding"],
                schema_id=i,
                metadata=dict(of["metadata"]),
            )
        )
    ids = list(range(1, len(channels or [SCALAR]) + 1))
    for record in declared_records:
        record.write(b)
    chunk_start = len(MAGIC) + b.count
    Chunk(
        compression=compression,
        data=data,
        message_start_time=0,
        message_end_time=1_000_000,
        uncompressed_crc=crc,
        uncompressed_size=declared,
    ).write(b)
    chunk_length = len(MAGIC) + b.count - chunk_start
    DataEnd(data_section_crc=0).write(b)
    summary_start = 0
    if indexed:
        summary_start = len(MAGIC) + b.count
        for record in declared_records:
            record.write(b)
        Statistics(
            message_count=10,
            schema_count=len(ids),
            channel_count=len(ids),
            attachment_count=0,
            metadata_count=0,
            chunk_count=1,
            message_start_time=0,
            message_end_time=1_000_000,
            channel_message_counts={i: 10 for i in ids},
        ).write(b)
        ChunkIndex(
            message_start_time=0,
            message_end_time=1_000_000,
            chunk_start_offset=chunk_start,
            chunk_length=chunk_length,
            message_index_offsets={i: chunk_start + chunk_length for i in ids},
            message_index_length=0,
            compression=compression,
            compressed_size=len(data),
            uncompressed_size=declared,
        ).write(b)
    Footer(summary_start=summary_start, summary_offset_start=0, summary_crc=0).write(b)
    return MAGIC + b.end() + MAGIC


def chunk_payload(messages: int) -> bytes:
    """Uncompressed chunk records: ``messages`` Scalar messages on channel 1, 1 ms apart."""
    b = RecordBuilder()
    for i in range(messages):
        data = f'{{"stamp":{i / 1000},"seq":{i + 1},"value":{float(i)},"_arrays":{{}}}}'
        Message(
            channel_id=1,
            sequence=i + 1,
            log_time=i * 1_000_000,
            publish_time=i * 1_000_000,
            data=data.encode(),
        ).write(b)
    return b.end()


def crc(data: bytes) -> int:
    return zlib.crc32(data)
