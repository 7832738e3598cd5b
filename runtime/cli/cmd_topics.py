"""``umbra topics``: every output of a running graph — key, type, producer, rate, age, drops."""

from __future__ import annotations

import argparse
import math
import sys
import threading
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, TypedDict

from umbra.connectors.cli_support import check_seconds
from umbra.connectors.errors import UserError
from umbra.connectors.json_text import json_text
from umbra.runtime.cli.observing import add_observer_args, open_observation, run_ended_text
from umbra.runtime.ros2 import shell as ros2_shell
from umbra.runtime.ros2.run_args import wants_ros2

if TYPE_CHECKING:  # annotations only: `umbra --help` loads this file without them
    from umbra.runtime.links.observe import Observed

NAME = "topics"
HELP = "list the outputs of a running graph: key, type, producer, rate, age, drops"
GUIDE = "docs/guide/recording.md"  # the guide page this command's --help points to


def configure(parser: argparse.ArgumentParser) -> None:
    add_observer_args(parser)
    parser.add_argument(
        "--window", type=float, default=2.0, metavar="S", help="seconds to watch (default 2)"
    )
    parser.add_argument("--json", action="store_true", help="one JSON object per output")
    ros2_shell.add_shell_args(parser)  # the ROS 2 domain's topics beside ours


@dataclass
class Seen:
    """What arrived on one key during the window."""

    type_name: str = ""
    count: int = 0
    first: float = math.nan
    last: float = math.nan
    last_seq: int = 0
    drops: int = 0
    ended: bool = False
    undecodable: int = 0
    sources: set[str] = field(default_factory=set)

    def add(self, o: Observed) -> None:
        if o.kind == "end":
            self.ended = True
            return
        self.type_name = o.type_name or self.type_name
        self.sources.add(o.source)
        if o.kind == "undecodable":
            self.undecodable += 1
            return
        self.ended = False
        self.count += 1
        self.first = o.arrival if self.count == 1 else self.first
        self.last = o.arrival
        seq = o.message.seq if o.message is not None else 0
        if self.last_seq and seq > self.last_seq + 1:
            self.drops += seq - self.last_seq - 1
        self.last_seq = max(seq, self.last_seq)

    def rate(self) -> float | None:
        """Samples per second over the window [Hz] (None with fewer than two)."""
        if self.count < 2 or self.last <= self.first:
            return None
        return (self.count - 1) / (self.last - self.first)


def main(args: argparse.Namespace) -> int:
    check_seconds("--window", args.window)
    ros2 = ros2_shell.list_topics(args, min(args.window, 1.0)) if wants_ros2(args) else None
    try:
        observation = open_observation(args, list_runs=True)
    except UserError as exc:
        if ros2 is None:
            raise
        print(f"umbra topics: {exc}", file=sys.stderr)  # no run of ours: the ROS 2 side alone
        ros2_shell.print_topics(*ros2, args.json)
        return 0
    seen: dict[str, Seen] = {}
    lock = threading.Lock()

    def on_sample(o: Observed) -> None:
        with lock:
            seen.setdefault(o.key, Seen()).add(o)

    try:
        observation.subscribe(on_sample)
        observation.ended.wait(args.window)
        ended = observation.ended.is_set()
        producers = {} if ended else observation.producers()
    finally:
        observation.close()
    if ended:
        print(f"umbra topics: {run_ended_text(observation)} within the window", file=sys.stderr)
    now = time.monotonic()
    process_of = {session: name for name, session in producers.items()}
    rows: list[_Row] = []
    known: set[str] = set()
    run = observation.run
    for proc in run.processes if run else []:
        for out in proc.outputs:
            known.add(out.key)
            published = out.link or proc.publish_all
            rows.append(_row(out.key, out.type, proc.process, seen.get(out.key), now, published))
    for key, s in sorted(seen.items()):
        if key not in known:  # a run elsewhere: what the wire says
            who = ", ".join(sorted(process_of.get(z, z or "?") for z in s.sources))
            rows.append(_row(key, s.type_name, who, s, now, True))
    rows.sort(key=lambda r: r["key"])
    if args.json:
        for row in rows:
            print(json_text(row))
    else:
        _table(rows, observation.prefix, producers)
    if ros2 is not None:
        ros2_shell.print_topics(*ros2, args.json)
    return 0


class _Row(TypedDict):
    """One topic as ``umbra topics`` prints it (``--json``: one object a line)."""

    key: str
    type: str
    producer: str
    rate_hz: float | None  # [Hz]
    age_s: float | None  # [s] since the last sample
    drops: int
    samples: int
    note: str


def _row(
    key: str, type_name: str, producer: str, s: Seen | None, now: float, published: bool
) -> _Row:
    rate = s.rate() if s else None
    age = now - s.last if s and s.count else None
    if not published:
        note = "not published (run with --publish-all)"
    elif s is None or (not s.count and not s.ended):
        note = "nothing in the window"
    elif s.ended:
        note = "ended"
    else:
        note = f"{s.undecodable} undecodable" if s.undecodable else ""
    return {
        "key": key,
        "type": type_name,
        "producer": producer,
        "rate_hz": round(rate, 2) if rate is not None else None,
        "age_s": round(age, 3) if age is not None else None,
        "drops": s.drops if s else 0,
        "samples": s.count if s else 0,
        "note": note,
    }


def _table(rows: list[_Row], prefix: str, producers: dict[str, str]) -> None:
    alive = ", ".join(sorted(producers)) or "none"
    print(f"graph prefix {prefix}; processes up: {alive}", file=sys.stderr)
    head = ("KEY", "TYPE", "PRODUCER", "RATE Hz", "AGE s", "DROPS", "")
    lines = [head] + [
        (
            r["key"],
            r["type"],
            r["producer"],
            "-" if r["rate_hz"] is None else f"{r['rate_hz']:.1f}",
            "-" if r["age_s"] is None else f"{r['age_s']:.2f}",
            str(r["drops"]),
            r["note"],
        )
        for r in rows
    ]
    widths = [max(len(line[i]) for line in lines) for i in range(len(head))]
    for line in lines:
        print("  ".join(c.ljust(w) for c, w in zip(line, widths, strict=True)).rstrip())
