"""``umbra replay RECORDING GRAPH``: run a graph with recorded outputs in place of some modules."""

from __future__ import annotations

import argparse
import logging
import sys
import time
from pathlib import Path

from umbra.connectors.cli_support import check_seconds
from umbra.runtime.cli.common import parse_module_set

NAME = "replay"
#: Past the recording's last sample [s]: less than any tick period, more than the scheduler's
#: 1 ns tolerance and the rounding of tick times.
END_MARGIN = 5e-9
HELP = "run a graph with recorded outputs in place of the modules that produced them"
GUIDE = "docs/guide/recording.md"  # the guide page this command's --help points to


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("recording", metavar="RECORDING", help="recording (.mcap) of a run")
    parser.add_argument("graph", metavar="GRAPH", help="graph file (.yaml) to replay into")
    parser.add_argument(
        "--replace",
        action="append",
        default=[],
        metavar="MODULE",
        help="module whose recorded outputs are replayed (repeatable or comma-separated; "
        "default: the modules whose recorded outputs are images)",
    )
    parser.add_argument(
        "--clock",
        choices=("sim", "real"),
        default="sim",
        help="sim: as fast as the machine goes (default); real: at the recorded pace",
    )
    parser.add_argument(
        "--duration",
        type=float,
        metavar="S",
        help="stop after S seconds (default: when the recording ends: a sim recording on the "
        "sim clock after the tick of its last sample, as the recorded run did; otherwise once "
        "every replayed sample was sent)",
    )
    parser.add_argument(
        "--set",
        action="append",
        metavar="MODULE.PARAM=VALUE",
        default=[],
        help="override a parameter (repeatable), e.g. snake.k_sigma=2.5",
    )
    parser.add_argument(
        "--out", type=Path, metavar="DIR", help="output folder (default runs/<graph>-replay-<time>)"
    )
    parser.add_argument(
        "--record", action="store_true", help="record the replay run too (to compare with)"
    )
    parser.add_argument(
        "--record-images", choices=("raw", "jpeg", "png"), help="with --record: image encoding"
    )
    parser.add_argument("--quiet", action="store_true", help="no summary table")


def main(args: argparse.Namespace) -> int:
    from umbra.runtime.cli.cmd_run import enable_recording
    from umbra.runtime.graph.check import load_graph
    from umbra.runtime.recording.replay import plan_replay
    from umbra.runtime.run import run_process
    from umbra.runtime.scheduler import SchedulerOptions

    check_seconds("--duration", args.duration)
    plan = load_graph(args.graph, overrides=parse_module_set(args.set))
    enable_recording(plan, args)
    replaced = [n.strip() for item in args.replace for n in item.split(",") if n.strip()]
    feed, names = plan_replay(plan, Path(args.recording), replaced, args.clock)
    out = args.out or Path("runs") / f"{plan.spec.name}-replay-{time.strftime('%Y%m%d-%H%M%S')}"
    logging.basicConfig(
        level=logging.INFO, format="%(levelname)s %(name)s: %(message)s", stream=sys.stderr
    )
    if not args.quiet:
        print(
            f"umbra replay: {', '.join(names)} replayed from {args.recording} "
            f"({feed.index.scan.messages} messages, "
            f"{(feed.index.end_ns - feed.index.t0_ns) / 1e9:.3f} s recorded on the "
            f"{feed.index.clock or '?'} clock)",
            file=sys.stderr,
        )
    duration = args.duration
    if duration is None and args.clock == "sim" and feed.index.clock == "sim":
        # the recorded ticks are the replay's: the tick of the last recorded sample runs, the
        # next one does not. Otherwise the replay ends once every replayed sample was sent.
        duration = max(0.0, (feed.index.end_ns - feed.index.t0_ns) / 1e9) + END_MARGIN
    options = SchedulerOptions(
        clock=args.clock, duration=duration, output_dir=out, handle_signals=True
    )
    result = run_process(plan, options)
    if not args.quiet:
        print(result.table(), file=sys.stderr)
        print(f"summary written to {out}", file=sys.stderr)
    if feed.error is not None:  # damage found while replaying: the samples before it were sent
        print(feed.error, file=sys.stderr)
        return 2
    return result.exit_code
