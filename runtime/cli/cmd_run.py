"""``umbra run GRAPH``: run a graph — every process, one process, or all in one process."""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from umbra.connectors.cli_support import check_seconds
from umbra.connectors.errors import UserError
from umbra.runtime.cli.common import parse_module_set
from umbra.runtime.graph.names import endpoint_problem
from umbra.runtime.realtime import NO_CONSTRAINT_US, is_latency_us, latency_limit
from umbra.runtime.ros2.run_args import add_ros2_args, ros2_options, start_router

if TYPE_CHECKING:  # annotations only: `umbra --help` loads this file without them
    from umbra.runtime.graph.plan import GraphPlan

NAME = "run"
HELP = "run a graph (all its processes, --process NAME, or --single-process)"
GUIDE = "docs/guide/running.md"  # the guide page this command's --help points to


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("graph", metavar="GRAPH", help="graph file (.yaml)")
    parser.add_argument("--clock", choices=("sim", "real"), help="override the graph's clock")
    parser.add_argument("--duration", type=float, metavar="S", help="stop after S seconds")
    parser.add_argument(
        "--attended",
        action="store_true",
        help="a person runs this run from the operator's page: simulated operators stay off, "
        "the run never ends on its own (no duration; a judge's verdict is published and "
        "printed, then the run waits); the page's Stop run ends it (exit 0, 1 for a missed "
        "grasp), as Ctrl-C does (exit 130); summaries and recordings are written either way",
    )
    parser.add_argument(
        "--set",
        action="append",
        metavar="MODULE.PARAM=VALUE",
        default=[],
        help="override a parameter (repeatable)",
    )
    parser.add_argument(
        "--out", type=Path, metavar="DIR", help="output folder (default runs/<graph>-<time>)"
    )
    parser.add_argument(
        "--process",
        metavar="NAME",
        help="run only this process, e.g. on another host (without --listen/--connect: the "
        "graph's `links:` endpoints, else the --zenoh-config file's, else a loopback mesh "
        "on tcp/127.0.0.1:7447+i for the i-th process; the processes you start by hand on this "
        "host authenticate each other with credentials derived from your secret in "
        "$XDG_RUNTIME_DIR/umbra/ or ~/.cache/umbra/, unless --zenoh-config authenticates)",
    )
    parser.add_argument(
        "--single-process",
        action="store_true",
        help="run every module in this process (links become local)",
    )
    parser.add_argument(
        "--listen",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help="zenoh endpoint to listen on, e.g. tcp/0.0.0.0:7447 (repeatable; with all processes "
        "on this host: for the first one)",
    )
    parser.add_argument(
        "--connect",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help="zenoh endpoint to connect to, e.g. tcp/192.168.1.10:7447 (repeatable; with all "
        "processes on this host: for every one)",
    )
    parser.add_argument(
        "--zenoh-config",
        metavar="FILE|DIR",
        help="zenoh JSON5 configuration (TLS, access control, routers); a folder written by "
        "`umbra keys` gives each process its own PROCESS.json5 (mutual TLS + the graph's rules)",
    )
    parser.add_argument(
        "--insecure",
        action="store_true",
        help="allow listening beyond loopback without TLS, and run processes without "
        "credentials: neither the launcher's per-run ones nor, with --process, those derived "
        "from your secret (anyone who reaches an endpoint can drive the graph)",
    )
    parser.add_argument(
        "--prefix",
        metavar="KEY",
        help="zenoh key prefix (default: the graph's `links.prefix`, else umbra/<graph>)",
    )
    parser.add_argument(
        "--cpu-latency-us",
        type=int,
        metavar="US",
        help="hold every CPU's wake-up latency at most US microseconds while running, as "
        "real-time hosts do (0: idle CPUs poll; writes /dev/cpu_dma_latency, needs root); "
        "overrides the graph's processes.NAME.cpu_latency_us",
    )
    parser.add_argument(
        "--record",
        action="store_true",
        help="record every output (connected or not; an image nobody reads only when "
        "`record.ports` names it) into one MCAP file in the run folder (Foxglove-ready; "
        "settings: the graph's `record:`)",
    )
    parser.add_argument(
        "--record-images",
        choices=("raw", "jpeg", "png"),
        help="with --record: how images are recorded (default: the graph's, else jpeg)",
    )
    parser.add_argument(
        "--record-format",
        choices=("foxglove", "ros2"),
        help="with --record: `foxglove` (default: Foxglove's schemas) or `ros2` (ros2msg/cdr "
        "channels that rosbags and `ros2 bag` read)",
    )
    add_ros2_args(parser)
    parser.add_argument(
        "--publish-all",
        action="store_true",
        help="split runs: every process also publishes the outputs that feed no other process, "
        "each on its key PREFIX/MODULE/PORT, for observers (`umbra topics`, viewers); links are "
        "always published",
    )
    parser.add_argument(
        "--run-id",
        metavar="ID",
        help="this run's ID, which observers name with --run ID (`umbra topics --run ID`) "
        "when several runs of the graph are up (default: a new one, GRAPH-YYYYmmdd-HHMMSS-XXXX, "
        "said on start; `by-hand` for a process started with --process)",
    )
    add_foxglove_args(parser)
    parser.add_argument("--quiet", action="store_true", help="no summary table")
    # a process started by the launcher: commands on stdin, bounded wait for its consumers
    parser.add_argument("--supervised", action="store_true", help=argparse.SUPPRESS)
    # when the launcher started the run [s since the epoch], for its run files
    parser.add_argument("--run-started", type=float, help=argparse.SUPPRESS)
    # the launcher's per-run credentials file of this process (mode 0600)
    parser.add_argument("--link-auth", metavar="FILE", help=argparse.SUPPRESS)
    # benchmarks only: links without identity checks and size bounds (their cost is measured)
    parser.add_argument("--unchecked-links", action="store_true", help=argparse.SUPPRESS)


