"""One recording per run: the parts written by the processes of a split run, merged by log time.

Each process of a split run records what it produced (``umbra.runtime.recording.tap``) into its
part; when every process has ended the launcher merges the parts into the run's file: messages in
log time order (the real clock is ``time.monotonic``, system-wide, so the processes' times compare),
channels and schemas once each, the graph and frames once, and the recorders' counts summed;
chunks are compressed as the parts' were. A part of a killed process reads to its last complete
chunk. The parts are removed once the merged file is finished; when merging fails they stay, each
one a readable recording.
"""

from __future__ import annotations

import heapq
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

from mcap.records import Channel, Message, Schema
from mcap.writer import CompressionType, Writer

from umbra.runtime.recording.reader import RecordingScan, indexed_scan, read_records
from umbra.runtime.recording.writer import PROFILE, TF_STATIC

if TYPE_CHECKING:
    from umbra.runtime.graph.plan import GraphPlan


def _stream(
    part: int, path: Path, scan: RecordingScan
) -> Iterator[tuple[int, int, int, Channel, Schema | None, Message]]:
    for n, (channel, schema, msg) in enumerate(read_records(path, scan)):
        yield msg.log_time, part, n, channel, schema, msg


def _compression(parts: list[Path]) -> CompressionType:
    """LZ4 unless a part was written uncompressed (raw images; a real-time process's part,
    ``tap.RunRecorder``)."""
    for part in parts:
        scan = indexed_scan(part)
        if scan is not None and scan.chunk_indexes and not scan.chunk_indexes[0].compression:
            return CompressionType.NONE
    return CompressionType.LZ4


def _register(
    writer: Writer,
    schema_ids: dict[tuple[str, str, bytes], int],
    schema: Schema | None,
    channel: Channel,
) -> int:
    """Channel ``channel`` (and its schema, once) in the merged file; its new id."""
    sid = 0
    if schema is not None:
        skey = (schema.name, schema.encoding, bytes(schema.data))
        if skey not in schema_ids:
            schema_ids[skey] = writer.register_schema(
                name=schema.name, encoding=schema.encoding, data=schema.data
            )
        sid = schema_ids[skey]
    return writer.register_channel(
        topic=channel.topic,
        message_encoding=channel.message_encoding,
        schema_id=sid,
        metadata=dict(channel.metadata or {}),
    )


def _profile(parts: list[Path]) -> str:
    """The parts' MCAP profile (``ros2`` for ``--record-format ros2``; else umbra's)."""
    from mcap.reader import make_reader

    with open(parts[0], "rb") as f:
        return make_reader(f).get_header().profile or PROFILE


def merge_parts(parts: list[Path], out: Path, chunk_size: int = 1024 * 1024) -> dict[str, int]:
    """Merge recordings ``parts`` into ``out``; returns counts (messages, parts)."""
    scans = [RecordingScan(p) for p in parts]
    streams = [_stream(i, p, scans[i]) for i, p in enumerate(parts)]
    schema_ids: dict[tuple[str, str, bytes], int] = {}
    channel_ids: dict[tuple[int, int], int | None] = {}
    topics: set[str] = set()
    messages = 0
    with open(out, "wb") as f:
        writer = Writer(f, chunk_size=chunk_size, compression=_compression(parts))
        writer.start(profile=_profile(parts), library="umbra")
        for log_time, part, _n, channel, schema, msg in heapq.merge(*streams):
            key = (part, channel.id)
            if key not in channel_ids:
                if channel.topic in topics and channel.topic == TF_STATIC:
                    channel_ids[key] = None  # every process writes the static frames: once
                else:
                    channel_ids[key] = _register(writer, schema_ids, schema, channel)
                    topics.add(channel.topic)
            cid = channel_ids[key]
            if cid is None:
                continue
            writer.add_message(
                channel_id=cid,
                log_time=log_time,
                publish_time=msg.publish_time,
                data=msg.data,
                sequence=msg.sequence,
            )
            messages += 1
        for part, scan in enumerate(scans):  # channels that carried nothing: declared all the same
            for channel in scan.channels.values():
                if (part, channel.id) not in channel_ids and channel.topic not in topics:
                    _register(writer, schema_ids, scan.schemas.get(channel.schema_id), channel)
                    topics.add(channel.topic)
        _merged_metadata(writer, scans)
        writer.finish()
    return {"messages": messages, "parts": len(parts)}


def _merged_metadata(writer: Writer, scans: list[RecordingScan]) -> None:
    run: dict[str, str] = {}
    counts: dict[str, int] = {}
    unfinished = []
    for scan in scans:
        for name, data in scan.metadata.items():
            if name == "umbra.recording":
                for k, v in data.items():
                    if v.isdigit():
                        counts[k] = counts.get(k, 0) + int(v)
            elif name == "umbra.run":
                if not run:
                    run = dict(data)
                else:  # the earliest first tick of the processes
                    t0 = min(int(run.get("t0_ns", "0")), int(data.get("t0_ns", "0")))
                    run["t0_ns"] = str(t0)
        if not scan.finished:
            unfinished.append(scan.path.name)
    if run:
        run["process"] = ""
        writer.add_metadata("umbra.run", run)
    names = {n for s in scans for n in s.metadata} - {"umbra.recording", "umbra.run"}
    for name in sorted(names):
        src = next(s for s in scans if name in s.metadata)
        writer.add_metadata(name, src.metadata[name])
    if counts or unfinished:
        stats = {k: str(v) for k, v in counts.items()}
        if unfinished:
            stats["unfinished_parts"] = ",".join(unfinished)
            stats.pop("dropped", None)  # a killed process's drops are unknown
        writer.add_metadata("umbra.recording", stats)
    seen: set[str] = set()
    for scan in scans:
        for name, att in scan.attachments.items():
            if name not in seen:
                seen.add(name)
                writer.add_attachment(att.create_time, att.log_time, name, att.media_type, att.data)


def merge_run(plan: GraphPlan, out: Path, processes: list[str]) -> str:
    """Merge the parts of a split run's processes in ``out``; what happened, in one line."""
    from umbra.connectors.errors import UserError
    from umbra.runtime.recording.tap import part_path

    settings = plan.spec.record
    target = out / settings.file
    parts = [p for p in (part_path(out, settings, n) for n in processes) if p.exists()]
    if not parts:
        return f"recording: no part was written in {out}"
    try:
        counts = merge_parts(parts, target)
    except (UserError, OSError) as exc:
        target.unlink(missing_ok=True)
        return f"recording: the parts could not be merged ({exc}); they stay in {out}"
    for p in parts:
        p.unlink(missing_ok=True)
    return f"recording: {target} ({counts['messages']} messages from {len(parts)} processes)"
