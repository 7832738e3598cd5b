"""Recordings made by the ``Recorder`` module: samples written to an MCAP file, and read back.

Each recorded input is a topic named as the recorder's channel; samples are encoded as every
recording of the project is (``umbra.runtime.recording``: Foxglove's well-known schemas for images
and poses, JSON with a JSON schema for the rest), with log time = the tick time at which the sample
arrived [ns] and publish time its stamp. ``read_recording`` gives the samples back as messages.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

from umbra.connectors.messages import Message
from umbra.runtime.recording.samples import iter_samples
from umbra.runtime.recording.writer import RecordingFile


class RecordingWriter:
    """Writes samples to one MCAP file from a background thread; ``close`` finishes it.

    ``blocking``: wait for room when the queue is full (sim clock) instead of dropping."""

    def __init__(self, path: Path, *, blocking: bool = True, images: str = "raw") -> None:
        self._file = RecordingFile(path, blocking=blocking)
        self._images = images

    def write(self, channel: str, sample: Message, now: float | None = None) -> None:
        """Append ``sample`` on ``channel`` (sent at ``now`` [s]; default its stamp)."""
        if channel not in self._file.counts:
            self._file.declare(channel, type(sample), images=self._images)
        self._file.offer(channel, sample, sample.stamp if now is None else now)

    @property
    def count(self) -> int:
        """Samples written so far."""
        return self._file.written

    @property
    def dropped(self) -> int:
        """Samples dropped because the queue was full (real clock only)."""
        return self._file.dropped

    def close(self) -> None:
        """Finish and close the file."""
        self._file.close()


def read_recording(path: str | Path) -> Iterator[tuple[str, Message]]:
    """Yield ``(channel, sample)`` in file order; UserError when the file is not a recording."""
    for sample in iter_samples(path):
        yield sample.topic, sample.message