def add_foxglove_args(parser: argparse.ArgumentParser) -> None:
    """``--foxglove`` and its settings (``umbra.runtime.live``)."""
    parser.add_argument(
        "--foxglove",
        action="store_true",
        help="serve the run live to Foxglove or Lichtblick (Foxglove WebSocket protocol, every "
        "output with the recordings' schemas and frames, wall-clock time); the address printed "
        "carries the run's token",
    )
    parser.add_argument(
        "--foxglove-port",
        type=int,
        default=8765,
        metavar="PORT",
        help="with --foxglove: port to serve on (default 8765, 0: any free one)",
    )
    parser.add_argument(
        "--foxglove-host",
        default="127.0.0.1",
        metavar="ADDR",
        help="with --foxglove: address to serve on (default loopback; beyond it needs --insecure)",
    )
    parser.add_argument(
        "--foxglove-origin",
        action="append",
        default=[],
        metavar="URL",
        help="with --foxglove: a viewer page allowed to connect from a browser, e.g. "
        "http://127.0.0.1:8080 for a Lichtblick you serve (https://app.foxglove.dev always is)",
    )


def start_live(plan: GraphPlan, args: argparse.Namespace, clock: Any) -> Any:
    """The live server of ``--foxglove`` (None without it); prints the address to open."""
    if not getattr(args, "foxglove", False):
        return None
    from umbra.runtime.live.session import LiveOptions, LiveRun

    options = LiveOptions(
        host=args.foxglove_host,
        port=args.foxglove_port,
        origins=list(args.foxglove_origin),
        insecure=bool(getattr(args, "insecure", False)),
    )
    live = LiveRun(plan, options, clock)
    print(f"foxglove: open {live.url} (Foxglove WebSocket)", file=sys.stderr, flush=True)
    return live


def enable_recording(plan: GraphPlan, args: argparse.Namespace) -> None:
    """``--record`` / ``--record-images``: turn the graph's ``record:`` setting on."""
    if getattr(args, "record", False):
        plan.spec.record.enabled = True
    if getattr(args, "record_images", None):
        if not plan.spec.record.enabled:
            raise UserError("--record-images needs --record (or `record:` in the graph)")
        plan.spec.record.images = args.record_images
    if getattr(args, "record_format", None):
        if not plan.spec.record.enabled:
            raise UserError("--record-format needs --record (or `record:` in the graph)")
        plan.spec.record.format = args.record_format


