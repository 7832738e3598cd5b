"""Replay: recorded outputs fed into a graph in place of the modules that produced them.

A replaced module keeps its name, ports, parameters, rate and trigger inputs, so the scheduler runs
it in the same ticks as the module it stands for; each time it runs it sends, on each output, the
recorded samples whose send time has come (``log_time`` mapped onto the replay's clock). On the sim
clock a replay of a sim recording therefore puts every sample into the same tick as the run did,
and a graph with the same parameters and seed reproduces the run sample for sample; on the real
clock samples come at their recorded pace. A sample stamped with its send time is stamped with the
replay's tick time (exactly the original stamp on the sim clock); other stamps are shifted by the
same offset as the times.

Before anything runs, :func:`plan_replay` checks that the graph matches the recording: every
replaced module exists, each of its connected outputs was recorded, and every output it will send
(its recorded outputs that feed nothing too) has the same message type, frame and joint names in
the recording; replay never drives a guarded input (a drive) or stands in for a safety
guard. Problems are reported as ``umbra check`` reports them (``GRAPH:LINE:COL: error: ...``).

Reading: a finished recording is indexed from its summary section, so the replay starts without
reading the file through; only the chunks holding the replayed outputs (all but images that feed
nothing) are read, each checked against its CRC, on a thread of their own, with images decoded by
two more threads ahead of the graph. A chunk found damaged on the way stops the replay there
with ``FILE: error: ...`` and exit status 2 (the samples before it were replayed). A killed run's
file (no summary) is read through once before anything runs.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import msgspec

from umbra.connectors.errors import CheckFailed, Diagnostic, Location, UserError
from umbra.connectors.messages import Image, Message
from umbra.connectors.module import Module
from umbra.connectors.params import Parameters
from umbra.runtime.graph.plan import GraphPlan
from umbra.runtime.hints import did_you_mean
from umbra.runtime.recording.reader import RecordingScan, indexed_scan, read_records
from umbra.runtime.recording.samples import Sample, channel_type, iter_samples_parallel
from umbra.runtime.recording.tap import recorded_outputs, topic_of
from umbra.runtime.recording.writer import META_FRAME, META_JOINTS, META_PORT

#: Samples read and decoded ahead of the replay (720p raw: 2.8 MB each).
PREFETCH = 32


@dataclass
class RecordingIndex:
    """What replay needs to know of a recording before it runs (one pass over the file)."""

    scan: RecordingScan
    #: primary topic -> (type name, frame, joints, count)
    topics: dict[str, dict[str, Any]] = field(default_factory=dict)
    t0_ns: int = 0
    end_ns: int = 0
    clock: str = ""

    @classmethod
    def read(cls, path: str | Path) -> RecordingIndex:
        """From the summary section of a finished recording (no chunk read); a killed run's file
        (no summary) is read through to its last complete chunk."""
        scan = indexed_scan(path)
        counts: dict[int, int] = {}
        first: int | None = None
        last = 0
        if scan is not None and scan.statistics is not None:
            stats = scan.statistics
            counts = dict(stats.channel_message_counts)
            if stats.message_count:
                first, last = stats.message_start_time, stats.message_end_time
        else:
            scan = RecordingScan(Path(path))
            for channel, _schema, msg in read_records(path, scan):
                counts[channel.id] = counts.get(channel.id, 0) + 1
                first = msg.log_time if first is None else min(first, msg.log_time)
                last = max(last, msg.log_time)
        index = cls(scan)
        for cid, channel in scan.channels.items():
            msg_type = channel_type(channel)
            if msg_type is None:
                continue
            meta = channel.metadata or {}
            index.topics[channel.topic] = {
                "type": msg_type.__name__,
                "frame": meta.get(META_FRAME, ""),
                "joints": meta.get(META_JOINTS, ""),
                "port": meta.get(META_PORT, ""),
                "count": counts.get(cid, 0),
            }
        run = scan.metadata.get("umbra.run", {})
        index.clock = run.get("clock", "")
        t0 = run.get("t0_ns")
        index.t0_ns = int(t0) if t0 is not None and t0.isdigit() else (first or 0)
        index.end_ns = last
        if not index.topics:
            raise UserError(
                f"{path}: error: holds no umbra samples to replay "
                f"({len(scan.channels)} channels, none written by `umbra run --record`)"
            )
        return index


class ReplayFeed:
    """Recorded samples of the replaced outputs, read once in file order, handed out by time."""

    def __init__(
        self, path: Path, index: RecordingIndex, outputs: dict[str, tuple[str, str]], sim: bool
    ) -> None:
        self.path, self.index, self.outputs = path, index, outputs
        self._samples: Iterator[Sample] = iter_samples_parallel(
            path, topics=list(outputs), depth=PREFETCH, scan=index.scan
        )
        self._next: Sample | None = None
        self._queues: dict[str, deque[tuple[str, Sample]]] = {}
        self._origin: float | None = 0.0 if sim else None
        self._exhausted = False
        self.sent = 0
        #: why the replay stopped early (``FILE: error: ...``: damage found while reading)
        self.error: str | None = None

    def _rel_ns(self, now: float) -> int:
        if self._origin is None:
            self._origin = now
        return round((now - self._origin) * 1e9)

    def _pull(self, until_ns: int) -> None:
        t0 = self.index.t0_ns
        while not self._exhausted:
            if self._next is None:
                try:
                    self._next = next(self._samples)
                except StopIteration:
                    self._exhausted = True
                    return
                except UserError as exc:  # damage past the summary: stop here, say what
                    self._exhausted = True
                    self.error = str(exc)
                    raise
            if self._next.log_ns - t0 > until_ns:
                return
            module, port = self.outputs[self._next.topic]
            self._queues.setdefault(module, deque()).append((port, self._next))
            self._next = None

    def due(self, module: str, now: float) -> list[tuple[str, Message]]:
        """``(port, sample)`` that ``module`` sends at ``now`` [s], stamped for the replay."""
        rel = self._rel_ns(now)
        self._pull(rel)
        queue = self._queues.get(module)
        out: list[tuple[str, Message]] = []
        t0, origin = self.index.t0_ns, self._origin or 0.0
        while queue and queue[0][1].log_ns - t0 <= rel:
            port, sample = queue.popleft()
            if sample.publish_ns == sample.log_ns:
                stamp = 0.0  # stamped with its send time: the port stamps it with this tick's
            else:
                stamp = max(0.0, origin + (sample.publish_ns - t0) / 1e9)
            out.append((port, _restamped(sample.message, stamp, now)))
        self.sent += len(out)
        return out

    def ended(self, now: float) -> bool:
        """True once every replayed sample was sent and the recording's end has passed."""
        rel = self._rel_ns(now)
        self._pull(rel)
        return (
            self._exhausted
            and not any(self._queues.values())
            and rel > self.index.end_ns - self.index.t0_ns
        )

    def close(self) -> None:
        """Stop reading (the reading and decoding threads end); call when the run ends."""
        self._exhausted = True
        close = getattr(self._samples, "close", None)
        if close is not None:
            close()


