"""The Foxglove WebSocket server of a run: channels from the recording's encoding table.

``LiveServer.offer(topic, sample, now)`` is what a tick pays: a dictionary look-up, one
``has_sinks()`` per channel (no client subscribed: nothing else happens) and a non-blocking put on
a bounded queue; a full queue drops the sample and counts it. Encoding (JPEG, protobuf, JSON) and
the hand-over to the SDK happen on the server's own threads at a lower CPU priority: one lane for
images (a few frames deep: a late frame is worth less than the next one) and one for everything
else, so joint states never wait behind a JPEG encoding. The SDK keeps a bounded backlog per
client (``CLIENT_BACKLOG``) and drops the oldest for a client that does not read, so a slow or
stalled viewer costs the run nothing but those threads' work.

Clients get no capability that acts on the run: no client publishing, no services. Module
parameters are visible (``Capability.Parameters``: ``MODULE.PARAM`` names, read only); a set
request changes nothing and is answered with the current values, and is logged.

Times: every message's log time and the Foxglove messages' own timestamps are wall-clock time, the
run's time plus one offset read when the server starts (as in a recording).
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import queue
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import foxglove
from foxglove.websocket import Capability, ServerListener
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from mcap_protobuf.schema import build_file_descriptor_set

from connectors.messages import Image, Message
from runtime.recording.encoders import ChannelEncoding, channel_encodings
from runtime.recording.foxglove_msgs import frame_transforms, time_ns
from runtime.recording.writer import TF_STATIC

#: Nice value of the server's encoding thread (Linux): below the run's loop.
ENCODER_NICE = 10
#: Messages the SDK holds for a client that does not keep up (then drops its oldest): about half
#: a second of a pick-up's image and joint streams, so a slow viewer sees late data for no longer.
CLIENT_BACKLOG = 64
#: Images waiting to be encoded at most (more: the newest is dropped and counted).
IMAGE_QUEUE = 4
#: Seconds between two sends of the static frames (a viewer that joins gets them this soon).
STATIC_PERIOD = 1.0
_STOP = object()


@dataclass
class LiveChannel:
    """One output served live: its encodings and their SDK channels."""

    topic: str
    msg_type: type[Message]
    encodings: list[ChannelEncoding]
    channels: list[Any]
    bulk: bool = False  #: images: served on their own lane
    sent: int = 0
    dropped: int = 0
    failed: int = 0


@dataclass
class LiveStats:
    """What the server did: samples offered while watched, sent, dropped (queue full)."""

    offered: int = 0
    sent: int = 0
    dropped: int = 0
    by_topic: dict[str, dict[str, int]] = field(default_factory=dict)


class _ReadOnlyParameters(ServerListener):
    """Parameters a client may read, never change."""

    def __init__(self, params: dict[str, Any], log: logging.Logger) -> None:
        self._params = params
        self._log = log

    def _all(self, names: list[str] | None = None) -> list[foxglove.Parameter]:
        wanted = (
            self._params if not names else {n: self._params[n] for n in names if n in self._params}
        )
        return [foxglove.Parameter(name, value=_parameter_value(v)) for name, v in wanted.items()]

    def on_get_parameters(
        self, client: Any, param_names: list[str], request_id: str | None = None
    ) -> list[Any]:
        return self._all(param_names)

    def on_set_parameters(
        self, client: Any, parameters: list[Any], request_id: str | None = None
    ) -> list[Any]:
        names = [p.name for p in parameters]
        self._log.warning(
            "foxglove: client %s asked to set %s: refused (parameters are read only live)",
            getattr(client, "id", "?"),
            ", ".join(names[:8]),
        )
        return self._all(names)


def _parameter_value(value: Any) -> Any:
    """A parameter value the SDK can carry (numbers, strings, bools, lists, dicts; others as
    JSON text)."""
    if isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, (list, tuple)) and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) for v in value
    ):
        return [float(v) for v in value]
    return json.dumps(value, default=str)


class LiveServer:
    """The SDK's WebSocket server on a private loopback port, fed by :meth:`offer`."""

    def __init__(
        self,
        *,
        name: str,
        clock_offset: float,
        parameters: dict[str, Any] | None = None,
        images: str = "jpeg",
        jpeg_quality: int = 80,
        max_items: int = 256,
        log: logging.Logger | None = None,
    ) -> None:
        self.clock_offset = clock_offset  #: wall-clock time minus the run's clock [s]
        self._images, self._jpeg_quality = images, jpeg_quality
        self._log = log or logging.getLogger("umbra.foxglove")
        self._context = foxglove.Context()
        self._channels: dict[str, LiveChannel] = {}
        self._lanes = {
            False: queue.Queue(maxsize=max_items),  # small messages
            True: queue.Queue(maxsize=IMAGE_QUEUE),  # images
        }
        self.stats = LiveStats()
        self._static: tuple[list[tuple[str, str, Any]], Any, Any] | None = None
        self._server = foxglove.start_server(
            name=name,
            host="127.0.0.1",
            port=0,
            context=self._context,
            capabilities=[Capability.Parameters],
            message_backlog_size=CLIENT_BACKLOG,
            server_listener=_ReadOnlyParameters(dict(parameters or {}), self._log),
        )
        self._threads = [
            threading.Thread(
                target=self._run, args=(lane, not bulk), name="umbra-foxglove", daemon=True
            )
            for bulk, lane in self._lanes.items()
        ]
        for thread in self._threads:
            thread.start()

    @property
    def port(self) -> int:
        """The SDK server's private loopback port (the gate forwards to it)."""
        return self._server.port

    def declare(
        self, topic: str, msg_type: type[Message], meta: dict[str, str] | None = None
    ) -> LiveChannel:
        """Serve ``topic`` carrying ``msg_type``: one SDK channel per encoding (as recorded)."""
        found = self._channels.get(topic)
        if found is not None:
            return found
        images = self._images if issubclass(msg_type, Image) else "raw"
        encodings = channel_encodings(msg_type, images, self._jpeg_quality, self.clock_offset)
        channels = [
            foxglove.Channel(
                topic + enc.suffix,
                schema=foxglove.Schema(
                    name=enc.schema_name, encoding=enc.schema_encoding, data=enc.schema_data
                ),
                message_encoding=enc.message_encoding,
                context=self._context,
                metadata=dict(meta or {}),
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
            foxglove.Channel(
                TF_STATIC,
                schema=foxglove.Schema(
                    name=FrameTransforms.DESCRIPTOR.full_name,
                    encoding="protobuf",
                    data=build_file_descriptor_set(FrameTransforms).SerializeToString(),
                ),
                message_encoding="protobuf",
                context=self._context,
            ),
        )

    def _send_static(self) -> None:
        if self._static is None:
            return
        frames, clock, channel = self._static
        if channel.has_sinks():
            now = clock.now()
            data = frame_transforms(frames, now, self.clock_offset).SerializeToString()
            channel.log(data, log_time=time_ns(now, self.clock_offset))

    # -- the tick's part ------------------------------------------------------------------------
    def offer(self, topic: str, sample: Message, now: float) -> None:
        """Hand ``sample`` (sent at the run's time ``now`` [s]) to the server when a client
        watches ``topic``; never waits."""
        live = self._channels.get(topic)
        if live is None or not any(ch.has_sinks() for ch in live.channels):
            return
        self.stats.offered += 1
        try:
            self._lanes[live.bulk].put_nowait((live, sample, now))
        except queue.Full:
            live.dropped += 1
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
            if not channel.has_sinks():
                continue
            try:
                data = enc.encode(sample)
            except (ValueError, TypeError) as exc:
                live.failed += 1
                if live.failed == 1:
                    self._log.warning("foxglove `%s`: cannot encode a sample: %s", live.topic, exc)
                continue
            if data:
                channel.log(data, log_time=log_ns)
        live.sent += 1
        self.stats.sent += 1

    def _run(self, lane: queue.Queue[Any], statics: bool) -> None:
        with contextlib.suppress(AttributeError, OSError):
            os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), ENCODER_NICE)
        next_static = time.monotonic()
        while True:
            try:
                item = lane.get(timeout=STATIC_PERIOD)
            except queue.Empty:
                item = None
            if item is _STOP:
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
        """Stop serving: the thread ends, the SDK server stops."""
        for lane in self._lanes.values():
            with contextlib.suppress(queue.Full):
                lane.put(_STOP, timeout=1.0)
        for thread in self._threads:
            thread.join(timeout=2.0)
        self._server.stop()

    def summary(self) -> dict[str, Any]:
        """For the run's summary."""
        return {
            "offered": self.stats.offered,
            "sent": self.stats.sent,
            "dropped": self.stats.dropped,
            "topics": len(self._channels),
        }
