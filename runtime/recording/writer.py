"""An MCAP recording written from its own thread: a tick only hands the sample over.

``RecordingFile.offer(topic, sample, now)`` is what a tick pays: a budget check under a lock and a
queue put (about a microsecond); encoding (JPEG, protobuf, JSON) and writing happen on the
recorder's thread. The queue is bounded (``max_items`` samples and ``max_bytes`` of arrays): on the
real clock a sample that does not fit is dropped and counted per channel, so the recorder never
holds a tick back; on the sim clock time is virtual, so the tick waits for room instead and a sim
recording is complete.

The recorder's thread runs at a lower CPU priority (nice ``WRITER_NICE``), so the loop's thread
gets the CPU first when it wakes; in a real-time process it follows the loop into ``SCHED_FIFO``
(:func:`umbra.connectors.threads.lowered`: it holds the GIL too often to wait for a CPU). The
file is chunked (LZ4, or uncompressed with ``compress=False``:
raw camera pixels do not compress, LZ4 only costs time on both sides) and
flushed at least every ``flush_period`` seconds of wall time, so a
run that is killed leaves a file whose complete chunks read back
(``umbra.runtime.recording.reader``): it loses at most the last chunk. ``close`` writes the counts
and drops as metadata ``umbra.recording`` and finishes the file (index, summary, footer).

Message times are wall-clock time: ``log_time`` is the tick time at which the sample was sent,
``publish_time`` the sample's ``stamp`` (and the Foxglove messages' own timestamps too), each
[ns] plus ``clock_offset`` (wall − the run's clock, read once when the recording starts: see
``umbra.runtime.recording.encoders``); the run's clock is therefore ``publish_time - clock_offset``
for every message, and JSON messages keep their ``stamp`` as is. The MCAP ``sequence`` is the
sample's ``seq``.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO

from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from mcap.writer import CompressionType, Writer
from mcap_protobuf.schema import register_schema

from umbra.connectors.errors import UserError
from umbra.connectors.messages import CameraModel, Image, Message, Pose, Poses
from umbra.runtime.recording.encoders import ChannelEncoding, channel_encodings
from umbra.runtime.recording.foxglove_msgs import frame_transforms, time_ns, view_frames
from umbra.runtime.recording.ros2_channels import ros2_channel_encodings, static_frames_message
from umbra.runtime.rt_priority import lowered

#: Channel metadata keys (strings), read by record-info and replay.
META_TYPE = "umbra.type"
META_PORT = "umbra.port"
META_FRAME = "umbra.frame"
META_JOINTS = "umbra.joints"
META_ROLE = "umbra.role"  # "primary" or "view"
META_PROCESS = "umbra.process"
TF_STATIC = "/tf_static"
#: Recording formats: Foxglove's schemas (protobuf, JSON) or ROS 2's (``ros2msg``/``cdr``,
#: ``umbra.runtime.recording.ros2_channels``).
RECORD_FORMATS = ("foxglove", "ros2")
PROFILE = "umbra"
#: Nice value of the recorder's thread (Linux): below the run's loop, which never waits for it.
WRITER_NICE = 10


@dataclass
class ChannelInfo:
    """A recorded topic: its type, what the channel metadata says, counters."""

    topic: str
    msg_type: type[Message]
    meta: dict[str, str]
    images: str = "raw"
    encodings: list[ChannelEncoding] = field(default_factory=list)
    ids: list[int] = field(default_factory=list)
    written: int = 0
    dropped: int = 0
    failed: int = 0


_STOP = object()


class RecordingFile:
    """One MCAP file written by a background thread (see the module docstring)."""

    def __init__(
        self,
        path: Path,
        *,
        blocking: bool = False,
        max_items: int = 4096,
        max_bytes: int = 256 * 1024 * 1024,
        chunk_size: int = 1024 * 1024,
        flush_period: float = 1.0,
        jpeg_quality: int = 90,
        compress: bool = True,
        clock_offset: float = 0.0,
        record_format: str = "foxglove",
        log: logging.Logger | None = None,
    ) -> None:
        if record_format not in RECORD_FORMATS:
            raise ValueError(
                f"expected a recording format among {RECORD_FORMATS}, found {record_format!r}"
            )
        self.record_format = record_format
        self.path = Path(path)
        self.clock_offset = clock_offset  #: wall-clock time minus the run's clock [s]
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._file: BinaryIO = open(self.path, "wb")  # noqa: SIM115 — closed by the thread
        except OSError as exc:
            raise UserError(f"{path}: error: cannot write the recording: {exc.strerror}") from None
        compression = CompressionType.LZ4 if compress else CompressionType.NONE
        self._writer = Writer(self._file, chunk_size=chunk_size, compression=compression)
        profile = "ros2" if record_format == "ros2" else PROFILE  # rosbag2 readers ask for it
        self._writer.start(profile=profile, library="umbra")
        self._log = log or logging.getLogger("umbra.record")
        #: child frame -> (parent, topic) of its first transform (a viewer keeps one parent)
        self._parents: dict[str, tuple[str, str]] = {}
        self._two_parents: set[str] = set()  # frames already reported
        self._blocking = blocking
        self._max_items, self._max_bytes = max_items, max_bytes
        self._flush_period = flush_period
        self._jpeg_quality = jpeg_quality
        self._channels: dict[str, ChannelInfo] = {}
        self._schemas: dict[tuple[str, str], int] = {}
        self._queue: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self._room = threading.Condition(threading.Lock())
        self._items = 0
        self._bytes = 0
        self._closed = False
        self._error: str | None = None
        self._thread = threading.Thread(target=self._run, name="umbra-recorder", daemon=True)
        self._thread.start()

    # -- set-up (any thread, before samples of that topic) ---------------------------------------
    def declare(
        self,
        topic: str,
        msg_type: type[Message],
        meta: dict[str, str] | None = None,
        images: str = "raw",
    ) -> ChannelInfo:
        """Declare ``topic`` carrying ``msg_type`` (images recorded ``raw``, ``jpeg`` or ``png``);
        its channels are registered on the recorder's thread."""
        info = self._channels.get(topic)
        if info is None:
            info = ChannelInfo(topic, msg_type, dict(meta or {}), images)
            info.meta.setdefault(META_TYPE, msg_type.__name__)
            self._channels[topic] = info
            self._queue.put(("declare", info))
        return info

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        """A metadata record ``name`` (string to string)."""
        self._queue.put(("metadata", name, dict(data)))

    def add_attachment(self, name: str, media_type: str, data: bytes, when_ns: int = 0) -> None:
        """An attachment (the graph file, the frames)."""
        self._queue.put(("attachment", name, media_type, bytes(data), when_ns))

    def write_static_frames(self, frames: list[tuple[str, str, Any]], now: float) -> None:
        """The graph's static frames on ``/tf_static`` (``foxglove.FrameTransforms``)."""
        if frames:
            self._queue.put(("static", list(frames), now))

    # -- the tick's part ------------------------------------------------------------------------
    def offer(self, topic: str, sample: Message, now: float) -> bool:
        """Hand ``sample`` (sent at tick time ``now`` [s]) to the recorder; False when dropped."""
        info = self._channels.get(topic)
        if info is None:
            info = self.declare(topic, type(sample))
        size = sample.pixels.nbytes if isinstance(sample, Image) else 256
        with self._room:
            if self._closed:
                return False
            while self._items >= self._max_items or self._bytes + size > self._max_bytes:
                if not self._blocking or self._error is not None:
                    info.dropped += 1
                    return False
                self._room.wait(0.5)
            self._items += 1
            self._bytes += size
        self._queue.put((info, sample, now, size))
        return True

    def sink(self, topic: str) -> Any:
        """A port sink ``(sample, now)`` recording on ``topic``."""
        offer = self.offer

        def record(sample: Message, now: float) -> None:
            offer(topic, sample, now)

        return record

    # -- the recorder's thread ------------------------------------------------------------------
    def _register(self, info: ChannelInfo) -> None:
        table = ros2_channel_encodings if self.record_format == "ros2" else channel_encodings
        info.encodings = table(info.msg_type, info.images, self._jpeg_quality, self.clock_offset)
        for enc in info.encodings:
            key = (enc.schema_name, enc.schema_encoding)
            if key not in self._schemas:
                self._schemas[key] = self._writer.register_schema(
                    name=enc.schema_name, encoding=enc.schema_encoding, data=enc.schema_data
                )
            meta = dict(info.meta)
            meta[META_ROLE] = "view" if enc.view else "primary"
            if info.msg_type is Image or issubclass(info.msg_type, Image):
                meta["umbra.images"] = info.images
            info.ids.append(
                self._writer.register_channel(
                    topic=info.topic + enc.suffix,
                    message_encoding=enc.message_encoding,
                    schema_id=self._schemas[key],
                    metadata=meta,
                )
            )

    def _write(self, info: ChannelInfo, sample: Message, now: float) -> None:
        log_ns = time_ns(now, self.clock_offset)
        pub_ns = time_ns(sample.stamp, self.clock_offset)
        seq = sample.seq & 0xFFFFFFFF
        for enc, cid in zip(info.encodings, info.ids, strict=True):
            try:
                data = enc.encode(sample)
            except (ValueError, TypeError) as exc:
                info.failed += 1
                if info.failed == 1:
                    self._log.warning("recording `%s`: cannot encode a sample: %s", info.topic, exc)
                continue
            if not data:  # nothing to write for this sample (see encoders)
                continue
            self._writer.add_message(
                channel_id=cid, log_time=log_ns, publish_time=pub_ns, data=data, sequence=seq
            )
        info.written += 1
        if isinstance(sample, (Pose, Poses, CameraModel)):
            try:
                for parent, child in view_frames(sample):
                    self._one_parent(child, parent, info.topic)
            except ValueError:  # counted above as a sample that did not encode
                pass

    def _one_parent(self, child: str, parent: str, topic: str) -> None:
        """Warn once when ``child`` is given a second parent: a viewer's transform tree keeps one
        parent per frame, so the frame would jump between the two."""
        first = self._parents.setdefault(child, (parent, topic))
        if first[0] != parent and child not in self._two_parents:
            self._two_parents.add(child)
            self._log.warning(
                "recording: frame `%s` has two parents, `%s` (%s) and `%s` (%s); a viewer keeps "
                "one: rename the frame in the graph's `frames:` or in the module's parameters",
                child,
                first[0],
                first[1],
                parent,
                topic,
            )

    def _static(self, frames: list[tuple[str, str, Any]], now: float) -> None:
        if self.record_format == "ros2":
            self._static_ros2(frames, now)
            return
        key = ("foxglove.FrameTransforms", "protobuf")
        if key not in self._schemas:
            self._schemas[key] = register_schema(self._writer, FrameTransforms)
        cid = self._writer.register_channel(
            topic=TF_STATIC,
            message_encoding="protobuf",
            schema_id=self._schemas[key],
            metadata={META_ROLE: "view"},
        )
        ns = time_ns(now, self.clock_offset)
        for parent, child, _T in frames:
            self._one_parent(child, parent, TF_STATIC)
        data = frame_transforms(frames, now, self.clock_offset).SerializeToString()
        self._writer.add_message(channel_id=cid, log_time=ns, publish_time=ns, data=data)

    def _static_ros2(self, frames: list[tuple[str, str, Any]], now: float) -> None:
        enc, data = static_frames_message(frames, now, self.clock_offset)
        key = (enc.schema_name, enc.schema_encoding)
        if key not in self._schemas:
            self._schemas[key] = self._writer.register_schema(
                name=enc.schema_name, encoding=enc.schema_encoding, data=enc.schema_data
            )
        cid = self._writer.register_channel(
            topic=TF_STATIC,
            message_encoding=enc.message_encoding,
            schema_id=self._schemas[key],
            metadata={META_ROLE: "view"},
        )
        ns = time_ns(now, self.clock_offset)
        self._writer.add_message(channel_id=cid, log_time=ns, publish_time=ns, data=data)

    def _handle(self, item: Any) -> None:
        if isinstance(item[0], ChannelInfo):
            info, sample, now, size = item
            try:
                self._write(info, sample, now)
            finally:
                with self._room:
                    self._items -= 1
                    self._bytes -= size
                    self._room.notify()
            return
        kind = item[0]
        if kind == "declare":
            self._register(item[1])
        elif kind == "metadata":
            self._writer.add_metadata(item[1], item[2])
        elif kind == "attachment":
            _, name, media, data, when = item
            self._writer.add_attachment(when, when, name, media, data)
        elif kind == "static":
            self._static(item[1], item[2])

    def _run(self) -> None:
        lowered(WRITER_NICE)  # the recorder gives way, and never keeps the GIL from the loop
        last_flush = time.monotonic()
        dirty = False
        while True:
            try:
                item = self._queue.get(timeout=self._flush_period)
            except queue.Empty:
                item = None
            if item is _STOP:
                break
            if item is not None and self._error is None:
                try:
                    self._handle(item)
                    dirty = True
                except Exception as exc:  # a full disk, a closed file: stop recording, say so
                    self._error = f"{type(exc).__name__}: {exc}"
                    self._log.error("recording %s stopped: %s", self.path, self._error)
            elif item is not None and isinstance(item[0], ChannelInfo):
                item[0].dropped += 1
                with self._room:
                    self._items -= 1
                    self._bytes -= item[3]
                    self._room.notify()
            now = time.monotonic()
            if dirty and now - last_flush >= self._flush_period and self._error is None:
                try:
                    self._writer.flush()
                except OSError as exc:
                    self._error = f"cannot write: {exc.strerror}"
                last_flush, dirty = now, False

    # -- the end --------------------------------------------------------------------------------
    @property
    def counts(self) -> dict[str, dict[str, int]]:
        """Per topic: samples written, dropped (queue full), failed (could not be encoded)."""
        return {
            t: {"written": c.written, "dropped": c.dropped, "failed": c.failed}
            for t, c in self._channels.items()
        }

    def _stats(self) -> dict[str, str]:
        stats = {"written": str(self.written), "dropped": str(self.dropped)}
        for topic, c in self.counts.items():
            stats[f"dropped:{topic}"] = str(c["dropped"])
            stats[f"failed:{topic}"] = str(c["failed"])
        return stats

    @property
    def written(self) -> int:
        return sum(c.written for c in self._channels.values())

    @property
    def dropped(self) -> int:
        return sum(c.dropped for c in self._channels.values())

    def close(self) -> None:
        """Write what is queued, the counts as metadata, the index and footer; close the file."""
        with self._room:
            if self._closed:
                return
            self._closed = True
        self._queue.put(_STOP)
        self._thread.join()
        try:
            if self._error is None:
                self._writer.add_metadata("umbra.recording", self._stats())
                self._writer.finish()
        except Exception as exc:  # the run's end must not fail on its recording: say so
            self._error = f"{type(exc).__name__}: {exc}"
        finally:
            self._file.close()
        if self._error is not None:
            self._log.error("recording %s stopped early: %s", self.path, self._error)

    @property
    def error(self) -> str | None:
        """Why the recording stopped early (a full disk...), or None."""
        return self._error