class ReplaySource(Module[Parameters]):
    """Stands in for a recorded module: sends its recorded outputs (see the module docstring)."""

    FEED: ClassVar[ReplayFeed | None] = None

    def step(self, now: float) -> None:
        feed = type(self).FEED
        assert feed is not None
        if feed.error is not None:
            return
        try:
            due = feed.due(self.name, now)
        except UserError as exc:  # the recording is damaged here: a user error, exit status 2
            self.context.request_stop(str(exc), 2)
            return
        for port, sample in due:
            self.outputs[port].send(sample)
        if feed.ended(now):
            span = (feed.index.end_ns - feed.index.t0_ns) / 1e9
            self.context.request_stop(f"replay: the recording ends at {span:.3f} s", 0)

    def stop(self) -> None:
        feed = type(self).FEED
        if feed is not None:
            feed.close()

    def summary(self) -> dict[str, Any]:
        feed = type(self).FEED
        return {"replayed_from": str(feed.path) if feed else "", "sent": self.outputs_sent()}

    def outputs_sent(self) -> int:
        return sum(p.count for p in self.outputs.values())


def replay_class(original: type[Module[Any]], feed: ReplayFeed) -> type[Module[Any]]:
    """A module type with ``original``'s ports and parameters that replays from ``feed``."""
    attrs: dict[str, Any] = {
        "TYPE": original.type_name(),
        "Params": original.Params,
        "FEED": feed,
        "__doc__": f"Replays recorded outputs of a {original.type_name()}.",
        "dynamic_inputs": classmethod(lambda cls, params: original.dynamic_inputs(params)),
    }
    attrs.update(original.input_decls())
    attrs.update(original.output_decls())
    return type(f"Replay{original.__name__}", (ReplaySource,), attrs)


# -- planning and checks ---------------------------------------------------------------------------
def default_replaced(plan: GraphPlan, index: RecordingIndex) -> list[str]:
    """Modules replaced when the user names none: those whose recorded outputs are images (the
    cameras), so the graph's vision and servo run on the recorded approach."""
    fed = {(c.src.module, c.src.port) for c in plan.connections}
    found = []
    for name in plan.order:
        mplan = plan.modules[name]
        if any(  # an image nobody reads (a view drawn for a video file) is not a camera
            issubclass(p.msg_type, Image)
            and (name, port) in fed
            and topic_of(name, port) in index.topics
            for port, p in mplan.outputs.items()
        ):
            found.append(name)
    return found


def fed_outputs(
    plan: GraphPlan, index: RecordingIndex, names: list[str]
) -> dict[str, tuple[str, str]]:
    """Topic -> (module, port) of the recorded outputs of ``names`` that a replay sends: those
    that feed a connection, and those of other types than images that feed nothing (a re-record
    then holds them again; an image nobody reads is not decoded): what ``--record`` records; an
    output that sent nothing while recorded (none listened) is not replayed."""
    return {
        topic_of(n, port): (n, port)
        for n, port in recorded_outputs(plan, set(names))
        if topic_of(n, port) in index.topics and index.topics[topic_of(n, port)]["count"]
    }


