"""The Foxglove WebSocket server of a run: channels from the recording's encoding table.

``LiveServer.offer(topic, sample, now)`` is what a tick pays: a dictionary look-up, one look-up
per channel of whether a viewer subscribes (none: nothing else happens) and a put that never
waits into a lane holding the newest sample of each topic (:mod:`umbra.runtime.live.latest_lane`:
a sample replaced before it was encoded is dropped and counted, and every topic gets its turn).
Encoding (JPEG, protobuf, JSON) and the hand-over to the socket happen on the server's own
threads at a lower CPU priority: one lane for images and one for everything else, so joint
states never wait behind a JPEG encoding. The socket
(``umbra.runtime.live.viewer_server``) keeps a bounded backlog per viewer and drops the oldest for a
viewer that does not read, so a slow or stalled viewer costs the run nothing but those threads'
work.

Viewers get no capability that acts on the run: no client publishing, no services. Module
parameters are visible (``MODULE.PARAM`` names; ``umbra.runtime.live.parameters``).

Times: every message's log time and the Foxglove messages' own timestamps are wall-clock time, the
run's time plus one offset read when the server starts (as in a recording).
"""

from __future__ import annotations

import contextlib
import logging
import os
import threading
import time
from dataclasses import dataclass, field
from typing import Any

from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from mcap_protobuf.schema import build_file_descriptor_set

from umbra.connectors.messages import Image, Message
from umbra.runtime.live.latest_lane import CLOSED, LatestLane
from umbra.runtime.live.viewer_server import ViewerServer
from umbra.runtime.recording.encoders import ChannelEncoding, channel_encodings
from umbra.runtime.recording.foxglove_msgs import frame_transforms, time_ns
from umbra.runtime.recording.writer import TF_STATIC

#: Nice value of the server's encoding thread (Linux): below the run's loop.
ENCODER_NICE = 10
#: Seconds between two sends of the static frames (a viewer that joins gets them this soon).
STATIC_PERIOD = 1.0


@dataclass
class LiveChannel:
    """One output served live: its encodings and their channel ids (one per encoding)."""

    topic: str
    msg_type: type[Message]
    encodings: list[ChannelEncoding]
    channels: list[int]
    bulk: bool = False  #: images: served on their own lane
    sent: int = 0
    dropped: int = 0
    failed: int = 0


@dataclass
class LiveStats:
    """What the server did: samples offered while watched, sent, dropped (replaced by a newer
    one of their topic before they were encoded)."""

    offered: int = 0
    sent: int = 0
    dropped: int = 0
    by_topic: dict[str, dict[str, int]] = field(default_factory=dict)


