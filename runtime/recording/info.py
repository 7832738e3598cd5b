"""``umbra record-info``'s figures: channels, rates, gaps, drops and duration of a recording."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from umbra.connectors.json_text import json_text
from umbra.runtime.recording.reader import RecordingScan, read_records
from umbra.runtime.recording.writer import META_ROLE, META_TYPE

#: An interval longer than this many times the channel's median interval is a gap.
GAP_FACTOR = 3.0
#: Fewest messages a channel needs for a rate: fewer are events (two messages 10 ms apart are two
#: events, not a 100 Hz stream).
MIN_RATE_MESSAGES = 5


@dataclass
class TopicInfo:
    """One channel's figures (times in seconds of the run's clock)."""

    topic: str
    schema: str
    msg_type: str
    role: str
    count: int = 0
    first: float = 0.0
    last: float = 0.0
    #: (count - 1) / span [Hz]; None for an event channel (fewer than MIN_RATE_MESSAGES messages)
    rate_hz: float | None = None
    median_interval: float = 0.0
    max_gap: float = 0.0
    gaps: int = 0
    dropped: int | None = None


@dataclass
class RecordingInfo:
    """The summary of a recording."""

    path: Path
    size: int
    finished: bool
    messages: int
    start: float
    end: float
    topics: list[TopicInfo] = field(default_factory=list)
    run: dict[str, str] = field(default_factory=dict)
    versions: dict[str, str] = field(default_factory=dict)
    attachments: list[str] = field(default_factory=list)
    dropped: int | None = None

    @property
    def duration(self) -> float:
        return max(0.0, self.end - self.start)

    def as_dict(self) -> dict[str, Any]:
        return {
            "file": str(self.path),
            "bytes": self.size,
            "finished": self.finished,
            "messages": self.messages,
            "duration_s": round(self.duration, 6),
            "start_s": self.start,
            "end_s": self.end,
            "dropped": self.dropped,
            "run": self.run,
            "versions": self.versions,
            "attachments": self.attachments,
            "channels": [t.__dict__ for t in self.topics],
        }


def recording_info(path: str | Path) -> RecordingInfo:
    """Read ``path`` once and summarise it (UserError for a file that is not a recording)."""
    scan = RecordingScan(Path(path))
    times: dict[int, list[int]] = {}
    for channel, _schema, msg in read_records(path, scan):
        times.setdefault(channel.id, []).append(msg.log_time)
    stats = scan.metadata.get("umbra.recording")
    all_times = [t for ts in times.values() for t in ts]
    info = RecordingInfo(
        path=Path(path),
        size=scan.size,
        finished=scan.finished,
        messages=scan.messages,
        start=min(all_times) / 1e9 if all_times else 0.0,
        end=max(all_times) / 1e9 if all_times else 0.0,
        run=scan.metadata.get("umbra.run", {}),
        versions=scan.metadata.get("umbra.versions", {}),
        attachments=sorted(scan.attachments),
        dropped=int(stats["dropped"]) if stats and "dropped" in stats else None,
    )
    for cid, channel in sorted(scan.channels.items()):
        schema = scan.schemas.get(channel.schema_id)
        meta = channel.metadata or {}
        t = TopicInfo(
            topic=channel.topic,
            schema=schema.name if schema else "",
            msg_type=meta.get(META_TYPE, ""),
            role=meta.get(META_ROLE, ""),
        )
        if stats and f"dropped:{channel.topic}" in stats:
            t.dropped = int(stats[f"dropped:{channel.topic}"])
        stamps = np.sort(np.asarray(times.get(cid, []), dtype=np.int64)) / 1e9
        t.count = int(stamps.size)
        if stamps.size:
            t.first, t.last = float(stamps[0]), float(stamps[-1])
        if stamps.size > 1:
            gaps = np.diff(stamps)
            span = stamps[-1] - stamps[0]
            if stamps.size >= MIN_RATE_MESSAGES and span > 0:
                t.rate_hz = float((stamps.size - 1) / span)
            t.median_interval = float(np.median(gaps))
            t.max_gap = float(gaps.max())
            if t.median_interval > 0:
                t.gaps = int(np.count_nonzero(gaps > GAP_FACTOR * t.median_interval))
        info.topics.append(t)
    return info


def format_info(info: RecordingInfo) -> str:
    """The human-readable summary."""
    run = info.run
    lines = [
        f"file      {info.path} ({info.size / 1e6:.1f} MB)"
        + (
            ""
            if info.finished
            else "  NOT FINISHED: no footer (the run was killed?); read to its last complete chunk"
        ),
        f"run       graph {run.get('graph', '?')}, clock {run.get('clock', '?')}, "
        f"seed {run.get('seed', '?')}, processes {run.get('processes', '?')}",
        f"duration  {info.duration:.3f} s ({info.start:.3f} .. {info.end:.3f} s), "
        f"{info.messages} messages",
        "drops     "
        + (
            f"{info.dropped} samples dropped by the recorder"
            if info.dropped is not None
            else "unknown (the recorder did not finish the file)"
        ),
    ]
    if info.attachments:
        lines.append(f"attached  {', '.join(info.attachments)}")
    width = max([len(t.topic) for t in info.topics] + [5])
    lines.append("")
    lines.append(
        f"{'topic':<{width}}  {'schema':<26} {'count':>6} {'rate Hz':>8} {'max gap s':>9} "
        f"{'gaps':>4} {'dropped':>7}"
    )
    for t in info.topics:
        dropped = "-" if t.dropped is None else str(t.dropped)
        rate = "event" if t.rate_hz is None else f"{t.rate_hz:.2f}"
        lines.append(
            f"{t.topic:<{width}}  {t.schema:<26} {t.count:>6} {rate:>8} "
            f"{t.max_gap:>9.3f} {t.gaps:>4} {dropped:>7}"
        )
    lines.append("")
    lines.append(f"gaps: intervals longer than {GAP_FACTOR:g} x the channel's median interval")
    lines.append(
        f"rate: (count - 1) / time from first to last message; event: fewer than "
        f"{MIN_RATE_MESSAGES} messages, no rate"
    )
    return "\n".join(lines)


def info_json(info: RecordingInfo) -> str:
    return json_text(info.as_dict(), indent=2)