def _problems(
    plan: GraphPlan, index: RecordingIndex, replaced: list[str], path: Path
) -> list[Diagnostic]:
    spec = plan.spec
    graph_loc = spec.loc or Location(str(spec.file), 1)
    problems: list[Diagnostic] = []
    consumers: dict[tuple[str, str], list[Any]] = {}
    for conn in plan.connections:
        consumers.setdefault((conn.src.module, conn.src.port), []).append(conn)
    sent = fed_outputs(plan, index, [n for n in replaced if n in plan.modules])
    for name in replaced:
        mplan = plan.modules.get(name)
        if mplan is None:
            problems.append(
                Diagnostic(
                    graph_loc,
                    f"replay: the graph has no module `{name}` to replace"
                    f"{did_you_mean(name, list(plan.modules))}",
                )
            )
            continue
        loc = mplan.spec.loc
        if mplan.cls.SAFETY_GUARD:
            problems.append(
                Diagnostic(
                    loc,
                    f"replay: `{name}` is a safety guard ({mplan.spec.type}); a recording never "
                    f"stands in for one",
                )
            )
        for port, info in mplan.outputs.items():
            conns = consumers.get((name, port), [])
            if not conns and topic_of(name, port) not in sent:
                continue
            for conn in conns:
                dst = plan.modules.get(conn.dst.module)
                decl = dst.input_decls.get(conn.dst.port) if dst else None
                if decl is not None and getattr(decl, "requires_guard", False):
                    problems.append(
                        Diagnostic(
                            conn.loc,
                            f"replay: `{conn}` would drive the guarded input `{conn.dst}` "
                            f"straight from a recording; replace modules upstream of the guard",
                        )
                    )
            topic = topic_of(name, port)
            rec = index.topics.get(topic)
            if rec is None:
                have = sorted(t for t in index.topics if t.startswith(f"/{name}/"))
                problems.append(
                    Diagnostic(
                        loc,
                        f"replay: output `{name}.{port}` ({info.msg_type.__name__}) feeds "
                        f"{', '.join(str(c.dst) for c in conns)} but {path} has no `{topic}` "
                        f"(recorded from `{name}`: {', '.join(have) or 'nothing'})",
                    )
                )
                continue
            if rec["type"] != info.msg_type.__name__:
                problems.append(
                    Diagnostic(
                        loc,
                        f"replay: output `{name}.{port}` carries {info.msg_type.__name__}, "
                        f"the recording's `{topic}` carries {rec['type']}",
                    )
                )
                continue
            frame = info.frame or ""
            if frame and rec["frame"] and frame != rec["frame"]:
                problems.append(
                    Diagnostic(
                        loc,
                        f"replay: output `{name}.{port}` is in frame `{frame}`, the recording's "
                        f"`{topic}` in `{rec['frame']}`",
                    )
                )
            joints = ",".join(info.joints or ())
            if joints and rec["joints"] and joints != rec["joints"]:
                problems.append(
                    Diagnostic(
                        loc,
                        f"replay: output `{name}.{port}` has joints [{joints}], the recording's "
                        f"`{topic}` has [{rec['joints']}]",
                    )
                )
            if rec["count"] == 0:
                problems.append(
                    Diagnostic(loc, f"replay: the recording's `{topic}` holds no samples")
                )
    return problems


def plan_replay(
    plan: GraphPlan, path: Path, replaced: list[str] | None, clock: str
) -> tuple[ReplayFeed, list[str]]:
    """Check the graph against the recording and put replay sources in place of ``replaced``
    (default: :func:`default_replaced`); CheckFailed before anything runs when they differ."""
    index = RecordingIndex.read(path)
    names = list(replaced) if replaced else default_replaced(plan, index)
    if not names:
        raise UserError(
            f"{path}: error: no module to replace: the recording has no images from a module of "
            f"graph `{plan.spec.name}`; name them with --replace MODULE"
        )
    problems = _problems(plan, index, names, path)
    if problems:
        raise CheckFailed(problems)
    feed = ReplayFeed(path, index, fed_outputs(plan, index, names), sim=clock == "sim")
    for n in names:
        mplan = plan.modules[n]
        mplan.cls = replay_class(mplan.cls, feed)
    return feed, names


def _restamped(message: Message, stamp: float, now: float) -> Message:
    """``message`` stamped ``stamp`` for the replay (0: its send time, ``now``), its data as old
    at that stamp as it was when recorded (``origin`` moved with the stamp); a message recorded
    without an origin (an older recording, a schema that holds none) gets the one its port gives
    it."""
    if message.origin == -math.inf:  # undatable when recorded: undatable now
        return msgspec.structs.replace(message, stamp=stamp)
    recorded_age = message.stamp - message.origin if message.origin else None
    if recorded_age is None or not math.isfinite(recorded_age):
        return msgspec.structs.replace(message, stamp=stamp, origin=0.0)
    return msgspec.structs.replace(message, stamp=stamp, origin=(stamp or now) - recorded_age)