class LiveServer:
    """Encodes what :meth:`offer` hands over and publishes it on ``socket``'s channels."""

    def __init__(
        self,
        *,
        socket: ViewerServer,
        clock_offset: float,
        images: str = "jpeg",
        jpeg_quality: int = 80,
        log: logging.Logger | None = None,
    ) -> None:
        self.clock_offset = clock_offset  #: wall-clock time minus the run's clock [s]
        self._images, self._jpeg_quality = images, jpeg_quality
        self._log = log or logging.getLogger("umbra.foxglove")
        self._socket = socket
        self._channels: dict[str, LiveChannel] = {}
        self._lanes = {False: LatestLane(), True: LatestLane()}  # small messages, images
        self.stats = LiveStats()
        self._static: tuple[list[tuple[str, str, Any]], Any, int] | None = None
        self._threads = [
            threading.Thread(
                target=self._run, args=(lane, not bulk), name="umbra-foxglove", daemon=True
            )
            for bulk, lane in self._lanes.items()
        ]
        for thread in self._threads:
            thread.start()

    def declare(self, topic: str, msg_type: type[Message]) -> LiveChannel:
        """Serve ``topic`` carrying ``msg_type``: one channel per encoding (as recorded)."""
        found = self._channels.get(topic)
        if found is not None:
            return found
        images = self._images if issubclass(msg_type, Image) else "raw"
        encodings = channel_encodings(msg_type, images, self._jpeg_quality, self.clock_offset)
        channels = [
            self._socket.add_channel(
                topic + enc.suffix,
                enc.message_encoding,
                enc.schema_name,
                enc.schema_encoding,
                enc.schema_data,
            )
            for enc in encodings
        ]
        found = self._channels[topic] = LiveChannel(
            topic, msg_type, encodings, channels, bulk=issubclass(msg_type, Image)
        )
        return found

    def set_static_frames(self, frames: list[tuple[str, str, Any]], clock: Any) -> None:
        """The graph's static frames on ``/tf_static`` (``foxglove.FrameTransforms``), sent again
        every ``STATIC_PERIOD`` s so that a viewer that joins later has them; ``clock.now()``
        gives the run's time."""
        if not frames:
            return
        self._static = (
            list(frames),
            clock,
            self._socket.add_channel(
                TF_STATIC,
                "protobuf",
                FrameTransforms.DESCRIPTOR.full_name,
                "protobuf",
                build_file_descriptor_set(FrameTransforms).SerializeToString(),
            ),
        )

    def _send_static(self) -> None:
        if self._static is None:
            return
        frames, clock, channel = self._static
        if self._socket.watched(channel):
            now = clock.now()
            data = frame_transforms(frames, now, self.clock_offset).SerializeToString()
            self._socket.publish(channel, time_ns(now, self.clock_offset), data)

    # -- the tick's part ------------------------------------------------------------------------
    def offer(self, topic: str, sample: Message, now: float) -> None:
        """Hand ``sample`` (sent at the run's time ``now`` [s]) to the server when a client
        watches ``topic``; never waits."""
        live = self._channels.get(topic)
        watched = self._socket.watched
        if live is None or not any(watched(ch) for ch in live.channels):
            return
        self.stats.offered += 1
        if not self._lanes[live.bulk].put(topic, (live, sample, now)):
            live.dropped += 1  # replaced by this newer one before it was encoded
            self.stats.dropped += 1

    def sink(self, topic: str) -> Any:
        """A port sink ``(sample, now)`` serving on ``topic``."""
        offer = self.offer

        def serve(sample: Message, now: float) -> None:
            offer(topic, sample, now)

        return serve

    # -- the server's thread --------------------------------------------------------------------
    def _send(self, live: LiveChannel, sample: Message, now: float) -> None:
        log_ns = time_ns(now, self.clock_offset)
        for enc, channel in zip(live.encodings, live.channels, strict=True):
            if not self._socket.watched(channel):
                continue
            try:
                data = enc.encode(sample)
            except (ValueError, TypeError) as exc:
                live.failed += 1
                if live.failed == 1:
                    self._log.warning("foxglove `%s`: cannot encode a sample: %s", live.topic, exc)
                continue
            if data:
                self._socket.publish(channel, log_ns, data)
        live.sent += 1
        self.stats.sent += 1

    def _run(self, lane: LatestLane, statics: bool) -> None:
        with contextlib.suppress(AttributeError, OSError):
            os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), ENCODER_NICE)
        next_static = time.monotonic()
        while True:
            item = lane.get(timeout=STATIC_PERIOD)
            if item is CLOSED:
                return
            try:
                if item is not None:
                    self._send(*item)
                if statics and time.monotonic() >= next_static:
                    next_static = time.monotonic() + STATIC_PERIOD
                    self._send_static()
            except Exception as exc:  # a viewer must never end the run: say it, go on
                self._log.warning("foxglove: %s: %s", type(exc).__name__, exc)

    def close(self) -> None:
        """Stop encoding: the threads end (the socket is closed by its owner)."""
        for lane in self._lanes.values():
            lane.close()
        for thread in self._threads:
            thread.join(timeout=2.0)

    def summary(self) -> dict[str, Any]:
        """For the run's summary."""
        return {
            "offered": self.stats.offered,
            "sent": self.stats.sent,
            "dropped": self.stats.dropped,
            "topics": len(self._channels),
        }