def run_duration(plan: GraphPlan, args: argparse.Namespace) -> float | None:
    """How long the run lasts [s]: ``--duration``, else the graph's; None (until stopped) for an
    ``--attended`` run, which says so once when it leaves a duration aside."""
    duration = args.duration if args.duration is not None else plan.spec.duration
    if not getattr(args, "attended", False):
        return duration
    if duration is not None and not getattr(args, "supervised", False):
        print(
            "umbra run: attended: the run waits for its operator (the page's Stop run or "
            f"Ctrl-C ends it); the duration of {duration:g} s is not applied",
            file=sys.stderr,
        )
    return None


def main(args: argparse.Namespace) -> int:
    from umbra.runtime.graph.check import load_graph
    from umbra.runtime.ros2.run_bridge import ros2_lines
    from umbra.runtime.run import default_output_dir, run_process
    from umbra.runtime.scheduler import SchedulerOptions

    check_seconds("--duration", args.duration, "leave it out to run until stopped")
    latency = args.cpu_latency_us
    if latency is not None and not is_latency_us(latency):
        raise UserError(
            f"--cpu-latency-us must be from 0 to {NO_CONSTRAINT_US} microseconds, found {latency}"
        )
    for option in ("listen", "connect"):
        for endpoint in getattr(args, option):
            if endpoint_problem(endpoint):
                raise UserError(f"--{option}: error: {endpoint_problem(endpoint)}")
    plan = load_graph(args.graph, overrides=parse_module_set(args.set), prefix=args.prefix)
    enable_recording(plan, args)
    single = args.single_process or (len(plan.processes) == 1 and not args.process)
    if single:
        unused = (
            ("--zenoh-config", args.zenoh_config),
            ("--listen", " ".join(args.listen)),
            ("--connect", " ".join(args.connect)),
            ("--run-id", args.run_id),
        )
        for option, value in unused:
            if value:
                raise UserError(
                    f"{option}: a run in one process has no links to configure nor a run ID "
                    f"for observers, found {str(value)!r}: leave it out, or run the graph's "
                    "processes apart"
                )
    clock = args.clock or plan.spec.clock
    if args.attended and clock != "real":
        raise UserError(
            f"--attended: a person acts in real time: expected the real clock, found clock "
            f"{clock} ({'--clock' if args.clock else plan.spec.file}); add --clock real"
        )
    duration = run_duration(plan, args)
    ros2 = ros2_options(plan, args)
    router = start_router(ros2, bool(getattr(args, "supervised", False)))  # none answers: ours
    out = args.out or default_output_dir(plan)
    logging.basicConfig(
        level=logging.INFO, format="%(levelname)s %(name)s: %(message)s", stream=sys.stderr
    )
    if single:
        options = SchedulerOptions(
            clock=clock,
            duration=duration,
            output_dir=out,
            handle_signals=True,
            cpu_latency_us=latency_limit(plan.spec.cpu_latency_us, None, latency),
            attended=args.attended,
            ros2=ros2,
        )
        live: Any = None

        def serve_live(scheduler: Any) -> None:
            nonlocal live
            live = start_live(plan, args, scheduler.clock)
            if live is not None:
                live.serve(scheduler)

        try:
            result = run_process(plan, options, prepare=serve_live)
        finally:
            if live is not None:
                live.close()
                print(f"foxglove: {live.summary()}", file=sys.stderr)
            if router is not None:
                router.close()
        if not args.quiet:
            print(result.table(), file=sys.stderr)
            for line in ros2_lines(result.extra.get("ros2")):
                print(line, file=sys.stderr)
            print(f"summary written to {out}", file=sys.stderr)
            if "recording" in result.extra:
                rec = result.extra["recording"]
                print(
                    f"recording: {rec['file']} ({rec['written']} samples, "
                    f"{rec['dropped']} dropped)",
                    file=sys.stderr,
                )
        return result.exit_code
    from umbra.runtime import launcher
    from umbra.runtime.clock import RealClock

    if getattr(args, "foxglove", False):
        args.publish_all = True  # every process's outputs, for the live server to observe
    args.run_id = launcher.run_identity(plan, args)  # one for the run, its processes, its viewer
    live = start_live(plan, args, RealClock())
    if live is not None:
        args.tuner_password = live.tuner_password  # the launcher's credentials let it tune
        live.observe(args.run_id)
    try:
        return launcher.main(plan, args, clock=clock, duration=duration, out=out)
    finally:
        if router is not None:
            router.close()
        if live is not None:
            live.close()
            print(f"foxglove: {live.summary()}", file=sys.stderr)
