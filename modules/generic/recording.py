"""Recordings: samples written to an MCAP file, and read back.

Each recorded input is an MCAP channel (topic = the channel name given to the recorder); every
message is the umbra binary encoding (``connectors.codec``, message encoding ``umbra.v1``) with
log time = the sample's stamp [ns]. Any MCAP tool lists the channels and times; ``read_recording``
gives the samples back as message objects.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import BinaryIO

from mcap.reader import make_reader
from mcap.writer import Writer

from connectors.codec import Codec
from connectors.errors import UserError
from connectors.messages import Message

ENCODING = "umbra.v1"


class RecordingWriter:
    """Writes samples to one MCAP file; ``close`` finishes it (index and summary)."""

    def __init__(self, path: Path) -> None:
        try:
            self._file: BinaryIO = open(path, "wb")  # noqa: SIM115 — closed in close()
        except OSError as exc:
            raise UserError(f"{path}: error: cannot write the recording: {exc.strerror}") from None
        self._writer = Writer(self._file)
        self._writer.start(profile="umbra", library="umbra")
        self._codec = Codec()
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self.count = 0

    def write(self, channel: str, sample: Message) -> None:
        """Append ``sample`` on ``channel``."""
        type_name = type(sample).__name__
        if type_name not in self._schemas:
            self._schemas[type_name] = self._writer.register_schema(
                name=type_name, encoding="", data=b""
            )
        if channel not in self._channels:
            self._channels[channel] = self._writer.register_channel(
                topic=channel, message_encoding=ENCODING, schema_id=self._schemas[type_name]
            )
        stamp_ns = max(0, int(sample.stamp * 1e9))
        self._writer.add_message(
            channel_id=self._channels[channel],
            log_time=stamp_ns,
            publish_time=stamp_ns,
            data=self._codec.encode(sample),
            sequence=sample.seq & 0xFFFFFFFF,
        )
        self.count += 1

    def close(self) -> None:
        """Finish and close the file."""
        if not self._file.closed:
            self._writer.finish()
            self._file.close()


def read_recording(path: str | Path) -> Iterator[tuple[str, Message]]:
    """Yield ``(channel, sample)`` in file order; UserError when the file is not a recording."""
    codec = Codec()
    try:
        with open(path, "rb") as f:
            reader = make_reader(f)
            for _schema, channel, message in reader.iter_messages(log_time_order=False):
                if channel.message_encoding != ENCODING:
                    continue
                yield channel.topic, codec.decode(message.data)
    except OSError as exc:
        raise UserError(f"{path}: error: cannot read the recording: {exc.strerror}") from None
    except Exception as exc:  # mcap raises several types on a damaged file
        if isinstance(exc, UserError):
            raise
        raise UserError(f"{path}: error: not a readable MCAP recording: {exc}") from None
